"""The odometry-noise experiment: uniform vs Gaussian motion noise in MCL, swept and summarised.

It reproduces the source document's table, uniform half-widths c and Gaussian standard deviations
sigma in {0.01, 0.1, 0.3, 0.5, 1.0} (per update, applied to dx m, dy m and dtheta rad alike), and
adds the comparison the source does not make: Gaussian noise with the *variance* of each uniform
setting, sigma = c / sqrt(3) (series ``gaussian_matched``, plotted at its c).

Every run (:class:`mcl.runs.RunSpec`) drives the same route for a given seed: the env's noise and
the driver do not depend on the filter, so all schemes see the same true trajectory and the same
sensor noise. Runs go to a process pool; each writes its CSV error log as it goes, so ``resume``
can skip runs whose log is complete, and a run that crashes is reported while the others finish.

Output folder layout::

    config.json                  the sweep's settings (checked by ``resume``)
    logs/<run_id>.csv            one error log per run (mcl.error_log format)
    runs.csv                     one line per run: status and its error statistics
    summary.csv, summary.md      per series and coefficient: statistics across seeds (mean, sd)
    plots/runs/<run_id>.png      error vs time of each run
    plots/overlay_<series>.png   error vs time of every coefficient of a series (first seed)
    plots/error_vs_coefficient.png   mean error vs coefficient, all series, log x
    plots/error_vs_noise_sd.png      the same against the noise standard deviation (matched)
"""

from __future__ import annotations

import csv
import json
import math
import multiprocessing
import os
import sys
import traceback
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import as_completed as futures_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from mcl.error_log import count_rows, read_error_log
from mcl.metrics import DIVERGED_M, ErrorStats, error_stats
from mcl.motion_model import MotionModelParams, uniform_to_gaussian
from mcl.runs import RunResult, RunSpec, run_one
from racecar_sim.maps import DEFAULT_MAP

__all__ = [
    "DEFAULT_PARTICLES",
    "GAUSSIAN_SIGMAS",
    "METRICS",
    "SERIES",
    "UNIFORM_COEFFICIENTS",
    "ExperimentConfig",
    "ExperimentReport",
    "SummaryRow",
    "execute_runs",
    "markdown_table",
    "run_experiment",
    "run_spec_safely",
    "summarize",
    "write_plots",
    "write_summary",
]

UNIFORM_COEFFICIENTS: tuple[float, ...] = (0.01, 0.1, 0.3, 0.5, 1.0)
"""Half-widths c of the uniform noise in the source's table (per update)."""
GAUSSIAN_SIGMAS: tuple[float, ...] = (0.01, 0.1, 0.3, 0.5, 1.0)
"""Standard deviations sigma of the Gaussian noise in the source's table (per update)."""
DEFAULT_PARTICLES = 1500
"""Particles per run by default (see the README for the measured update rate)."""

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
class ExperimentConfig:
    """The sweep: which runs to make.

    Attributes:
        map: bundled map name or map YAML path.
        driver: ``"wall"`` or ``"pursuit"`` (see :data:`mcl.runs.DRIVERS`).
        scenario: a key of :data:`mcl.scenarios.SCENARIOS`.
        seeds: number of seeds (``first_seed``, ``first_seed + 1``, ...).
        first_seed: the first seed.
        duration: seconds of simulated time per run.
        n_particles: particles per run.
        uniform: uniform half-widths c (per update); empty skips the series.
        gaussian: Gaussian sigmas (per update); empty skips the series.
        matched: also run Gaussian noise at sigma = c / sqrt(3) for every uniform c.
        diverged_m: metres of position error counted as diverged.
        env: extra RacecarEnv settings as (name, value) pairs (e.g. fewer beams in tests).
    """

    map: str = DEFAULT_MAP
    driver: str = "wall"
    scenario: str = "tracking"
    seeds: int = 3
    first_seed: int = 0
    duration: float = 60.0
    n_particles: int = DEFAULT_PARTICLES
    uniform: tuple[float, ...] = UNIFORM_COEFFICIENTS
    gaussian: tuple[float, ...] = GAUSSIAN_SIGMAS
    matched: bool = True
    diverged_m: float = DIVERGED_M
    env: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        for name in ("seeds", "first_seed"):
            value = getattr(self, name)
            low = 1 if name == "seeds" else 0
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"ExperimentConfig.{name} = {value!r} must be an integer >= {low}")
        for name in ("uniform", "gaussian"):
            values = tuple(float(v) for v in getattr(self, name))
            if not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError(
                    f"ExperimentConfig.{name} = {values!r} must hold positive coefficients"
                )
            object.__setattr__(self, name, values)
        if not (math.isfinite(self.diverged_m) and self.diverged_m > 0):
            raise ValueError(f"ExperimentConfig.diverged_m = {self.diverged_m!r} must be > 0 m")
        object.__setattr__(self, "env", tuple((str(k), v) for k, v in dict(self.env).items()))
        if not self.runs():
            raise ValueError("ExperimentConfig: no runs (uniform and gaussian are both empty)")

    def runs(self) -> list[RunSpec]:
        """Every run of the sweep, seed by seed (so early results cover every series)."""
        points: list[tuple[str, str, float, float]] = []  # series, scheme, coefficient, nominal
        points += [("uniform", "uniform", c, c) for c in self.uniform]
        points += [("gaussian", "gaussian", s, s) for s in self.gaussian]
        if self.matched:
            points += [
                ("gaussian_matched", "gaussian", float(uniform_to_gaussian(c)), c)
                for c in self.uniform
            ]
        return [
            RunSpec(
                map=str(self.map),
                driver=self.driver,
                scenario=self.scenario,
                motion=MotionModelParams(scheme=scheme, coefficients=coeff),
                seed=seed,
                duration=self.duration,
                n_particles=self.n_particles,
                series=series,
                nominal=nominal,
                env=self.env,
            )
            for seed in range(self.first_seed, self.first_seed + self.seeds)
            for series, scheme, coeff, nominal in points
        ]


@dataclass(frozen=True)
class SummaryRow:
    """Statistics of one series at one coefficient, across seeds.

    Attributes:
        series: ``uniform``, ``gaussian`` or ``gaussian_matched``.
        scheme: the motion model's noise scheme.
        coefficient: the series' coefficient (c for uniform and matched, sigma for Gaussian).
        noise_sd: standard deviation of the noise per component (c / sqrt(3) or sigma).
        n_runs: runs that finished. n_failed: runs that crashed.
        mean, sd: each statistic of :data:`METRICS` averaged over the seeds, and its sample
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


@dataclass(frozen=True)
class ExperimentReport:
    """What :func:`run_experiment` did.

    Attributes:
        config: the sweep. out_dir: the output folder. results: one per run, in sweep order.
        summary: one row per series and coefficient. files: paths written (summaries and plots).
    """

    config: ExperimentConfig
    out_dir: Path
    results: list[RunResult]
    summary: list[SummaryRow]
    files: list[Path]

    @property
    def failed(self) -> list[RunResult]:
        """The runs that crashed."""
        return [r for r in self.results if r.status == "failed"]


# ---------------------------------------------------------------------- running
def _log_path(out_dir: Path, spec: RunSpec) -> Path:
    return out_dir / "logs" / f"{spec.run_id}.csv"


def _init_worker() -> None:
    """One numba thread per worker process: the pool already spreads the runs over the cores."""
    import numba

    numba.set_num_threads(1)


def run_spec_safely(spec: RunSpec, log_path: Path, diverged_m: float = DIVERGED_M) -> RunResult:
    """:func:`mcl.runs.run_one`, with any exception turned into a ``"failed"`` result."""
    try:
        return run_one(spec, log_path, diverged_m=diverged_m)
    except Exception as exc:  # a crashed run is reported; the sweep goes on
        where = traceback.extract_tb(exc.__traceback__)[-1]
        error = f"{type(exc).__name__}: {exc} (at {Path(where.filename).name}:{where.lineno})"
        return RunResult(spec=spec, status="failed", stats=None, log_path=log_path, error=error)


def _skipped(spec: RunSpec, log_path: Path, diverged_m: float) -> RunResult:
    stats = error_stats(read_error_log(log_path), diverged_m)
    return RunResult(spec=spec, status="skipped", stats=stats, log_path=log_path)


def execute_runs(
    todo: Sequence[tuple[RunSpec, Path]],
    workers: int = 1,
    *,
    diverged_m: float = DIVERGED_M,
    progress: bool = False,
    total: int | None = None,
    done_already: int = 0,
    stream: TextIO | None = None,
    runner: Callable[[RunSpec, Path, float], RunResult] | None = None,
) -> list[RunResult]:
    """Run ``todo`` = [(spec, log path)]: inline when ``workers`` is 1, else in a spawn process pool.

    Each run is ``runner(spec, log_path, diverged_m)`` (default :func:`run_spec_safely`; another
    runner must be a module-level function so that worker processes can import it).

    A tqdm bar counts ``total`` runs (default: len(todo)) from ``done_already``; failures are
    reported on ``stream`` (default stderr) as they come. Returns the results in the order they
    finished; a run that raised, or whose worker process died, is a ``"failed"`` result.
    """
    from tqdm import tqdm

    bar = tqdm(total=total, initial=done_already, unit="run", disable=not progress, file=stream)
    run = runner if runner is not None else run_spec_safely
    results: list[RunResult] = []

    def finished(result: RunResult) -> None:
        results.append(result)
        if result.status == "failed":
            bar.write(f"run {result.spec.run_id} FAILED: {result.error}", file=stream)
        bar.update(1)

    try:
        if workers <= 1:
            for spec, path in todo:
                finished(run(spec, path, diverged_m))
            return results
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker) as pool:
            futures: dict[Future[RunResult], tuple[RunSpec, Path]] = {
                pool.submit(run, spec, path, diverged_m): (spec, path) for spec, path in todo
            }
            for future in futures_completed(futures):
                spec, path = futures[future]
                try:
                    result = future.result()
                except Exception as exc:  # the worker process itself died
                    result = RunResult(
                        spec=spec,
                        status="failed",
                        stats=None,
                        log_path=path,
                        error=f"worker process failed: {type(exc).__name__}: {exc}",
                    )
                finished(result)
    finally:
        bar.close()
    return results


def record_settings(config: Any, path: Path, resume: bool) -> None:
    """Record an experiment config (a dataclass) as JSON in ``path``; with ``resume``, refuse a folder
    made with other settings, naming the settings that differ.

    Logs are only reusable by runs with the same settings (map, particles, env, ...).
    """
    settings = json.dumps(asdict(config), sort_keys=True, default=str)
    if resume and path.is_file():
        before = path.read_text(encoding="utf-8").strip()
        if before != settings:
            old, new = json.loads(before), json.loads(settings)
            changed = sorted(k for k in new if old.get(k) != new[k])
            raise ValueError(
                f"--resume: {path.parent} holds runs with other settings ({', '.join(changed)} "
                "differ); use another output folder or drop --resume"
            )
    path.write_text(settings + "\n", encoding="utf-8")


def run_pending(
    config: Any,
    specs: Sequence[RunSpec],
    out: Path,
    *,
    workers: int | None,
    resume: bool,
    reuse: Callable[[RunSpec, Path], RunResult | None],
    progress: bool,
    stream: TextIO,
    diverged_m: float = DIVERGED_M,
    runner: Callable[[RunSpec, Path, float], RunResult] | None = None,
) -> list[RunResult]:
    """Run ``specs`` into ``out/logs/<run_id>.csv``; the results in the order of ``specs``.

    The folder's ``config.json`` records ``config`` (see :func:`record_settings`). With ``resume``,
    ``reuse(spec, log_path)`` may return a ``"skipped"`` result for a run whose output is complete;
    every other run goes to :func:`execute_runs` over ``workers`` processes (default: the CPU count).
    """
    ids = [s.run_id for s in specs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{type(config).__name__}: two runs share a name (repeated settings?)")
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    (out / "logs").mkdir(parents=True, exist_ok=True)
    record_settings(config, out / "config.json", resume)
    by_id: dict[str, RunResult] = {}
    todo: list[tuple[RunSpec, Path]] = []
    for spec in specs:
        path = _log_path(out, spec)
        kept = reuse(spec, path) if resume else None
        if kept is not None:
            by_id[spec.run_id] = kept
        else:
            todo.append((spec, path))
    done = execute_runs(
        todo,
        min(workers, max(len(todo), 1)),
        diverged_m=diverged_m,
        progress=progress,
        total=len(specs),
        done_already=len(by_id),
        stream=stream,
        runner=runner,
    )
    by_id.update({r.spec.run_id: r for r in done})
    return [by_id[i] for i in ids]


def run_experiment(
    config: ExperimentConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
    plots: bool = True,
    stream: TextIO | None = None,
) -> ExperimentReport:
    """Run the sweep into ``out_dir`` and write the summaries and plots (see the module docstring).

    Args:
        config: the sweep.
        out_dir: output folder (created).
        workers: processes (default: the CPU count; 1 runs inline in this process).
        resume: skip runs whose log already has every row (the folder's config.json must match
            ``config``: ``ValueError`` naming the settings that differ otherwise).
        progress: show a tqdm bar over the runs on ``stream``.
        plots: draw the PNG plots.
        stream: where progress and failures are reported (default: stderr).

    Failed runs are listed on ``stream``, in runs.csv and in summary.md; they do not stop the
    others.
    """
    out = Path(out_dir)

    def reuse(spec: RunSpec, path: Path) -> RunResult | None:
        complete = count_rows(path) == spec.n_steps
        return _skipped(spec, path, config.diverged_m) if complete else None

    results = run_pending(
        config,
        config.runs(),
        out,
        workers=workers,
        resume=resume,
        reuse=reuse,
        progress=progress,
        stream=stream if stream is not None else sys.stderr,
        diverged_m=config.diverged_m,
    )
    summary = summarize(results)
    files = write_summary(config, summary, results, out)
    if plots:
        files += write_plots(config, summary, results, out)
    return ExperimentReport(config, out, results, summary, files)


# ---------------------------------------------------------------------- summary
def summarize(results: Iterable[RunResult]) -> list[SummaryRow]:
    """One :class:`SummaryRow` per (series, coefficient), in the order the series first appear."""
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
    with runs_path.open("w", newline="", encoding="utf-8") as f:
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
    with csv_path.open("w", newline="", encoding="utf-8") as f:
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
    md_path.write_text("\n".join(lines), encoding="utf-8")
    return [runs_path, csv_path, md_path]


# ---------------------------------------------------------------------- plots
def write_plots(
    config: ExperimentConfig,
    summary: Sequence[SummaryRow],
    results: Sequence[RunResult],
    out_dir: str | os.PathLike[str],
) -> list[Path]:
    """Draw every plot of the module docstring into ``out_dir/plots``; returns their paths."""
    from mcl.plots import plot_error_vs_coefficient, plot_error_vs_time, plot_overlay

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
