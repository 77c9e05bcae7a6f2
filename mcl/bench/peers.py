"""Benchmarks against the real peers, measured in the same run: ``racecar-sim bench peers``.

* range_libc ([`mcl.bench.peer_rangelibc`][mcl.bench.peer_rangelibc]): our full MCL update against a kctess5-style update
  on range_libc's giant lookup table, Stata basement, 4 000 particles x 100 beams by default;
  skipped with a message when ``range_libc`` is not importable. ``--default-filter`` also times
  the default filter's whole per-scan work ([`mcl.bench.default_update`][mcl.bench.default_update]).

* spread ([`mcl.bench.peer_spread`][mcl.bench.peer_spread]): the same update on clouds spread uniformly over the free
  space (global localization; ``--spread-particles``, 4 000 and 10 000 by default) and on a
  tracking cloud, interleaved with the GLT update round by round (``--spread-rounds``); then a
  global start's first update (236 k particles on Stata) and whole global-start replays of the
  shared bags, with the Z-order sort and without ([`mcl.bench.global_start`][mcl.bench.global_start],
  ``--global-rounds``, 0 skips them).

* races ([`mcl.bench.peer_race`][mcl.bench.peer_race]): agent-steps per second of ``--race-cars`` cars one behind
  the other, every car scanning every step, against f1tenth_gym's multi-agent env, and our race
  alone at ``--race-max-cars`` cars.

* f1tenth_gym ([`mcl.bench.peer_f1tenth`][mcl.bench.peer_f1tenth]): simulator steps per second on f1tenth_gym's own
  workload (one car, 1080 beams over 4.7 rad, 30 m, a scan every step, dt 0.01 s, slalom at
  1 m/s), our single env and our vector env of ``--num-envs`` cars interleaved with it round by
  round; f1tenth_gym runs in its own venv (``--f1tenth-python``, ``--f1tenth-path``), skipped
  with a message when those are not given.

* amcl ([`mcl.bench.amcl_bench`][mcl.bench.amcl_bench]): localization error of our filter against nav2's amcl
  (PyPI ``amcl``, GPL-3: its own venv, ``--amcl-python`` / ``$AMCL_PYTHON`` or made in
  ``out/peers/amcl-venv`` on first use, run as a subprocess) on the same recorded 60 s drives,
  ``--seeds`` seeds in the honest world (cluttered and clean scenes) and the ideal one; tables in
  ``--out``, kept per world, seed and filter (``--amcl-rerun ours`` runs ours again on the
  recorded drives and keeps amcl's rows); skipped with a message when the venv cannot be made.

Other peers add their part as a function ``part(args) -> int`` in `PARTS` and their options
in `add_arguments()`. Every part prints its workload (particles, beams, range, threads) and
ratios from the same run.

    .venv/bin/python scripts/bench_peers.py [--map YAML] [--particles 4000] [--beams 100]
        [--only rangelibc|spread|f1tenth|race|amcl] [--default-filter] [--seeds 20] [--amcl-worlds cluttered clean ideal cluttered_kidnap clean_kidnap] [--amcl-python PY] [--amcl-rerun ours] [--ours-filter KEY=VALUE] [--out DIR] [--spread-particles 4000 10000] [--spread-rounds 8] [--spread-clock wall|cpu] [--global-rounds 3] [--race-cars 2 4 8 16] [--race-max-cars 32] [--f1tenth-python VENV/bin/python --f1tenth-path CHECKOUT]
        [--sim-steps 1000] [--sim-runs 5] [--num-envs 32]
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path

from mcl.bench import missing_map, shared_dir, stata_map
from racecar_sim.file_guard import claim_folder, folder_problem


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The range_libc part's options."""
    parser.add_argument(
        "--map", type=Path, default=stata_map(), help="map YAML (default: ../shared's Stata map)"
    )
    parser.add_argument("--particles", type=int, default=4000, help="particles (MCL part)")
    parser.add_argument("--beams", type=int, default=100, help="beams per particle (MCL part)")
    parser.add_argument("--updates", type=int, default=20, help="timed updates (median)")
    parser.add_argument("--warmup", type=int, default=3, help="untimed updates first")
    parser.add_argument(
        "--threads", type=int, nargs="+", default=[1, 2], help="numba threads for ours"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--default-filter", action="store_true",
        help="also time the default filter's per-scan work (rangelibc part; scans along a path)",
    )  # fmt: skip
    parser.add_argument(
        "--only",
        choices=("rangelibc", "spread", "f1tenth", "race", "amcl"),
        help="run one part only",
    )
    parser.add_argument(
        "--spread-particles", type=int, nargs="+", default=[4000, 10000],
        help="sizes of the clouds spread over free space (spread part)",
    )  # fmt: skip
    parser.add_argument("--spread-rounds", type=int, default=8, help="rounds (spread part)")
    parser.add_argument(
        "--spread-clock", choices=("wall", "cpu"), default="wall",
        help="time the spread part's updates in wall or process CPU seconds (a shared machine)",
    )  # fmt: skip
    parser.add_argument(
        "--global-rounds", type=int, default=3,
        help="rounds of a global start's first update and bag replays (spread part; 0 skips)",
    )  # fmt: skip
    parser.add_argument("--f1tenth-python", help="python of a venv with f1tenth_gym installed")
    parser.add_argument("--f1tenth-path", help="the f1tenth_gym checkout (branch dev-dynamics)")
    parser.add_argument("--sim-steps", type=int, default=1000, help="steps per simulator run")
    parser.add_argument("--sim-runs", type=int, default=5, help="simulator runs (median)")
    parser.add_argument("--num-envs", type=int, default=32, help="cars in our vector env")
    parser.add_argument("--vector-steps", type=int, default=300, help="steps per vector run")
    parser.add_argument(
        "--race-cars", type=int, nargs="+", default=[2, 4, 8, 16], help="cars per race (race part)"
    )
    parser.add_argument("--race-max-cars", type=int, default=32, help="cars of our race alone")
    parser.add_argument("--race-steps", type=int, default=300, help="steps per race run")
    parser.add_argument("--race-runs", type=int, default=3, help="race rounds (median)")
    parser.add_argument("--race-workers", type=int, default=1, help="threads casting our scans")
    parser.add_argument(
        "--race-spacing", type=float, default=1.0, help="metres between the cars' rear axles"
    )
    parser.add_argument("--seeds", type=int, default=20, help="drives per world (amcl part)")
    parser.add_argument(
        "--amcl-worlds", nargs="+", default=["cluttered", "clean", "ideal"],
        choices=("cluttered", "clean", "ideal", "cluttered_kidnap", "clean_kidnap"),
        help="worlds of the amcl part (the _kidnap ones: the car carried away at 10 s)",
    )  # fmt: skip
    parser.add_argument("--amcl-duration", type=float, default=60.0,
                        help="simulated seconds per drive (amcl part)")  # fmt: skip
    parser.add_argument(
        "--amcl-python", help="python of a venv with PyPI amcl (default: $AMCL_PYTHON, else "
        "out/peers/amcl-venv, made on first use)",
    )  # fmt: skip
    parser.add_argument(
        "--amcl-rerun", nargs="+", default=[], choices=("ours", "amcl", "amcl_recovery"),
        help="drop these filters' rows from --out's amcl_results.csv and run them again on the "
        "recorded drives, keeping the other filters' rows (amcl part)",
    )  # fmt: skip
    parser.add_argument(
        "--ours-filter", action="append", default=[], metavar="KEY=VALUE",
        help="a setting of our filter in the amcl part (LocalizationConfig, dotted, YAML values: "
        "filter.odometry_scale.initial=1.056); with --amcl-rerun ours on a copy of --out",
    )  # fmt: skip
    parser.add_argument(
        "--amcl-filter-map", type=Path, default=None, metavar="YAML",
        help="the map every filter holds in the amcl part, e.g. one from racecar-sim update-map "
        "(default: ../shared/maps/stata_basement.yaml); give it its own --out",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("out/peers/amcl"),
                        help="folder of the amcl part's tables and drives")  # fmt: skip


def rangelibc_part(args: argparse.Namespace) -> int:
    """The MCL update against range_libc's GLT (skipped when range_libc is missing)."""
    from mcl.bench import peer_rangelibc

    print("== MCL update vs range_libc (giant lookup table), one run ==")
    if not peer_rangelibc.available():
        print(f"skipped: {peer_rangelibc.INSTALL_HINT}")
        return 0
    from racecar_sim.maps import load_map

    peer_rangelibc.compare(
        load_map(args.map),
        n_particles=args.particles,
        n_beams=args.beams,
        updates=args.updates,
        warmup=args.warmup,
        seed=args.seed,
        threads=tuple(args.threads),
        default_filter=args.default_filter,
    )
    return 0


def spread_part(args: argparse.Namespace) -> int:
    """The MCL update on clouds spread over the free space against the GLT update (ours alone
    when range_libc is missing)."""
    from mcl.bench import peer_spread
    from racecar_sim.maps import load_map

    print("== MCL update on spread clouds (global localization) vs range_libc GLT, one run ==")
    peer_spread.compare_spread(
        load_map(args.map),
        sizes=tuple(args.spread_particles),
        n_beams=args.beams,
        rounds=args.spread_rounds,
        seed=args.seed,
        threads=tuple(args.threads),
        clock=args.spread_clock,
    )
    if args.global_rounds > 0:
        global_part(args)
    return 0


def global_part(args: argparse.Namespace) -> None:
    """A global start's first update (236 k particles on Stata) against the GLT, and whole
    global-start replays of the shared bags ([`mcl.bench.global_start`][mcl.bench.global_start])."""
    from mcl.bench import global_start, shared_dir
    from racecar_sim.maps import load_map

    print("== global start: the first update, and whole replays of the bags ==")
    grid = load_map(args.map)
    global_start.first_update(grid, n_beams=args.beams, rounds=args.global_rounds, seed=args.seed)
    bags = sorted((shared_dir() / "bags").glob("*.bag"))
    if not bags:
        print(f"no bag in {shared_dir() / 'bags'}: replays skipped")
        return
    global_start.bag_replays(grid, bags, rounds=args.global_rounds)


def _check_peer_flags(args: argparse.Namespace) -> int:
    """2 (after a one-line error naming the flag) when the f1tenth_gym flags are unusable, else 0."""
    if bool(args.f1tenth_python) != bool(args.f1tenth_path):
        print("racecar-sim bench peers: error: give both --f1tenth-python and --f1tenth-path",
              file=sys.stderr)  # fmt: skip
        return 2
    for flag, value in (("--f1tenth-python", args.f1tenth_python),
                        ("--f1tenth-path", args.f1tenth_path)):  # fmt: skip
        if value and not Path(value).exists():
            print(f"racecar-sim bench peers: error: {flag} {value} does not exist", file=sys.stderr)
            return 2
    return 0


def f1tenth_part(args: argparse.Namespace) -> int:
    """Simulator steps per second against f1tenth_gym on its workload (peer in its own venv)."""
    from mcl.bench import peer_f1tenth
    from racecar_sim.maps import load_map

    print("== simulator vs f1tenth_gym (its workload), one run ==")
    status = _check_peer_flags(args)
    if status:
        return status
    peer_f1tenth.compare(
        load_map(args.map),
        args.map,
        args.f1tenth_python,
        args.f1tenth_path,
        steps=args.sim_steps,
        runs=args.sim_runs,
        num_envs=args.num_envs,
        vector_steps=args.vector_steps,
    )
    return 0


def race_part(args: argparse.Namespace) -> int:
    """Agent-steps per second of a race against f1tenth_gym's multi-agent env (every car scans)."""
    from mcl.bench import peer_race
    from racecar_sim.maps import load_map

    print("== race vs f1tenth_gym's multi-agent env, one run ==")
    status = _check_peer_flags(args)
    if status:
        return status
    try:
        peer_race.compare_race(
            load_map(args.map),
            args.map,
            args.f1tenth_python,
            args.f1tenth_path,
            sizes=tuple(args.race_cars),
            max_cars=args.race_max_cars,
            steps=args.race_steps,
            runs=args.race_runs,
            spacing=args.race_spacing,
            workers=args.race_workers,
        )
    except ValueError as exc:
        print(f"racecar-sim bench peers: error: {exc}", file=sys.stderr)
        return 2
    return 0


def amcl_part(args: argparse.Namespace) -> int:
    """Localization error of our filter against nav2's amcl on the same drives (amcl in its own
    venv; skipped with the reason when it cannot be had)."""
    from mcl.bench import amcl_bench, peer_amcl
    from mcl.wrappers.localization import as_localization_config, dotted_settings

    print("== localization vs nav2 amcl, the same recorded drives ==")
    kidnaps = [w for w in args.amcl_worlds if amcl_bench.WORLDS[w].kidnap_at is not None]
    if kidnaps and not args.amcl_duration > amcl_bench.KIDNAP_AT:
        print(f"racecar-sim bench peers: --amcl-duration {args.amcl_duration:g}: the kidnap "
              f"worlds ({', '.join(kidnaps)}) carry the car away at {amcl_bench.KIDNAP_AT:g} s; "
              "give more seconds than that", file=sys.stderr)  # fmt: skip
        return 2
    try:
        config = as_localization_config(dotted_settings(args.ours_filter))
    except (TypeError, ValueError) as exc:
        print(f"racecar-sim bench peers: --ours-filter: {exc}", file=sys.stderr)
        return 2
    problem = folder_problem(args.out)  # its tables are replaced: only in a folder of ours
    if problem is not None:
        print(f"racecar-sim bench peers: --out: {problem}", file=sys.stderr)
        return 2
    maps = shared_dir() / "maps"
    needed = [maps / amcl_bench.FILTER_MAP, *{maps / amcl_bench.WORLDS[w].world_map
                                              for w in args.amcl_worlds}]  # fmt: skip
    absent = [p for p in needed if not p.is_file()]
    if absent:
        print(f"skipped: {absent[0]} not found (../shared beside the checkout holds the maps)")
        return 0
    if args.amcl_filter_map is not None:
        from racecar_sim.maps import MapError, load_map

        try:
            load_map(args.amcl_filter_map)
        except (MapError, OSError, ValueError) as exc:
            print(f"racecar-sim bench peers: --amcl-filter-map: {exc}", file=sys.stderr)
            return 2
    python, why = peer_amcl.amcl_python(args.amcl_python)
    if python is None:
        print(f"skipped: {why}")
        return 0
    print(f"{args.seeds} seeds x {args.amcl_duration:g} s x worlds {', '.join(args.amcl_worlds)}; "
          f"amcl from {python}; results into {args.out}")  # fmt: skip
    claim_folder(args.out)
    try:
        rows = amcl_bench.run_benchmark(
            python, args.amcl_worlds, args.seeds, args.amcl_duration, args.out, config,
            rerun=args.amcl_rerun, filter_map=args.amcl_filter_map,
        )  # fmt: skip
    except amcl_bench.MixedMaps as exc:
        print(f"racecar-sim bench peers: --out: {exc}", file=sys.stderr)
        return 2
    name = (args.amcl_filter_map or maps / amcl_bench.FILTER_MAP).name
    print(amcl_bench.results_md(rows, args.seeds, args.amcl_duration, args.amcl_worlds, name))
    return 0


PARTS: list[Callable[[argparse.Namespace], int]] = [
    rangelibc_part,
    spread_part,
    f1tenth_part,
    race_part,
    amcl_part,
]
"""The peer comparisons run by `main()`, in order."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    add_arguments(parser)
    args = parser.parse_args(argv)
    for name in ("particles", "beams", "updates"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1")
    if any(t < 1 for t in args.threads):
        parser.error("--threads must be at least 1")
    if any(n < 1 for n in args.race_cars) or args.race_max_cars < 1 or not args.race_spacing > 0:
        parser.error("--race-cars and --race-max-cars must be at least 1, --race-spacing positive")
    if args.race_workers < 1:
        parser.error("--race-workers must be at least 1")
    if any(n < 1 for n in args.spread_particles) or args.spread_rounds < 1:
        parser.error("--spread-particles and --spread-rounds must be at least 1")
    if args.seeds < 1 or not 0 < args.amcl_duration <= 86400:
        parser.error("--seeds must be at least 1 and --amcl-duration in (0, 86400] seconds")
    if args.global_rounds < 0:
        parser.error("--global-rounds must be at least 0")
    for name in ("sim_steps", "sim_runs", "num_envs", "vector_steps", "race_steps", "race_runs"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1")
    if not args.map.is_file():
        parser.error(missing_map("--map", args.map))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{os.cpu_count()} CPUs, load average {load:.1f} before the run")
    status = 0
    for part in PARTS:
        if args.only and part.__name__ != f"{args.only}_part":
            continue
        status = max(status, part(args))
    return status


if __name__ == "__main__":
    sys.exit(main())
