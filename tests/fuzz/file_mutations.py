"""Seeded hostile inputs for file safety: command-line paths and ROS 2 / MCAP scan headers.

``path_cases``: a command with ``--out`` (and, for ``drive``, ``--bag``) given an extreme path
(long names, long paths, ``''``, NUL, ``.``/``..``, multibyte names) or a path onto something
that is already there (a folder of someone's files that must survive, a file where a folder
belongs, an empty folder, a folder of ours, a recording of ours, a link), or ``--bag`` and
``--out`` overlapping in several spellings. Everything lies inside the case's own temporary
folder (the worker runs each case from a folder inside it); no case names ``/`` or any system
folder.

``scan_cases``: a small ROS 2 bag (MCAP or sqlite3) whose LaserScan header is hostile (0 or huge
beam counts, NaN / infinite angles and ranges, ranges whose length disagrees with the angles),
read with ``read_bag`` or replayed with ``racecar-sim replay``.
"""

from __future__ import annotations

import random
from typing import Any

__all__ = ["EXISTING", "path_cases", "scan_cases"]

EXISTING = ("user", "file", "empty", "ours", "recording", "link")
"""What the worker puts in the case's folder before the command: ``user`` a folder of someone's
files (nested, hidden), ``file`` a file, ``empty`` an empty folder, ``ours`` a folder racecar-sim
made (with a user's note in it), ``recording`` a recording of ours, ``link`` a link to ``user``."""

_D = "d" * 99
_PATHS: list[str] = [
    "", ".", "..", "new", "new/", "a/./b/../c", "out\0x", "n" * 250, "n" * 251, "n" * 255,
    "n" * 256, "n" * 1000, "é" * 127, "é" * 128, "/".join([_D] * 38), "/".join([_D] * 39),
    "/".join([_D] * 41), "/".join([_D] * 50), "x/" * 2000, "/".join([_D] * 1000), "{user}",
    "{user}/inner", "{file}", "{file}/x", "{empty}", "{ours}", "{ours}/sub", "{recording}",
    "{link}", "{link}/inner", "-", "--out", " ", "new\nline",
]  # fmt: skip
"""Path texts; ``{name}`` is the thing of [EXISTING][tests.fuzz.file_mutations.EXISTING] of that
name."""

_COMMANDS = {  # command -> its other arguments (cheap settings; heavy runs are stubbed)
    "drive": ["--duration", "0.2", "--video-fps", "0", "--particles", "100", "--map", "corridor",
              "--quiet"],
    "experiment": ["--seeds", "1", "--duration", "0.5"],
    "ablation": ["--seeds", "1"],
    "fast-laps": ["--seeds", "1", "--duration", "1"],
    "opponents": ["--seeds", "1", "--duration", "1"],
    "train-agent": ["--timesteps", "10"],
    "make-maps": [],
    "replay": ["missing.bag", "--map", "corridor"],
    "calibrate-noise": ["{file}", "--map", "{file}"],
}  # fmt: skip


def path_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` command lines with an extreme ``--out`` / ``--bag`` (see the module docstring)."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        command = rng.choice(["drive"] * 5 + sorted(_COMMANDS))
        argv = [command, *_COMMANDS[command], "--out", rng.choice(_PATHS)]
        if command == "drive" and rng.random() < 0.5:
            out = argv[-1]
            overlap = [out, f"{out}/bag", f"{out}/./x/..", out.rstrip("/") + "/../" + out]
            bag = rng.choice(_PATHS + overlap if out not in ("", ".", "..") else _PATHS)
            argv += ["--bag", bag]
        cases.append({"kind": "path", "command": True, "argv": argv,
                      "existing": rng.sample(EXISTING, rng.randint(1, len(EXISTING)))})  # fmt: skip
    return cases


_NAN, _INF = "nan", "inf"
_HEADER_POOLS: dict[str, list[Any]] = {
    "beams": [0, 1, 2, 10, 1081, 10_000, 10_001, 100_000, 2_000_000],
    "angle_min": [-2.35, 0.0, _NAN, _INF, "-inf", 1e30, -7.0, 6.28],
    "angle_increment": [0.0058, 0.1, -0.1, 0.0, _NAN, _INF, 1e-300, 1e30, 7.0],
    "range_min": [0.02, 0.0, -1.0, _NAN, 40.0, _INF],
    "range_max": [30.0, 5.0, 1e-9, 0.0, -1.0, _NAN, _INF, 1e6, 1000.0],
}  # fmt: skip


def scan_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` bags with one to three hostile LaserScan header fields, and sometimes a ranges array
    whose length disagrees with the header, read (``via: read``) or replayed (``via: cli``)."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        fields: dict[str, Any] = {"beams": 10, "angle_increment": 0.1}
        for name in rng.sample(sorted(_HEADER_POOLS), rng.choice([1, 1, 2, 3])):
            fields[name] = rng.choice(_HEADER_POOLS[name])
        beams = fields["beams"]
        if rng.random() < 0.25:
            fields["n_ranges"] = rng.choice([0, max(beams - 1, 0), beams + 5, 2 * beams])
        if max(beams, fields.get("n_ranges", 0)) > 20_000:
            fields["scans"] = 2  # huge scans: two are enough to refuse (and quick to write)
        via = "cli" if rng.random() < 0.3 else "read"
        case = {"kind": "scan", "storage": rng.choice(["mcap", "sqlite3"]), "fields": fields,
                "via": via}  # fmt: skip
        if via == "cli":
            case["command"] = True
        cases.append(case)
    return cases
