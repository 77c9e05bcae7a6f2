"""Scripted races on the bundled loop maps: contacts, passes, laps per car by speed.

``racecar-sim bench race-matrix --out DIR`` races, on each loop map and for each count of
opponents, one ``RacecarRace-v0`` race per seed with car 0 driven like the opponents
([run_scripted_race][racecar_sim.race.scripted_race.run_scripted_race]: the grid behind a point of
the track drawn from the seed, the speeds drawn within 0.1 m/s of 2.0, 2.4, ... with car 0 the
fastest, starting last) and writes ``races.csv`` (one row per race) and ``matrix.md``
([matrix_table][racecar_sim.race.scripted_race.matrix_table]). The racing drivers read the
cars' poses, not their scans, so ``--n-beams`` changes the run time and not the races.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

from racecar_sim.race.scripted_race import matrix_table, ordered_share, run_scripted_race
from racecar_sim.world.track import LOOP_STARTS

_FIELDS = ["map", "opponents", "seed", "seconds", "speeds", "laps", "progress", "car_contacts",
           "wall_contacts", "passes", "pairs_in_speed_order", "wall_s"]  # fmt: skip


def _counts(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of whole numbers: {text!r}") from None
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"counts of opponents must be 1 or more, got {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", default=",".join(sorted(LOOP_STARTS)),
                        help="comma-separated bundled loop maps")  # fmt: skip
    parser.add_argument("--opponents", type=_counts, default="1,2,3,4,5",
                        help="counts of opponents, e.g. 1,2,3")  # fmt: skip
    parser.add_argument("--seeds", type=int, default=10, help="races per map and count (0 ...)")
    parser.add_argument("--duration", type=float, default=60.0, help="simulated seconds per race")
    parser.add_argument("--n-beams", type=int, default=61,
                        help="lidar beams per car (the racing drivers do not read the scans)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("out/race_matrix"),
                        help="folder for races.csv and matrix.md")  # fmt: skip
    args = parser.parse_args(argv)
    maps = [m for m in args.maps.split(",") if m]
    unknown = [m for m in maps if m not in LOOP_STARTS]
    if not maps or unknown:
        parser.error(f"--maps: {unknown[0] if unknown else args.maps!r} is not a loop map; "
                     f"choose from {', '.join(sorted(LOOP_STARTS))}")  # fmt: skip
    if args.seeds < 1:
        parser.error(f"--seeds: must be 1 or more, got {args.seeds}")
    if not 0 < args.duration <= 3600:
        parser.error(f"--duration: must be in (0, 3600] seconds, got {args.duration}")
    if args.n_beams < 1:
        parser.error(f"--n-beams: must be 1 or more, got {args.n_beams}")
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    with (args.out / "races.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(_FIELDS)
        for name in maps:
            for k in args.opponents:
                for seed in range(args.seeds):
                    t0 = time.perf_counter()
                    r = run_scripted_race(name, k, seed, args.duration, n_beams=args.n_beams)
                    results.append(r)
                    row = [r.map, r.opponents, r.seed, r.seconds, " ".join(map(str, r.speeds)),
                           " ".join(map(str, r.laps)), " ".join(map(str, r.progress)),
                           r.car_contacts, r.wall_contacts, r.passes,
                           round(ordered_share(r), 3), round(time.perf_counter() - t0, 1)]  # fmt: skip
                    writer.writerow(row)
                    f.flush()
                    print(", ".join(map(str, row)), flush=True)
    table = matrix_table(results)
    (args.out / "matrix.md").write_text(table + "\n")
    print(table)
    return 0
