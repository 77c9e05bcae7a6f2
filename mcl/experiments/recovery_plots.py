"""Plots of the global-localization / kidnapping experiment ([`mcl.experiments.recovery`][mcl.experiments.recovery]), headless (Agg).

Times are seconds of simulated time, errors metres.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mcl.experiments.plots import plot_error_vs_time, plot_overlay, save_figure
from mcl.wrappers.error_log import read_error_log

if TYPE_CHECKING:
    from mcl.experiments.recovery_config import RecoveryConfig, RecoveryRun

__all__ = ["plot_convergence_curve", "plot_particles", "write_recovery_plots"]


def plot_convergence_curve(
    times: Sequence[float],
    path: str | os.PathLike[str],
    limit: float,
    horizon: float,
    title: str = "",
) -> Path:
    """Fraction of runs converged against seconds since the filter lost the car, to a PNG.

    Args:
        times: seconds to convergence of each run (NaN: never).
        limit: the time limit (s), drawn as a dashed line.
        horizon: seconds of the x axis (the runs' length after losing the car).
    """
    t = np.asarray(times, dtype=np.float64)
    n = max(len(t), 1)
    done = np.sort(t[np.isfinite(t)])
    xs = np.concatenate([[0.0], np.repeat(done, 2), [horizon]])
    ys = np.concatenate([[0.0, 0.0], np.repeat(np.arange(1, done.size + 1) / n, 2)])
    ys = ys[: xs.size]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(xs, ys, color="tab:blue", linewidth=1.5)
    ax.axvline(limit, color="grey", linestyle="--", linewidth=1.0, label=f"limit {limit:g} s")
    within = float(np.mean(t <= limit)) if len(t) else math.nan
    ax.axhline(within, color="tab:green", linestyle=":", linewidth=1.0, label=f"{within:.0%}")
    ax.set_xlim(0.0, horizon)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("seconds since the filter lost the car")
    ax.set_ylabel("fraction of runs converged")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_particles(
    series: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    path: str | os.PathLike[str],
    lost_at: float,
    title: str = "",
) -> Path:
    """Particle count (log scale) per run, and the fraction of runs flagged ambiguous, against
    time (s), to a PNG.

    Args:
        series: per run (times (T,), particle counts (T,), ambiguity flags (T,) 0/1).
        lost_at: seconds at which the filter lost the car (dotted line).
    """
    fig, (ax_n, ax_a) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    cmap = plt.get_cmap("viridis")
    k = max(len(series) - 1, 1)
    for i, (t, n, _) in enumerate(series):
        ax_n.plot(t, np.maximum(n, 1), color=cmap(i / k), linewidth=0.8)
    ax_n.set_yscale("log")
    ax_n.set_ylabel("particles")
    ax_n.grid(True, which="both", alpha=0.3)
    if series:
        length = min(len(t) for t, _, _ in series)
        t0 = series[0][0][:length]
        amb = np.mean([a[:length] for _, _, a in series], axis=0)
        ax_a.plot(t0, amb, color="tab:red", linewidth=1.2)
    ax_a.set_ylim(-0.02, 1.02)
    ax_a.set_ylabel("fraction ambiguous")
    ax_a.set_xlabel("time (s)")
    ax_a.grid(True, alpha=0.3)
    for ax in (ax_n, ax_a):
        ax.axvline(lost_at, color="grey", linestyle=":", linewidth=1.0)
    if title:
        ax_n.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)


def write_recovery_plots(
    config: RecoveryConfig, runs: Sequence[RecoveryRun], out_dir: str | os.PathLike[str]
) -> list[Path]:
    """Every plot of [`mcl.experiments.recovery`][mcl.experiments.recovery]'s folder layout into ``out_dir/plots``."""
    plots = Path(out_dir) / "plots"
    name = Path(config.map).stem
    files: list[Path] = []
    logs = []
    particle_series = []
    for r in runs:
        res = r.result
        if r.stats is None or not res.log_path.is_file():
            continue
        log = read_error_log(res.log_path)
        logs.append((f"seed {res.spec.seed}", log))
        conv = r.stats.convergence_s
        state = f"converged after {conv:.2f} s" if math.isfinite(conv) else "never converged"
        title = f"{config.scenario}, seed {res.spec.seed} ({name}): {state}"
        files.append(plot_error_vs_time(log, plots / "runs" / f"{res.spec.run_id}.png", title))
        counts = np.asarray(res.outcome.get("n_particles", []), dtype=np.float64)
        flags = np.asarray(res.outcome.get("ambiguous", []), dtype=np.float64)
        m = min(len(log), len(counts), len(flags))
        if m:
            particle_series.append((np.asarray(log.time)[:m], counts[:m], flags[:m]))
    title = f"{config.scenario} on {name}, {len(logs)} seed(s)"
    if logs:
        files.append(plot_overlay(logs, plots / "overlay.png", title))
    times = [r.stats.convergence_s for r in runs if r.stats is not None]
    if times:
        horizon = config.total_duration - config.lost_at
        files.append(
            plot_convergence_curve(times, plots / "convergence.png", config.limit, horizon, title)
        )
    if particle_series:
        files.append(
            plot_particles(particle_series, plots / "particles.png", config.lost_at, title)
        )
    return files
