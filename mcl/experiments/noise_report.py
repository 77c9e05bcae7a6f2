"""The noise sweep's outputs: summary statistics across seeds, runs.csv, summary.csv/md, plots."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mcl.experiments.metrics import ErrorStats
from mcl.experiments.runs import RunResult
from mcl.filter.motion_model import uniform_to_gaussian
from mcl.wrappers.error_log import read_error_log
from racecar_sim.file_guard import writable

if TYPE_CHECKING:
    from mcl.experiments.noise_config import ExperimentConfig

__all__ = [
    "METRICS",
    "SERIES",
    "SummaryRow",
    "markdown_table",
    "summarize",
    "write_plots",
    "write_summary",
]

SERIES: dict[str, str] = {
    "uniform": "uniform, half-width c",
    "gaussian": "Gaussian, sigma",
    "gaussian_matched": "Gaussian, sigma = c/sqrt(3) (variance of uniform c)",
}
"""Series names and their legend text."""

METRICS: tuple[tuple[str, str], ...] = (
    ("mean_error", "mean error (m)"),
    ("median_error", "median (m)"),
    ("p95_error", "p95 (m)"),
    ("max_error", "max (m)"),
    ("mean_heading_error", "heading (rad)"),
    ("diverged_fraction", "diverged"),
)
"""(ErrorStats field, column title) of the statistics summarised across seeds."""


@dataclass(frozen=True)
class SummaryRow:
    """Statistics of one series at one coefficient, across seeds.

    Attributes:
        series: ``uniform``, ``gaussian`` or ``gaussian_matched``.
        scheme: the motion model's noise scheme.
        coefficient: the series' coefficient (c for uniform and matched, sigma for Gaussian).
        noise_sd: standard deviation of the noise per component (c / sqrt(3) or sigma).
        n_runs: runs that finished. n_failed: runs that crashed.
        mean, sd: each statistic of `METRICS` averaged over the seeds, and its sample
            standard deviation (NaN with one seed).
    """

    series: str
    scheme: str
    coefficient: float
    noise_sd: float
    n_runs: int
    n_failed: int
    mean: dict[str, float] = field(default_factory=dict)
    sd: dict[str, float] = field(default_factory=dict)

    def csv_row(self) -> dict[str, Any]:
        """Flat row for summary.csv."""
        row: dict[str, Any] = {
            "series": self.series,
            "scheme": self.scheme,
            "coefficient": self.coefficient,
            "noise_sd": self.noise_sd,
            "n_runs": self.n_runs,
            "n_failed": self.n_failed,
        }
        for name, _ in METRICS:
            row[name] = self.mean.get(name, math.nan)
            row[f"{name}_sd"] = self.sd.get(name, math.nan)
        return row


def summarize(results: Iterable[RunResult]) -> list[SummaryRow]:
    """One `SummaryRow` per (series, coefficient), in the order the series first appear."""
    groups: dict[tuple[str, float], list[RunResult]] = {}
    for r in results:
        groups.setdefault((r.spec.series, r.spec.nominal), []).append(r)
    rows = []
    for (series, nominal), group in groups.items():
        spec = group[0].spec
        stats = [r.stats for r in group if r.status != "failed" and r.stats is not None]
        mean: dict[str, float] = {}
        sd: dict[str, float] = {}
        for name, _ in METRICS:
            values = np.array([getattr(s, name) for s in stats], dtype=np.float64)
            mean[name] = float(values.mean()) if values.size else math.nan
            sd[name] = float(values.std(ddof=1)) if values.size > 1 else math.nan
        coeff = float(spec.motion.coefficients[0])
        noise_sd = coeff if spec.motion.scheme == "gaussian" else float(uniform_to_gaussian(coeff))
        rows.append(
            SummaryRow(
                series=series,
                scheme=spec.motion.scheme,
                coefficient=float(nominal),
                noise_sd=noise_sd,
                n_runs=len(stats),
                n_failed=len(group) - len(stats),
                mean=mean,
                sd=sd,
            )
        )
    order = {name: i for i, name in enumerate(SERIES)}
    rows.sort(key=lambda r: (order.get(r.series, len(order)), r.coefficient))
    return rows


def _cell(mean: float, sd: float, digits: int = 3) -> str:
    if math.isnan(mean):
        return "–"
    text = f"{mean:.{digits}f}"
    return text if math.isnan(sd) else f"{text} ± {sd:.{digits}f}"


def markdown_table(summary: Sequence[SummaryRow]) -> str:
    """The summary as a Markdown table (statistics as mean ± sd across seeds)."""
    head = ["series", "coefficient", "noise sd", "runs", *(title for _, title in METRICS)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in summary:
        runs = f"{row.n_runs}" + (f" ({row.n_failed} failed)" if row.n_failed else "")
        cells = [row.series, f"{row.coefficient:g}", f"{row.noise_sd:.3g}", runs]
        cells += [_cell(row.mean[name], row.sd[name]) for name, _ in METRICS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _stats_fields() -> list[str]:
    return list(ErrorStats.__dataclass_fields__)


def write_summary(
    config: ExperimentConfig,
    summary: Sequence[SummaryRow],
    results: Sequence[RunResult],
    out_dir: str | os.PathLike[str],
) -> list[Path]:
    """Write runs.csv, summary.csv and summary.md into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    runs_path, csv_path, md_path = out / "runs.csv", out / "summary.csv", out / "summary.md"
    run_fields = [
        "run_id", "series", "scheme", "coefficient", "nominal", "seed", "status",
        *_stats_fields(), "wall_s", "n_collisions", "error",
    ]  # fmt: skip
    with writable(runs_path).open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, run_fields)
        writer.writeheader()
        for r in results:
            stats = r.stats.as_dict() if r.stats is not None else {}
            writer.writerow(
                {
                    "run_id": r.spec.run_id,
                    "series": r.spec.series,
                    "scheme": r.spec.motion.scheme,
                    "coefficient": r.spec.motion.coefficients[0],
                    "nominal": r.spec.nominal,
                    "seed": r.spec.seed,
                    "status": r.status,
                    **stats,
                    "wall_s": round(r.wall_s, 3),
                    "n_collisions": r.n_collisions,
                    "error": r.error,
                }
            )
    with writable(csv_path).open("w", newline="", encoding="utf-8") as f:
        rows = [row.csv_row() for row in summary]
        writer = csv.DictWriter(f, list(rows[0]) if rows else ["series"])
        writer.writeheader()
        writer.writerows(rows)
    c = config
    lines = [
        "# MCL odometry-noise experiment",
        "",
        f"Map `{c.map}`, driver `{c.driver}`, scenario `{c.scenario}`, seeds "
        f"{c.first_seed}..{c.first_seed + c.seeds - 1}, {c.duration:g} s of simulated time per "
        f"run, {c.n_particles} particles. Coefficients are per filter update (every "
        f"{results[0].spec.dt:g} s) on dx (m), dy (m) and dtheta (rad) alike. Statistics are "
        f"means ± sample standard deviations across seeds of each run's statistic; diverged = "
        f"fraction of time with position error > {c.diverged_m:g} m.",
        "",
        markdown_table(summary),
        "",
    ]
    failed = [r for r in results if r.status == "failed"]
    if failed:
        lines += ["## Failed runs", ""]
        lines += [f"- `{r.spec.run_id}`: {r.error}" for r in failed]
        lines.append("")
    writable(md_path).write_text("\n".join(lines), encoding="utf-8")
    return [runs_path, csv_path, md_path]


# ---------------------------------------------------------------------- plots
def write_plots(
    config: ExperimentConfig,
    summary: Sequence[SummaryRow],
    results: Sequence[RunResult],
    out_dir: str | os.PathLike[str],
) -> list[Path]:
    """Draw every plot of the module docstring into ``out_dir/plots``; returns their paths."""
    from mcl.experiments.plots import plot_error_vs_coefficient, plot_error_vs_time, plot_overlay

    plots = Path(out_dir) / "plots"
    files: list[Path] = []
    logs = {}
    for r in results:
        if r.status == "failed" or not r.log_path.is_file():
            continue
        log = read_error_log(r.log_path)
        logs[r.spec.run_id] = log
        title = f"{r.spec.series} {r.spec.nominal:g}, seed {r.spec.seed} ({Path(r.spec.map).stem})"
        files.append(
            plot_error_vs_time(
                log, plots / "runs" / f"{r.spec.run_id}.png", title, config.diverged_m
            )
        )
    for series in SERIES:
        runs = [
            r
            for r in results
            if r.spec.series == series
            and r.spec.seed == config.first_seed
            and r.spec.run_id in logs
        ]
        if runs:
            runs.sort(key=lambda r: r.spec.nominal)
            symbol = "sigma" if series == "gaussian" else "c"
            files.append(
                plot_overlay(
                    [(f"{symbol} = {r.spec.nominal:g}", logs[r.spec.run_id]) for r in runs],
                    plots / f"overlay_{series}.png",
                    f"{SERIES[series]}, seed {config.first_seed}",
                )
            )

    def points(key: str) -> dict[str, tuple[list[float], list[float], list[float]]]:
        out: dict[str, tuple[list[float], list[float], list[float]]] = {}
        for row in summary:
            if row.n_runs == 0:
                continue
            xs, ms, ss = out.setdefault(row.series, ([], [], []))
            xs.append(getattr(row, key))
            ms.append(row.mean["mean_error"])
            ss.append(row.sd["mean_error"])
        return out

    title = f"{Path(config.map).stem}, {config.seeds} seed(s), {config.duration:g} s"
    if summary:
        files.append(
            plot_error_vs_coefficient(
                points("coefficient"),
                plots / "error_vs_coefficient.png",
                title,
                labels=SERIES,
            )
        )
        files.append(
            plot_error_vs_coefficient(
                points("noise_sd"),
                plots / "error_vs_noise_sd.png",
                title,
                xlabel="noise standard deviation per update (uniform: c/sqrt(3))",
                labels=SERIES,
            )
        )
    return files
