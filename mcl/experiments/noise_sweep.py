"""The odometry-noise experiment: uniform vs Gaussian motion noise in MCL, swept and summarised.

It reproduces the source document's table, uniform half-widths c and Gaussian standard deviations
sigma in {0.01, 0.1, 0.3, 0.5, 1.0} (per update, applied to dx m, dy m and dtheta rad alike), and
adds the comparison the source does not make: Gaussian noise with the *variance* of each uniform
setting, sigma = c / sqrt(3) (series ``gaussian_matched``, plotted at its c).

Every run ([`mcl.experiments.runs.RunSpec`][mcl.experiments.runs.RunSpec]) drives the same route for a given seed: the env's noise and
the driver do not depend on the filter, so all schemes see the same true trajectory and the same
sensor noise. Runs go to a process pool; each writes its CSV error log as it goes, so ``resume``
can skip runs whose log is complete, and a run that crashes is reported while the others finish.

Output folder layout::

    config.json                  the sweep's settings (checked by ``resume``)
    logs/<run_id>.csv            one error log per run (mcl.wrappers.error_log format)
    runs.csv                     one line per run: status and its error statistics
    summary.csv, summary.md      per series and coefficient: statistics across seeds (mean, sd)
    plots/runs/<run_id>.png      error vs time of each run
    plots/overlay_<series>.png   error vs time of every coefficient of a series (first seed)
    plots/error_vs_coefficient.png   mean error vs coefficient, all series, log x
    plots/error_vs_noise_sd.png      the same against the noise standard deviation (matched)
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from mcl.experiments.noise_config import GAUSSIAN_SIGMAS, UNIFORM_COEFFICIENTS, ExperimentConfig
from mcl.experiments.noise_report import SummaryRow, summarize, write_plots, write_summary
from mcl.experiments.runner import Executor, run_pending, skipped_result
from mcl.experiments.runs import RunResult, RunSpec
from mcl.wrappers.error_log import count_rows

__all__ = [
    "GAUSSIAN_SIGMAS",
    "UNIFORM_COEFFICIENTS",
    "ExperimentConfig",
    "ExperimentReport",
    "run_experiment",
]


@dataclass(frozen=True)
class ExperimentReport:
    """What `run_experiment()` did.

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


def run_experiment(
    config: ExperimentConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
    plots: bool = True,
    stream: TextIO | None = None,
    executor: Executor | None = None,
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
        executor: where the runs execute (default: a process pool of ``workers``; see
            [`mcl.experiments.runner.make_executor()`][mcl.experiments.runner.make_executor], e.g. Ray).

    Failed runs are listed on ``stream``, in runs.csv and in summary.md; they do not stop the
    others.
    """
    out = Path(out_dir)

    def reuse(spec: RunSpec, path: Path) -> RunResult | None:
        complete = count_rows(path) == spec.n_steps
        return skipped_result(spec, path, config.diverged_m) if complete else None

    results = run_pending(
        config,
        config.runs(),
        out,
        workers=workers,
        resume=resume,
        reuse=reuse,
        progress=progress,
        stream=stream if stream is not None else sys.stderr,
        executor=executor,
        diverged_m=config.diverged_m,
    )
    summary = summarize(results)
    files = write_summary(config, summary, results, out)
    if plots:
        files += write_plots(config, summary, results, out)
    return ExperimentReport(config, out, results, summary, files)
