"""Seeded hostile inputs: maps, settings, actions, command lines and bags, drawn from a seed (and
the API misuse of the race and the localization wrappers, :mod:`tests.fuzz.api_cases`).

Each generator returns JSON-able case dicts; :mod:`tests.fuzz.worker` runs them and reports what
happened. The same seed gives the same cases (``random.Random(seed)``).
"""

from __future__ import annotations

import dataclasses
import random
from typing import Any

from tests.fuzz.api_cases import localization_api_cases, race_api_cases
from tests.fuzz.file_mutations import path_cases, scan_cases  # the file-safety kinds
from tests.fuzz.live_cases import live_cases  # misbehaving live-view clients

__all__ = [
    "HOSTILE_TEXTS",
    "HOSTILE_VALUES",
    "action_cases",
    "bag_cases",
    "cli_cases",
    "filter_cases",
    "live_cases",
    "localization_api_cases",
    "map_cases",
    "path_cases",
    "race_api_cases",
    "scan_cases",
    "setting_cases",
]

HOSTILE_VALUES: list[Any] = [
    0, -1, 1e-12, 1e-9, 1e-6, 1e12, -1e12, 1e300, -1e300, "nan", "inf", "-inf", 2**63, 10**30,
    True, False, "abc", "1e12", "", None, [], {}, [1, 2], [1e12, 1e12, 1e12], "x" * 5000, 0.5, 3,
    1000000, 100000000,
]  # fmt: skip
"""Values for settings; "nan" / "inf" / "-inf" stand for the floats (JSON has none)."""

HOSTILE_TEXTS: list[str] = [
    "0", "-1", "1e-12", "1e-9", "1e12", "-1e12", "1e300", ".nan", ".inf", "-.inf", "abc", "true",
    "[]", "{}", "[1e12, 1e12, 1e12]", "&a [*a]", "null", "'1e12'", "[" * 60, "x" * 5000, "0.5",
    "2", "1000000", "{boxes: 1000000}", "[0.1, 0.2]", "!!python/object:os.system ls",
]  # fmt: skip
"""Texts for YAML values and ``--env NAME=TEXT``."""

_MAP_KEYS = {
    "resolution": ["0.05", "0", "-1", "1e-9", "1e9", ".nan", ".inf", "abc", "[1]", "1e12", "0.2"],
    "origin": ["[0, 0, 0]", "[1e300, 0, 0]", "[.nan, 0, 0]", "[1, 2]", "abc", "[1e6, -1e6, 9]",
               "[a, b, c]", "{}"],
    "negate": ["0", "1", "2", "abc", "[]"],
    "mode": ["trinary", "scale", "raw", "bogus", "[a, b]", "{}"],
    "occupied_thresh": ["0.65", "0.1", "2", "-1", "abc"],
    "free_thresh": ["0.196", "0.9", "-1", ".nan"],
}  # fmt: skip


def _value(v: Any) -> Any:
    return {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}.get(v, v) \
        if isinstance(v, str) else v  # fmt: skip


def decode(v: Any) -> Any:
    """A case value back from its JSON form (``"nan"`` / ``"inf"`` strings to floats, lists of
    them too)."""
    if isinstance(v, list):
        return [decode(x) for x in v]
    if isinstance(v, dict):
        return {k: decode(x) for k, x in v.items()}
    return _value(v)


def _env_fields() -> dict[str, Any]:
    from racecar_sim.settings.config import EnvConfig

    out: dict[str, Any] = {}
    for f in dataclasses.fields(EnvConfig):
        if f.name != "map":
            out[f.name] = f.default if f.default is not dataclasses.MISSING else None
    return out


_NESTED = {
    "car": ["wheelbase", "max_steer", "max_speed", "max_reverse_speed", "max_accel", "length",
            "width", "rear_overhang", "mass", "max_steer_rate", "max_decel"],
    "obstacles": ["boxes", "people", "box_size", "person_speed", "person_radius", "leg_radius",
                  "keep_out", "stop_distance"],
    "scan_effects": ["hit_bias", "hit_sigma", "short_fraction", "short_run", "long_excess",
                     "noreturn_edges", "noreturn_probability"],
    "odom_bias": ["scale", "offset"],
}  # fmt: skip


def setting_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` env settings with one or two hostile values (API keywords)."""
    rng = random.Random(seed)
    names = sorted(_env_fields())
    cases = []
    for _ in range(n):
        settings: dict[str, Any] = {}
        for _ in range(rng.choice([1, 1, 2])):
            name = rng.choice(names)
            if name in _NESTED:
                settings[name] = {rng.choice(_NESTED[name]): rng.choice(HOSTILE_VALUES)}
            else:
                settings[name] = rng.choice(HOSTILE_VALUES)
        cases.append({"kind": "setting", "settings": settings})
    return cases


def filter_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` filter settings (mcl.LocalizationConfig sections) with a hostile value."""
    rng = random.Random(seed)
    fields = {
        "filter": ["n_particles", "global_particles", "global_density", "global_clearance",
                   "init_spread", "update_min_distance", "global_max_particles"],
        "sensor": ["num_beams_per_particle", "table_width", "sigma_hit", "squash_exponent",
                   "max_range", "alpha_hit", "likelihood_sigma", "fov", "mount_offset"],
        "motion": ["coefficients", "scheme"],
    }  # fmt: skip
    cases = []
    for _ in range(n):
        section = rng.choice(sorted(fields))
        name = rng.choice(fields[section])
        value = rng.choice(HOSTILE_VALUES)
        cases.append({"kind": "filter", "section": section, "name": name, "value": value})
    return cases


def map_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` maps: an image (size and content drawn) and a YAML with one or two keys mutated."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        shape = rng.choice([(1, 1), (1, 300), (3, 3), (40, 40), (60, 90), (120, 80), (120, 80)])
        content = rng.choice(["free", "occupied", "room", "room", "noise", "grey"])
        keys = {k: v[0] for k, v in _MAP_KEYS.items()}
        for key in rng.sample(sorted(_MAP_KEYS), rng.choice([0, 1, 1, 2])):
            keys[key] = rng.choice(_MAP_KEYS[key])
        image = rng.choice(["png"] * 5 + ["pgm", "missing", "junk", "huge_header", "dir"])
        bomb = rng.random() < 0.1
        cases.append({"kind": "map", "shape": shape, "content": content, "keys": keys,
                      "image": image, "bomb": bomb, "seed": rng.randrange(2**31)})  # fmt: skip
    return cases


def action_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` actions: text, bytes, bools, mappings, nested lists, arrays of odd dtypes and shapes."""
    rng = random.Random(seed)
    pool = [
        {"text": "12"}, {"bytes": "12"}, {"list": ["0.1", "2"]}, {"dict": {"steer": 0.1}},
        {"list": [True, True]}, {"list": [0.1, True]}, {"list": [0.1]}, {"list": [0.1, 1, 2]},
        {"list": [[0.1, 1.0]]}, {"list": ["nan", 1.0]}, {"list": [1e308, -1e308]},
        {"list": [0.1, 1.0]}, {"tuple": [0, 1]}, {"none": None}, {"number": 3.0},
        {"array": [0.1, 1.0], "dtype": "float32"}, {"array": [1, 2], "dtype": "int64"},
        {"array": [1, 0], "dtype": "bool"}, {"array": [1, 2], "dtype": "complex128"},
        {"array": ["1", "2"], "dtype": "U1"}, {"array": [0.1, 1.0, 2.0], "dtype": "float64"},
        {"array": [[0.1, 1.0]], "dtype": "float64"}, {"array": [0.1, "inf"], "dtype": "float64"},
        {"array": [1, 2], "dtype": "uint8"}, {"array": [0.1, 1.0], "dtype": "object"},
    ]  # fmt: skip
    cases = [{"kind": "action", "reset_first": rng.random() > 0.1, **rng.choice(pool)}
             for _ in range(n)]  # fmt: skip
    return cases


def cli_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` ``racecar-sim drive`` command lines with a hostile ``--env`` value (parsed, and run
    for 0.2 s when accepted)."""
    rng = random.Random(seed)
    names = sorted(_env_fields())
    cases = []
    for _ in range(n):
        name = rng.choice(names)
        if name in _NESTED:
            text = "{" + rng.choice(_NESTED[name]) + ": " + rng.choice(HOSTILE_TEXTS) + "}"
        else:
            text = rng.choice(HOSTILE_TEXTS)
        cases.append({"kind": "cli", "argv": ["drive", "--env", f"{name}={text}"]})
    return cases


def bag_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` damaged copies of a recorded bag: byte flips, a cut, a repeated or a dropped span."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        how = rng.choice(["flip", "flip", "cut", "repeat", "drop", "zero"])
        cases.append({"kind": "bag", "how": how, "seed": rng.randrange(2**31),
                      "count": rng.choice([1, 4, 32])})  # fmt: skip
    return cases
