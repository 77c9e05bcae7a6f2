"""Seeded API misuse of the race and the localization wrappers: sequences of calls (make, reset,
step) with hostile arguments, as JSON-able case dicts that :mod:`tests.fuzz.api_runners` plays.

A race case makes a ``RaceEnv`` (odd ``n_cars`` among them) and calls ``reset`` and ``step`` in a
drawn order: steps before a reset and after every agent is done, actions that are not a dict,
agent names that are not the race's, hostile action values (text, bools, NaN, masked arrays, odd
shapes and dtypes), reset options of the wrong kind, poses that are NaN, infinite, of the wrong
shape, off the map or on another car. A localization case wraps a single, vector or race env
(sometimes the wrong kind) and does the same with the wrappers' own options (``init``,
``init_spread``, ``init_pose``, ``reset_mask``, ``agents``, ``filter_map``).

Each call carries ``bad``: True when it must be refused (a ``ValueError``), False when it must be
taken, None when either is right; the runner adds what the env's state says (a step before a
reset, or once every agent is done, must raise ``ResetNeeded``). The same seed gives the same
cases.
"""

from __future__ import annotations

import random
from typing import Any

__all__ = ["VALUES", "localization_api_cases", "race_api_cases"]

# One action value, encoded for JSON (tests.fuzz.api_runners.action_value decodes it), and whether
# it must be refused.
VALUES: list[tuple[dict[str, Any], bool]] = [
    ({"list": [0.1, 1.0]}, False), ({"tuple": [0, 1]}, False), ({"list": [1e308, -1e308]}, False),
    ({"array": [0.1, 1.0], "dtype": "float32"}, False), ({"array": [1, 2], "dtype": "int64"}, False),
    ({"array": [1, 2], "dtype": "uint8"}, False),
    ({"text": "12"}, True), ({"bytes": "12"}, True), ({"list": ["0.1", "2"]}, True),
    ({"dict": {"steer": 0.1}}, True), ({"list": [True, True]}, True), ({"list": [0.1, True]}, True),
    ({"list": [0.1]}, True), ({"list": [0.1, 1, 2]}, True), ({"list": [[0.1, 1.0]]}, True),
    ({"list": ["nan", 1.0]}, True), ({"list": [0.0, "-inf"]}, True), ({"none": None}, True),
    ({"number": 3.0}, True), ({"array": [1, 0], "dtype": "bool"}, True),
    ({"array": [1, 2], "dtype": "complex128"}, True), ({"array": ["1", "2"], "dtype": "U1"}, True),
    ({"array": [0.1, 1.0, 2.0], "dtype": "float64"}, True),
    ({"array": [0.1, "inf"], "dtype": "float64"}, True),
    ({"array": [0.1, 1.0], "dtype": "object"}, True),
    ({"masked": [0.1, 1.0], "mask": [False, True]}, True),
    ({"masked": [0.1, 1.0], "mask": [False, False]}, True),
]  # fmt: skip

_POSES = ["free", "free", "nan", "inf", "dict", "text", "short", "bools", "far", "wall", "huge",
          "same", "nested_text", "none"]  # fmt: skip
"""How a pose option is drawn (:func:`tests.fuzz.api_runners.poses` builds it on the env's map):
"free" is a free place per car, "same" one place for every car, "huge" 1e300, "short" two numbers
a pose, "nested_text" numbers as text; "none" leaves the option out."""

_SEEDS = [0, 1, 7, None, None, -1, 2.5, "a", True, [0, 1], 2**70]


def _value(rng: random.Random) -> tuple[dict[str, Any], bool]:
    return rng.choice(VALUES)


def _race_actions(rng: random.Random) -> dict[str, Any]:
    """A hostile step's actions: the whole thing of the wrong kind, or a dict with a twist."""
    how = rng.choice(["none", "list", "array", "text", "empty", "extra", "missing", "int_key",
                      "upper", *["value"] * 9])  # fmt: skip
    if how == "value":
        value, bad = _value(rng)
        return {"how": how, "value": value, "bad": bad}
    return {"how": how, "bad": True}


def _race_options(rng: random.Random) -> dict[str, Any]:
    """A hostile reset's options."""
    how = rng.choice(["poses", "poses", "poses", "poses", "list", "text", "int_key", "unknown",
                      "poses_none", "empty"])  # fmt: skip
    if how == "poses":
        pose = rng.choice([p for p in _POSES if p != "none"])
        return {"how": how, "pose": pose, "bad": pose not in ("free", "same") or None}
    return {"how": how, "bad": how in ("list", "text", "int_key") or None}


_VALID_RESET = {"op": "reset", "seed": 0, "options": {"how": "none", "bad": False}}
_VALID_STEP = {"op": "step", "actions": {"how": "valid", "bad": False}}


def _skeleton(rng: random.Random, hostile: Any) -> list[dict[str, Any]]:
    """A valid sequence of calls (a reset, then steps, runs to the end and resets) with 0 to 3 of
    them replaced by ``hostile(rng)`` calls, and sometimes no first reset."""
    ops: list[dict[str, Any]] = [dict(_VALID_RESET)]
    for _ in range(rng.randint(1, 5)):
        kind = rng.choice(["step", "step", "run_out", "reset"])
        if kind == "reset":
            ops.append({**_VALID_RESET, "seed": rng.choice([0, 1, 7, None])})
        else:
            ops.append(dict(_VALID_STEP) if kind == "step" else {"op": "run_out"})
    for _ in range(rng.choice([0, 0, 1, 1, 1, 1, 2, 3])):
        ops[rng.randrange(len(ops))] = hostile(rng)
    if rng.random() < 0.15:
        ops = ops[1:]  # the first call is not a reset
    return ops


def _race_hostile(rng: random.Random) -> dict[str, Any]:
    if rng.random() < 0.35:
        seed = rng.choice(_SEEDS)
        return {"op": "reset", "seed": seed, "options": _race_options(rng)}
    return {"op": "step", "actions": _race_actions(rng)}


def race_api_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` races misused: a map, ``n_cars``, an episode limit and 1 to 6 calls."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        n_cars = rng.choice([1, 2, 3])
        if rng.random() < 0.1:
            n_cars = rng.choice([0, -1, 2.5, "2", True, 101, None])
        elif rng.random() < 0.04:
            n_cars = rng.choice([96, 100])  # the loop's grid holds 95
        cases.append({
            "kind": "race_api",
            "map": rng.choice(["corridor", "corridor", "basement_loop", "office"]),
            "n_cars": n_cars,
            "max_steps": rng.choice([None, 1, 2, 3]),
            "ops": _skeleton(rng, _race_hostile),
        })  # fmt: skip
    return cases


_INITS = [("pose", False), ("global", False), ("nowhere", True), (["pose"], True), (1, True),
          (None, True)]  # fmt: skip
_SPREADS = [(0.1, False), ([0.1, 0.1, 0.05], False), (0, False), (-1, True), ("wide", True),
            ({}, True), ("nan", True), ([1, 2], True), (1e12, True), (1e300, True), (10_000, False)]  # fmt: skip
_WRAPPERS = ("single", "vector", "race")


def _loc_options(rng: random.Random, wrapper: str) -> dict[str, Any]:
    """A hostile reset's options for a wrapper: the filter's options, or options of the wrong
    kind."""
    how = rng.choice(["filter", "filter", "filter", "filter", "list", "text", "int_key"])
    if how != "filter":
        return {"how": how, "bad": True}
    out: dict[str, Any] = {"how": how}
    bad = False
    if rng.random() < 0.4:
        out["init"], b = rng.choice(_INITS)
        bad = bad or b
    if rng.random() < 0.4:
        out["init_spread"], b = rng.choice(_SPREADS)
        bad = bad or bool(b)
    if rng.random() < 0.6:
        out["init_pose"] = rng.choice(_POSES)
        out["one_pose"] = wrapper != "single" and rng.random() < 0.3  # (3,) for every car
        if out["init_pose"] != "none":
            shape_bad = out["one_pose"] and wrapper == "race"
            bad = bad or shape_bad or out["init_pose"] not in ("free", "same")
    if wrapper == "vector" and rng.random() < 0.4:
        out["reset_mask"] = rng.choice([[True, False], [False, True], [False, False], [1, 0],
                                        "ab", [True], None])  # fmt: skip
        # whether the mask fits depends on the number of cars: the runner judges it
    out["bad"] = True if bad else None
    return out


def _loc_actions(rng: random.Random, wrapper: str) -> dict[str, Any]:
    """A hostile step's actions for a wrapper."""
    if wrapper == "race":
        return _race_actions(rng)
    how = rng.choice(["value", "value", "value", "none", "text", "dict"])
    if how == "value":
        value, bad = _value(rng)
        return {"how": how, "value": value, "bad": bad}
    return {"how": how, "bad": True}


def localization_api_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` localization wrappers misused: the wrapper, what it wraps, its arguments, 1 to 6
    calls."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        wrapper = rng.choice(_WRAPPERS)
        wraps = wrapper if rng.random() < 0.85 else rng.choice([*_WRAPPERS, "none"])

        def hostile(r: random.Random, wrapper: str = wrapper) -> dict[str, Any]:
            if r.random() < 0.5:
                return {"op": "reset", "seed": r.choice(_SEEDS[:5]),
                        "options": _loc_options(r, wrapper)}  # fmt: skip
            return {"op": "step", "actions": _loc_actions(r, wrapper)}

        ops = [op for op in _skeleton(rng, hostile) if op["op"] != "run_out"]
        case = {"kind": "localization_api", "wrapper": wrapper, "wraps": wraps, "ops": ops,
                "n_cars": rng.choice([1, 2, 3]), "max_steps": rng.choice([None, 2])}  # fmt: skip
        if wrapper == "single":
            case["filter_map"] = rng.choice([None, None, None, "same", "far", "shifted"])
        if wrapper == "race":
            case["agents"] = rng.choice([None, None, None, [], ["car_0"], ["car_9"], "car_0", [0],
                                         ["car_0", "car_0"]])  # fmt: skip
        if wraps != wrapper:
            owner = {"single": "LocalizationWrapper", "vector": "LocalizedVectorEnv",
                     "race": "LocalizedRaceEnv"}[wrapper]  # fmt: skip
            case.update(clear_types=["TypeError"], owner=owner)
        cases.append(case)
    return cases
