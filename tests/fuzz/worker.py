"""Runs fuzz cases in this process and prints one JSON line per case (what happened, how long).

``python -m tests.fuzz.worker`` reads a JSON list of cases (:mod:`tests.fuzz.mutations`) on
stdin. The caller (:func:`tests.fuzz.harness.run_cases`) starts it under a memory and a time
limit, so a case that grows without bound or hangs ends the worker instead of the machine.

An outcome is ``ok`` (the input was accepted and the run was correct: observations of the right
shape, finite, in range), ``error`` (an exception: its type and message), or for a command line
its exit code and stderr.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import resource
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from tests.fuzz.api_runners import run_localization_api, run_race_api
from tests.fuzz.file_worker import remove_case_folder, run_path, run_scan
from tests.fuzz.hostile_maps import alias_bomb, fake_png, small_png
from tests.fuzz.live_cases import run_live
from tests.fuzz.mutations import decode

_SMALL = {"map": "corridor", "n_beams": 60}


def _check_obs(env: Any, obs: dict[str, np.ndarray]) -> None:
    """A correct observation: the scan's shape, finite and within [0, max_range]."""
    scan = obs["scan"]
    n = env.unwrapped.lidar_params.n_beams
    assert scan.shape == (n,), f"scan shape {scan.shape} != ({n},)"
    assert np.isfinite(scan).all() and (scan >= 0).all(), "scan not finite and >= 0"
    assert (scan <= env.unwrapped.lidar_params.max_range + 1e-6).all(), "scan beyond max_range"
    assert np.isfinite(obs["odom"]).all(), "odometry not finite"


def _drive(env: Any, steps: int = 3) -> None:
    obs, _ = env.reset(seed=0)
    _check_obs(env, obs)
    for _ in range(steps):
        obs, reward, terminated, _, _ = env.step(np.array([0.1, 1.0]))
        _check_obs(env, obs)
        assert math.isfinite(reward), "reward not finite"
        if terminated:
            break


def run_setting(case: dict[str, Any], tmp: Path) -> None:
    from racecar_sim.env import RacecarEnv

    settings = decode(case["settings"])
    _drive(RacecarEnv(**{**_SMALL, **settings}))


def run_filter(case: dict[str, Any], tmp: Path) -> None:
    from mcl.wrappers.localization import LocalizationConfig
    from mcl.wrappers.single import LocalizationWrapper
    from racecar_sim.env import RacecarEnv

    config = LocalizationConfig(**{case["section"]: {case["name"]: decode(case["value"])}})
    env = LocalizationWrapper(RacecarEnv(**_SMALL), config)
    _drive(env, steps=2)


def _image(case: dict[str, Any]) -> np.ndarray:
    rng = np.random.default_rng(case["seed"])
    h, w = case["shape"]
    content = case["content"]
    if content == "free":
        return np.full((h, w), 254, np.uint8)
    if content == "occupied":
        return np.zeros((h, w), np.uint8)
    if content == "grey":
        return np.full((h, w), 205, np.uint8)
    if content == "noise":
        return rng.integers(0, 256, (h, w), dtype=np.uint8)
    img = np.full((h, w), 254, np.uint8)  # a room: free with a wall border
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    return img


def run_map(case: dict[str, Any], tmp: Path) -> None:
    from racecar_sim.env import RacecarEnv

    image = case["image"]
    name = {"pgm": "map.pgm", "dir": "folder"}.get(image, "map.png")
    if image in ("png", "pgm"):
        small_png(tmp / name, _image(case))
    elif image == "junk":
        (tmp / name).write_bytes(b"this is not an image" * 10)
    elif image == "huge_header":
        fake_png(tmp / name, 14000, 14000)
    elif image == "dir":
        (tmp / name).mkdir()
    keys = {"image": name, **case["keys"]}
    text = "".join(f"{k}: {v}\n" for k, v in keys.items())
    if case["bomb"]:
        text = text.replace("mode:", "mode_was:") + alias_bomb() + "mode: *a8\n"
    (tmp / "map.yaml").write_text(text)
    _drive(RacecarEnv(str(tmp / "map.yaml"), n_beams=60))


def _action(case: dict[str, Any]) -> Any:
    if "text" in case:
        return case["text"]
    if "bytes" in case:
        return case["bytes"].encode()
    if "dict" in case:
        return case["dict"]
    if "tuple" in case:
        return tuple(decode(case["tuple"]))
    if "list" in case:
        return decode(case["list"])
    if "none" in case:
        return None
    if "number" in case:
        return case["number"]
    return np.array(decode(case["array"]), dtype=case["dtype"])


def run_action(case: dict[str, Any], tmp: Path) -> None:
    from racecar_sim.env import RacecarEnv

    env = RacecarEnv(**{**_SMALL, "n_beams": 30})
    if case["reset_first"]:
        env.reset(seed=0)
    obs, *_ = env.step(_action(case))
    _check_obs(env, obs)


def run_cli(case: dict[str, Any], tmp: Path) -> dict[str, Any]:
    from mcl.cli.main import main

    argv = list(case["argv"])
    if argv[0] == "drive":  # a short quiet drive into the case's folder, unless the case says
        defaults = {"--duration": "0.2", "--video-fps": "0", "--particles": "200"}
        for flag, value in defaults.items():
            if flag not in argv:
                argv += [flag, value]
        argv += ["--quiet", "--out", str(tmp / "out")]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    left = sorted(p.name for p in tmp.iterdir())
    return {"outcome": "exit", "exit": code, "stderr": err.getvalue(), "left": left}


_BAG: dict[str, Path] = {}


def _recorded_bag() -> Path:
    """A 1.5 s synthetic drive recorded once per worker (tests/io/bag_fixtures.py)."""
    if "path" not in _BAG:
        from tests.conftest import room_map
        from tests.io.bag_fixtures import record_drive

        folder = Path(tempfile.mkdtemp(prefix="fuzz_bag_"))
        record_drive(folder / "drive", room_map(), duration=1.5)
        _BAG["path"] = folder / "drive"
    return _BAG["path"]


def run_bag(case: dict[str, Any], tmp: Path) -> None:
    from mcl.io import read_bag

    source = _recorded_bag()
    target = tmp / "bag"
    shutil.copytree(source, target)
    mcap = next(target.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    rng = np.random.default_rng(case["seed"])
    n = len(data)
    if case["how"] == "flip":
        for i in rng.integers(0, n, case["count"]):
            data[int(i)] ^= 1 << int(rng.integers(8))
    elif case["how"] == "zero":
        i = int(rng.integers(0, n))
        data[i : i + 64 * case["count"]] = bytes(len(data[i : i + 64 * case["count"]]))
    elif case["how"] == "cut":
        data = data[: int(rng.integers(0, n))]
    else:
        i, j = sorted(int(v) for v in rng.integers(0, n, 2))
        data = data[:j] + data[i:j] + data[j:] if case["how"] == "repeat" else data[:i] + data[j:]
    mcap.write_bytes(bytes(data))
    bag = read_bag(target)
    assert len(bag.scan_times) == len(bag.scans) > 0, "no scans, or times and scans differ"
    assert np.isfinite(bag.scan_times).all(), "scan times not finite"


RUNNERS = {
    "race_api": run_race_api,
    "localization_api": run_localization_api,
    "setting": run_setting,
    "filter": run_filter,
    "map": run_map,
    "action": run_action,
    "cli": run_cli,
    "bag": run_bag,
    "path": run_path,
    "scan": run_scan,
    "live": run_live,
}


def run_case(case: dict[str, Any]) -> dict[str, Any]:
    """One case: its outcome, error type and message (a traceback's last lines for a bug)."""
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="fuzz_"))
    try:
        extra = RUNNERS[case["kind"]](case, tmp) or {"outcome": "ok"}
        result = {**extra}
    except AssertionError as exc:
        result = {"outcome": "wrong", "type": "AssertionError", "message": str(exc)}
    except Exception as exc:  # every exception is reported; the test judges it
        result = {
            "outcome": "error",
            "type": type(exc).__name__,
            "mro": [c.__name__ for c in type(exc).__mro__],
            "message": str(exc),
            "where": "".join(traceback.format_exception(exc)[-3:])[-600:],
        }
    finally:
        remove_case_folder(tmp)
    result["seconds"] = time.perf_counter() - t0
    result["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB
    return result


def main() -> int:
    cases = json.load(sys.stdin)
    for i, case in enumerate(cases):
        result = run_case(case)
        print(json.dumps({"index": i, **result}), flush=True)
    for path in _BAG.values():
        shutil.rmtree(path.parent, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
