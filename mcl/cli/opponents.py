"""MCL among opponents: the filter's error alone and with cars close ahead, plain and with beam
skipping, against the truth ([`mcl.experiments.opponents_run`][mcl.experiments.opponents_run]).

Every (opponents, method, seed) run drives the map's loop by pure pursuit on the true pose; the
opponents are car-sized boxes held a few metres ahead on the same line (``--backend boxes``).
Writes ``<out>/runs.csv`` (one row per
run), ``<out>/summary.csv`` and ``<out>/summary.md`` (the table: each cell's steps pooled over the
seeds), and the error logs in ``<out>/logs``; prints the table.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

from mcl.cli.common import (
    Parser,
    check_map,
    check_out,
    duration_seconds,
    non_negative_int,
    number_list,
    output_folder,
    path_arg,
    positive_float,
    positive_int,
)
from mcl.cli.compile_notice import compile_notice
from mcl.experiments.opponents_run import (
    BACKENDS,
    METHODS,
    OpponentRun,
    opponents_table,
    run_opponents,
    run_row,
)
from racecar_sim.file_guard import writable

EXAMPLES = """\
examples:
  racecar-sim opponents --seeds 5 --duration 30 --out runs/opponents
  racecar-sim opponents --opponents 0 3 --methods plain --seeds 1 --duration 10 --out runs/quick
"""

COLUMNS = (
    ("opponents", "opponents", "{}"),
    ("method", "method", "{}"),
    ("seeds", "seeds", "{}"),
    ("mean_m", "mean m", "{:.4f}"),
    ("median_m", "median m", "{:.4f}"),
    ("p95_m", "p95 m", "{:.4f}"),
    ("max_m", "max m", "{:.3f}"),
    ("diverged_steps", "steps > 1 m", "{:.1%}"),
    ("diverged_runs", "runs > 1 m", "{}"),
    ("skipped_beams", "beams skipped", "{:.1%}"),
    ("update_ms", "update ms", "{:.2f}"),
)


def build_parser() -> Parser:
    """The ``racecar-sim opponents`` options."""
    parser = Parser("racecar-sim opponents", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--map", default="basement_loop", metavar="NAME|YAML", help="a map with a known loop")
    add("--opponents", nargs="+", type=non_negative_int, default=[0, 1, 3], metavar="K",
        help="opponent counts, one table block each")  # fmt: skip
    add("--methods", nargs="+", choices=list(METHODS), default=list(METHODS), metavar="NAME",
        help=f"filter variants, from: {', '.join(METHODS)}")  # fmt: skip
    add("--seeds", type=positive_int, default=5, metavar="N", help="seeds 0 .. N-1 per cell")
    add("--duration", type=duration_seconds, default=30.0, metavar="S",
        help="simulated seconds per run")  # fmt: skip
    add("--speed", type=positive_float, default=2.0, metavar="M/S", help="the cars' speed")
    add("--gaps", type=number_list, default=(2.0, 3.2, 4.4), metavar="M,M,M",
        help="metres of loop from the car to each opponent (boxes backend)")  # fmt: skip
    add("--particles", type=positive_int, default=1500, metavar="N", help="particles")
    add("--backend", choices=BACKENDS, default="boxes", help="where the opponents come from")
    add("--out", type=path_arg, default=Path("runs/opponents"), metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made")  # fmt: skip
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim opponents``; returns the exit code (2: a user mistake)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    check_map(parser, args.map)
    if max(args.opponents) > len(args.gaps) and args.backend == "boxes":
        parser.error(f"--gaps: {len(args.gaps)} gaps for {max(args.opponents)} opponents")
    if any(g <= 0 for g in args.gaps):
        parser.error("--gaps: every gap must be positive metres")
    out: Path = check_out(parser, args.out)
    compile_notice()
    with output_folder(parser, out):
        return _run(args, out)


def _run(args, out: Path) -> int:
    logs = out / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    results, rows = [], []
    for k in args.opponents:
        for method in args.methods:
            for seed in range(args.seeds):
                run = OpponentRun(
                    map=args.map, opponents=k, method=method, seed=seed,
                    duration=args.duration, speed=args.speed, gaps=tuple(args.gaps),
                    n_particles=args.particles, backend=args.backend,
                )  # fmt: skip
                result = run_opponents(run, logs / f"{run.run_id}.csv")
                results.append(result)
                rows.append(run_row(result))
                print(f"  {run.run_id}: median {rows[-1]['median_m']:.4f} m, "
                      f"{result.wall_s:.0f} s", file=sys.stderr, flush=True)  # fmt: skip
    _write_csv(out / "runs.csv", rows)
    table = opponents_table(results)
    _write_csv(out / "summary.csv", table)
    text = markdown_table(table)
    writable(out / "summary.md").write_text(text)
    print(text, end="")
    return 0


def markdown_table(table: list[dict]) -> str:
    """The summary rows as a Markdown table."""
    head = "| " + " | ".join(label for _, label, _ in COLUMNS) + " |\n"
    rule = "|" + "---|" * len(COLUMNS) + "\n"
    body = "".join(
        "| " + " | ".join(fmt.format(row[key]) for key, _, fmt in COLUMNS) + " |\n" for row in table
    )
    return head + rule + body


def _write_csv(path: Path, rows: list[dict]) -> None:
    with open(writable(path), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    sys.exit(main())
