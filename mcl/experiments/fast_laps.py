"""Localization on fast laps: the lab's constant motion noise against the alpha model that grows
with the motion (`mcl.filter.alpha_motion`), on a car that may slide.

Each run is a [`RunSpec`][mcl.experiments.runs.RunSpec]: the ``racing`` driver (pure pursuit round
the map's loop at ``speed`` m/s everywhere, on the true pose), the ``tracking`` scenario started on
the loop (seed ``k`` of ``n`` starts ``k / n`` of the way round), ``car_model`` and any other env
settings, one motion model per series. Runs that differ only in the motion model drive the same
true trajectory through the same sensor noise ([`mcl.experiments.runs`][mcl.experiments.runs]).

The table pools every logged step of a series' runs (position error, metres: mean, median, 95th
percentile), counts the runs that diverged (a position error beyond ``diverged_m`` at any step)
and the steps with wall contact. Output folder: ``config.json``, ``logs/<run_id>.csv``,
``summary.md``.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from mcl.experiments.metrics import DIVERGED_M
from mcl.experiments.runner import run_pending
from mcl.experiments.runs import RunResult, RunSpec
from mcl.filter.motion_model import MotionModelParams
from mcl.wrappers.error_log import read_error_log
from racecar_sim.file_guard import writable

__all__ = ["FastLapConfig", "SeriesRow", "fast_lap_specs", "markdown_table", "run_fast_laps",
           "summarize_fast_laps"]  # fmt: skip

LAB_MOTION = MotionModelParams()
"""The lab's motion noise: Gaussian, standard deviations (0.02 m, 0.01 m, 0.02 rad) per update."""

ALPHA_MOTION = MotionModelParams(
    scheme="alpha", coefficients=(0.005, 0.005, 0.005), alphas=(0.2, 0.08, 0.16, 0.02)
)
"""The alpha model as compared: a1..a4 (0.2, 0.08, 0.16, 0.02), floor 5 mm / 5 mrad per update."""


@dataclass(frozen=True)
class FastLapConfig:
    """The fast-lap experiment's settings.

    Attributes:
        map: bundled map with a known loop (``basement_loop``).
        speed: m/s the car is asked to hold everywhere.
        seeds: runs per series (seeds 0..seeds-1).
        duration: simulated seconds per run.
        n_particles: particles of every filter.
        env: RacecarEnv settings of the world, e.g. ``{"car_model": "single_track"}``.
        motions: series label -> motion model.
        diverged_m: metres of position error that make a run count as diverged.
    """

    map: str = "basement_loop"
    speed: float = 6.0
    seeds: int = 5
    duration: float = 60.0
    n_particles: int = 1500
    env: Mapping[str, Any] = field(default_factory=dict)
    motions: Mapping[str, MotionModelParams] = field(
        default_factory=lambda: {"lab": LAB_MOTION, "alpha": ALPHA_MOTION}
    )
    diverged_m: float = DIVERGED_M


def fast_lap_specs(cfg: FastLapConfig) -> list[RunSpec]:
    """The runs: every series x every seed (same starts and world per seed across series)."""
    from mcl.agents.track import track_for_map

    track = track_for_map(cfg.map)
    specs = []
    for seed in range(cfg.seeds):
        s = track.length * seed / cfg.seeds
        x, y = track.point_at(s).tolist()
        start = (x, y, track.heading_at(s))
        for label, motion in cfg.motions.items():
            specs.append(
                RunSpec(
                    map=cfg.map,
                    driver="racing",
                    scenario="tracking",
                    motion=motion,
                    seed=seed,
                    duration=cfg.duration,
                    n_particles=cfg.n_particles,
                    series=label,
                    env=tuple(dict(cfg.env).items()),
                    scenario_settings=(("start", start),),
                    driver_settings=(("speed", cfg.speed),),
                )
            )
    return specs


@dataclass(frozen=True)
class SeriesRow:
    """One series of the table: pooled position errors (metres) and run counts."""

    series: str
    runs: int
    failed: int
    mean: float
    median: float
    p95: float
    diverged_runs: int
    contact_steps: int
    corner_speed: float
    corner_speed_p5: float

    @property
    def divergence_rate(self) -> float:
        """Fraction of the finished runs that diverged."""
        return self.diverged_runs / self.runs if self.runs else math.nan


def summarize_fast_laps(results: Sequence[RunResult], diverged_m: float) -> list[SeriesRow]:
    """One row per series, in the order the series first appear."""
    groups: dict[str, list[RunResult]] = {}
    for r in results:
        groups.setdefault(r.spec.series, []).append(r)
    rows = []
    for series, group in groups.items():
        ok = [r for r in group if r.status != "failed"]
        errors, diverged, corner = [], 0, []  # corner: (K,) true speeds on turning steps
        for r in ok:
            log = read_error_log(r.log_path)
            err = log.position_error
            errors.append(err)
            diverged += bool(err.size and err.max() > diverged_m)
            corner.append(_corner_speed(log))
        pooled = np.concatenate(errors) if errors else np.array([math.nan])
        rows.append(
            SeriesRow(
                series=series,
                runs=len(ok),
                failed=len(group) - len(ok),
                mean=float(np.mean(pooled)),
                median=float(np.median(pooled)),
                p95=float(np.percentile(pooled, 95)),
                diverged_runs=diverged,
                contact_steps=sum(max(r.n_collisions, 0) for r in ok),
                corner_speed=_percentile(corner, 50),
                corner_speed_p5=_percentile(corner, 5),
            )
        )
    return rows


def _percentile(parts: list[np.ndarray], q: float) -> float:
    values = np.concatenate(parts) if parts else np.zeros(0)
    return float(np.percentile(values, q)) if values.size else math.nan


def _corner_speed(log: Any) -> np.ndarray:
    """True speeds (m/s) on the run's steps that turn faster than 1 rad/s (corners)."""
    dt = np.diff(log.time)
    if dt.size == 0:
        return np.zeros(0)
    speed = np.hypot(np.diff(log.x_true), np.diff(log.y_true)) / dt
    turn = np.abs(np.angle(np.exp(1j * np.diff(log.theta_true)))) / dt
    return speed[(turn > 1.0) & (speed > 0.5)]  # moving and turning


def markdown_table(rows: Sequence[SeriesRow], diverged_m: float) -> str:
    """The table of `summarize_fast_laps()` as Markdown."""
    lines = [
        f"| motion model | runs | mean error (m) | median (m) | p95 (m) | diverged (> {diverged_m:g} m) "
        "| wall-contact steps | corner speed: median, 5th pct (m/s) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.series} | {r.runs} | {r.mean:.3f} | {r.median:.3f} | {r.p95:.3f} "
            f"| {r.diverged_runs}/{r.runs} | {r.contact_steps} "
            f"| {r.corner_speed:.2f}, {r.corner_speed_p5:.2f} |"
        )
    return "\n".join(lines)


def run_fast_laps(
    cfg: FastLapConfig,
    out: str | Path,
    *,
    workers: int | None = None,
    progress: bool = False,
    stream: TextIO | None = None,
) -> tuple[list[SeriesRow], list[RunResult]]:
    """Run the experiment into ``out`` and write ``summary.md``; returns (table rows, results)."""
    out = Path(out)
    specs = fast_lap_specs(cfg)
    stream = stream if stream is not None else sys.stderr
    results = run_pending(
        cfg, specs, out, workers=workers, resume=False, reuse=lambda spec, path: None,
        progress=progress, stream=stream, diverged_m=cfg.diverged_m,
    )  # fmt: skip
    rows = summarize_fast_laps(results, cfg.diverged_m)
    summary = markdown_table(rows, cfg.diverged_m) + "\n"
    writable(out / "summary.md").write_text(summary, encoding="utf-8")
    return rows, results
