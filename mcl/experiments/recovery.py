"""The global-localization and kidnapping experiment: how fast, and how often, the filter finds the car.

Over N seeds on one map, every run starts the filter without knowing the pose (scenario
``global``: particles uniform over free space, the car at a random start) or loses it on purpose
(scenario ``kidnap``: tracking from the true start, then the car is teleported to a random free pose
at ``kidnap_time``, see [`mcl.experiments.scenarios`][mcl.experiments.scenarios]). The wall follower drives; each run writes the
wrapper's CSV error log. From the log (`mcl.experiments.convergence`): the time from losing the car to
convergence (position error < 0.3 m and heading error < 10 deg held for 2 s), success within the
time limit (10 s global, 15 s kidnap), and from the per-step flags of ``info["localization"]`` the
fraction of time the filter called its pose ambiguous and the fraction it was confidently wrong.

The filter (`recovery_localization()`) is the lab's beam model tempered harder (squash 0.05),
using a scan every 0.1 m or 0.2 rad of motion, started with 300 particles per m² of free floor,
KLD-sampling down to 1000 particles (up to 20 000 while searching) and augmented MCL
(alpha_slow 0.001, alpha_fast 0.1). The docs' page on global localization and kidnapping says why each of these is needed.

Output folder layout::

    config.json                 the experiment's settings (checked by ``resume``)
    logs/<run_id>.csv           one error log per run (mcl.wrappers.error_log format)
    logs/<run_id>.json          what the scenario recorded (kidnap poses, per-step flags)
    runs.csv                    one line per run: convergence time, success, honesty, particles
    summary.md                  summary table and the per-run table
    plots/runs/<run_id>.png     error vs time of each run
    plots/overlay.png           position error vs time of every seed
    plots/convergence.png       fraction of runs converged vs time since the filter lost the car
    plots/particles.png         particle count, and the fraction of runs ambiguous, vs time
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from mcl.experiments.convergence import recovery_stats
from mcl.experiments.metrics import DIVERGED_M, error_stats
from mcl.experiments.recovery_config import (
    RECOVERY_SCENARIOS,
    RecoveryConfig,
    RecoveryRun,
    recovery_localization,
)
from mcl.experiments.recovery_plots import write_recovery_plots
from mcl.experiments.recovery_report import write_tables
from mcl.experiments.runner import Executor, run_pending, run_spec_safely
from mcl.experiments.runs import RunResult, RunSpec
from mcl.wrappers.error_log import count_rows, read_error_log
from racecar_sim.file_guard import writable

__all__ = [
    "RECOVERY_SCENARIOS",
    "RecoveryConfig",
    "RecoveryReport",
    "RecoveryRun",
    "recovery_localization",
    "run_recovery_experiment",
    "run_recovery_safely",
]


@dataclass(frozen=True)
class RecoveryReport:
    """What `run_recovery_experiment()` did.

    Attributes:
        config: the experiment. out_dir: its folder. runs: one per seed, in seed order.
        files: paths written.
    """

    config: RecoveryConfig
    out_dir: Path
    runs: list[RecoveryRun]
    files: list[Path]

    @property
    def failed(self) -> list[RunResult]:
        """The runs that crashed."""
        return [r.result for r in self.runs if r.result.status == "failed"]

    @property
    def success_rate(self) -> float:
        """Fraction of the finished runs that converged within the time limit."""
        done = [r.stats for r in self.runs if r.stats is not None]
        return float(np.mean([s.success for s in done])) if done else math.nan


# ---------------------------------------------------------------------- running
def _outcome_path(log_path: Path) -> Path:
    return Path(log_path).with_suffix(".json")


def run_recovery_safely(spec: RunSpec, log_path: Path, diverged_m: float = DIVERGED_M) -> RunResult:
    """[`mcl.experiments.runner.run_spec_safely()`][mcl.experiments.runner.run_spec_safely], then the scenario's outcome saved next to the log
    (``<log>.json``) so that ``resume`` can judge the run without running it again."""
    result = run_spec_safely(spec, log_path, diverged_m)
    if result.status == "ok":
        writable(_outcome_path(log_path)).write_text(json.dumps(result.outcome), encoding="utf-8")
    return result


def _judge(config: RecoveryConfig, result: RunResult) -> RecoveryRun:
    if result.status == "failed" or not result.log_path.is_file():
        return RecoveryRun(result, None)
    log = read_error_log(result.log_path)
    outcome = result.outcome
    lost_at = float(outcome.get("lost_at", config.lost_at))
    if not math.isfinite(lost_at):  # the kidnap never happened (run too short)
        lost_at = config.lost_at
    stats = recovery_stats(
        log,
        lost_at,
        config.limit,
        ambiguous=np.asarray(outcome["ambiguous"]) if "ambiguous" in outcome else None,
        n_particles=np.asarray(outcome["n_particles"]) if "n_particles" in outcome else None,
        criteria=config.criteria,
    )
    return RecoveryRun(result, stats)


def run_recovery_experiment(
    config: RecoveryConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
    plots: bool = True,
    stream: TextIO | None = None,
    executor: Executor | None = None,
) -> RecoveryReport:
    """Run every seed into ``out_dir``, judge the runs, write runs.csv, summary.md and the plots.

    Args:
        config: the experiment.
        out_dir: output folder (created).
        workers: processes (default: the CPU count; 1 runs inline in this process).
        resume: skip runs whose log is complete and whose outcome file exists (config.json must
            match ``config``).
        progress: show a tqdm bar over the runs on ``stream``.
        plots: draw the PNG plots.
        stream: where progress and failures are reported (default: stderr).
        executor: where the runs execute (default: a process pool of ``workers``; see
            [`mcl.experiments.runner.make_executor()`][mcl.experiments.runner.make_executor], e.g. Ray).
    """
    out = Path(out_dir)

    def reuse(spec: RunSpec, path: Path) -> RunResult | None:
        outcome = _outcome_path(path)
        if count_rows(path) != spec.n_steps or not outcome.is_file():
            return None
        return RunResult(
            spec=spec,
            status="skipped",
            stats=error_stats(read_error_log(path)),
            log_path=path,
            outcome=json.loads(outcome.read_text(encoding="utf-8")),
        )

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
        runner=run_recovery_safely,
    )
    runs = [_judge(config, r) for r in results]
    files = write_tables(config, runs, out)
    if plots:
        files += write_recovery_plots(config, runs, out)
    return RecoveryReport(config, out, runs, files)
