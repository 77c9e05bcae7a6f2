"""The results of a race as a table: ``results.csv`` and ``results.md`` (one row per car, by
finishing position).

Columns: ``position`` (1 = leading at the end: race order by distance covered along the
centerline), ``car`` (``car_i``, its colour in the video), ``driver``, ``speed`` (m/s),
``grid`` (start slot, 1 = pole), ``laps`` (completed), ``best_lap`` (s; empty before a lap),
``lap_times`` (s, ``;``-separated in the CSV), ``distance`` (m along the centerline since the
start), ``overtakes`` and ``overtaken`` (the car's gains and losses of rank in race order, counted
step by step: passing a car ahead in race order is one overtake, lapping a car already behind is
none; [RaceTally][mcl.agents.race_tally.RaceTally]), ``wall_contacts`` and ``car_contacts``
(separate contacts), ``mean_error`` and
``max_error`` (m, the car's filter against its true pose; empty without ``--localize``).
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

from mcl.experiments.race_run import RaceResult

__all__ = ["CSV_COLUMNS", "markdown_table", "write_results"]

CSV_COLUMNS: tuple[str, ...] = (
    "position",
    "car",
    "driver",
    "speed",
    "grid",
    "laps",
    "best_lap",
    "lap_times",
    "distance",
    "overtakes",
    "overtaken",
    "wall_contacts",
    "car_contacts",
    "mean_error",
    "max_error",
)
"""Columns of results.csv."""


def _number(value: float, digits: int) -> str:
    return "" if math.isnan(value) else f"{value:.{digits}f}"


def markdown_table(result: RaceResult) -> str:
    """The results as a Markdown table (module doc), a line above it saying what was raced."""
    spec = result.spec
    localized = spec.localize
    head = (
        f"{spec.n_cars} cars on {Path(spec.map).stem} ({result.track_length:.1f} m track), "
        f"{result.seconds:.1f} s raced"
        + (f" (to {spec.laps} laps)" if spec.laps is not None else "")
        + f", seed {spec.seed}"
        + (
            f", MCL per car ({spec.particles} particles, driving on the estimate)"
            if localized
            else ""
        )
    )
    columns = [
        "pos",
        "car",
        "driver",
        "m/s",
        "grid",
        "laps",
        "best lap (s)",
        "distance (m)",
        "overtakes",
        "overtaken",
        "wall contacts",
        "car contacts",
    ]
    if localized:
        columns.append("MCL error mean / max (m)")
    lines = [
        head,
        "",
        "| " + " | ".join(columns) + " |",
        "|" + "|".join("---:" if c not in ("car", "driver") else "---" for c in columns) + "|",
    ]
    for c in result.cars:
        row = [
            str(c.position),
            f"car_{c.car}",
            c.driver,
            f"{c.speed:.1f}",
            str(c.grid_slot),
            str(c.laps),
            _number(c.best_lap, 2) or "-",
            f"{c.progress:.1f}",
            str(c.overtakes),
            str(c.overtaken),
            str(c.wall_contacts),
            str(c.car_contacts),
        ]
        if localized:
            row.append(f"{c.mean_error:.3f} / {c.max_error:.3f}")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def write_results(result: RaceResult, out: str | os.PathLike[str]) -> list[Path]:
    """results.csv and results.md into folder ``out``; returns their paths."""
    out = Path(out)
    csv_path, md_path = out / "results.csv", out / "results.md"
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(CSV_COLUMNS)
        for c in result.cars:
            writer.writerow(
                [
                    c.position,
                    f"car_{c.car}",
                    c.driver,
                    f"{c.speed:g}",
                    c.grid_slot,
                    c.laps,
                    _number(c.best_lap, 3),
                    ";".join(f"{t:.3f}" for t in c.lap_times),
                    f"{c.progress:.2f}",
                    c.overtakes,
                    c.overtaken,
                    c.wall_contacts,
                    c.car_contacts,
                    _number(c.mean_error, 4),
                    _number(c.max_error, 4),
                ]
            )
    md_path.write_text(markdown_table(result) + "\n", encoding="utf-8")
    return [csv_path, md_path]
