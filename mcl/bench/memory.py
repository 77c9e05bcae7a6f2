"""Benchmark: resident memory per car of the vector env, reset without poses (random starts).

For each number of cars (default 1, 32 and 128), a fresh Python process loads the map (its distance
field included), warms the numba kernels up on a small bundled map, notes its resident set size
(``VmRSS``), makes ``RacecarVectorEnv(num_envs=N)`` on the map, resets it without poses (every car
draws a random start) and notes the resident set again. The difference is what N cars add: their
physics, lidars and odometry, and whatever each builds for itself (a random-start table per car
costs about 2.7 MB on the Stata basement) or shares with the others (the exact caster's field,
the start table when shared: paid once, divided by N).

Usage: ``racecar-sim bench memory [--cars 1,32,128] [--map MAP.yaml]`` (the default map is the
Stata basement in ``../shared/maps``). Linux only (``/proc/self/status``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from mcl.bench import STATA, missing_map

__all__ = ["main", "measure", "resident_mb"]

_WARM_MAP = "office"  # a small bundled map: compiles (or loads) the kernels before the baseline


def resident_mb() -> float:
    """This process's resident set size now, MB (10^6 bytes), from ``/proc/self/status``."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024 / 1e6
    raise RuntimeError("no VmRSS in /proc/self/status")  # pragma: no cover - Linux has it


def measure(map_path: str, n_cars: int, seed: int = 0) -> dict[str, float]:
    """In this process: the resident MB before and after ``n_cars`` cars on ``map_path`` are made
    and reset without poses (see the module doc)."""
    import gymnasium as gym  # noqa: F401  (the env's imports, before the baseline)

    from racecar_sim.maps import resolve_map
    from racecar_sim.vector_env import RacecarVectorEnv

    grid = resolve_map(map_path)
    grid.distance  # noqa: B018  (the map's distance field is the map's, not the cars')
    warm = RacecarVectorEnv(2, _WARM_MAP)
    warm.reset(seed=seed)
    warm.step(warm.action_space.sample() * 0.0)
    del warm
    before = resident_mb()
    env = RacecarVectorEnv(n_cars, grid)
    env.reset(seed=seed)
    after = resident_mb()
    return {"cars": n_cars, "before_mb": before, "after_mb": after}


def _child(map_path: str, n_cars: int) -> dict[str, float]:
    """`measure` in a fresh Python process (nothing left from an earlier count)."""
    code = (
        "import json, sys; from mcl.bench.memory import measure; "
        "print(json.dumps(measure(sys.argv[1], int(sys.argv[2]))))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, map_path, str(n_cars)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    if done.returncode != 0:
        raise SystemExit(f"bench memory: {n_cars} cars failed: {done.stderr.strip()[-500:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _cars(text: str) -> list[int]:
    try:
        counts = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--cars must be positive integers, got {text!r}"
        ) from None
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(f"--cars must be positive integers, got {text!r}")
    return counts


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cars", type=_cars, default=[1, 32, 128],
                        help="numbers of cars, comma-separated (default: 1,32,128)")  # fmt: skip
    parser.add_argument("--map", default=None, help="map YAML (default: the Stata basement)")
    args = parser.parse_args(argv)
    map_path = Path(args.map) if args.map is not None else STATA
    if not map_path.is_file():
        print(f"bench memory: {missing_map('--map', map_path)}", file=sys.stderr)
        return 2
    print(f"vector env reset without poses on {map_path.name} (resident MB, a fresh process each)")
    print("| cars | before | after | added | per car |")
    print("|---:|---:|---:|---:|---:|")
    for n in args.cars:
        row = _child(str(map_path), n)
        added = row["after_mb"] - row["before_mb"]
        print(f"| {n} | {row['before_mb']:.1f} | {row['after_mb']:.1f} | {added:.1f} | "
              f"{added / n:.2f} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
