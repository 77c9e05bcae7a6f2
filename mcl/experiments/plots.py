"""Matplotlib (Agg, headless) plots of localization error logs and experiment summaries.

Errors are in metres (position) and radians (heading), times in seconds of simulated time.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mcl.wrappers.error_log import ErrorLog
from racecar_sim.file_guard import writable

__all__ = ["SeriesPoints", "plot_error_vs_coefficient", "plot_error_vs_time", "plot_overlay"]

_DPI = 100
SeriesPoints = tuple[Sequence[float], Sequence[float], Sequence[float]]
"""(x values, mean errors in metres, spreads in metres) of one series, same lengths."""

_STYLES: dict[str, dict[str, object]] = {
    "uniform": {"color": "tab:blue", "marker": "o", "linestyle": "-"},
    "gaussian": {"color": "tab:red", "marker": "s", "linestyle": "-"},
    "gaussian_matched": {"color": "tab:red", "marker": "^", "linestyle": "--"},
}


def save_figure(fig: plt.Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` as PNG to ``path`` (folders created), close it, return the path."""
    path = writable(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return path


def plot_error_vs_time(
    log: ErrorLog,
    path: str | os.PathLike[str],
    title: str = "",
    diverged_m: float | None = None,
) -> Path:
    """Position error (m) and heading error (rad) against time (s) of one run, to a PNG.

    ``diverged_m`` draws the divergence threshold as a dotted line when the error comes within
    half of it (otherwise it would only squash the curve).
    """
    fig, (ax_p, ax_h) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax_p.plot(log.time, log.position_error, color="tab:blue", linewidth=1.0)
    if diverged_m is not None and len(log) and np.max(log.position_error) > 0.5 * diverged_m:
        ax_p.axhline(diverged_m, color="grey", linestyle=":", linewidth=1.0, label="diverged")
        ax_p.legend(loc="upper right")
    ax_p.set_ylabel("position error (m)")
    ax_p.set_ylim(bottom=0.0)
    ax_p.grid(True, alpha=0.3)
    ax_h.plot(log.time, log.heading_error, color="tab:orange", linewidth=1.0)
    ax_h.set_ylabel("heading error (rad)")
    ax_h.set_xlabel("time (s)")
    ax_h.grid(True, alpha=0.3)
    if title:
        ax_p.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_overlay(
    logs: Sequence[tuple[str, ErrorLog]],
    path: str | os.PathLike[str],
    title: str = "",
) -> Path:
    """Position error (m, log scale) against time (s) of several runs on one axis, to a PNG.

    Args:
        logs: (legend label, log) pairs, drawn in order with a sequential colour map.
    """
    fig, ax = plt.subplots(figsize=(8, 4.5))
    cmap = plt.get_cmap("viridis")
    n = max(len(logs) - 1, 1)
    for i, (label, log) in enumerate(logs):
        err = np.maximum(log.position_error, 1e-4)  # log axis: keep exact zeros visible
        ax.plot(log.time, err, color=cmap(i / n), linewidth=0.9, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position error (m)")
    ax.grid(True, which="both", alpha=0.3)
    if logs:
        ax.legend(fontsize="small", ncol=2)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_error_vs_coefficient(
    series: Mapping[str, SeriesPoints],
    path: str | os.PathLike[str],
    title: str = "",
    xlabel: str = "noise coefficient (uniform half-width c / Gaussian sigma, per update)",
    labels: Mapping[str, str] | None = None,
) -> Path:
    """Mean position error (m) against the noise coefficient, one line per series, log-log axes.

    Args:
        series: name -> (x, mean error, spread across seeds) drawn with error bars.
        labels: legend text per series name (default: the name).
    """
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, (x, mean, spread) in series.items():
        xs = np.asarray(x, dtype=np.float64)
        ys = np.asarray(mean, dtype=np.float64)
        es = np.nan_to_num(np.asarray(spread, dtype=np.float64))
        order = np.argsort(xs)
        style = _STYLES.get(name, {"marker": "o"})
        ax.errorbar(
            xs[order],
            ys[order],
            yerr=es[order],
            capsize=3,
            label=(labels or {}).get(name, name),
            **style,  # type: ignore[arg-type]
        )
    ax.set_xscale("log")
    finite = [v for _, m, _ in series.values() for v in m if math.isfinite(v) and v > 0]
    if finite and max(finite) / min(finite) > 20:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("mean position error (m)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path)
