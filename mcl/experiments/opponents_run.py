"""MCL among opponents: one localized drive with K opponents close ahead, and the table over seeds.

A run (`OpponentRun`) drives the car by pure pursuit (on its true pose, so that filter
settings never change the trajectory) round the map's loop at ``speed``, starting at a point of
the loop picked by the seed, with [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] in the loop, and logs
the position error against the truth every step. The opponents are
[`OpponentsScenario`][mcl.experiments.opponents.OpponentsScenario]'s car-sized boxes held ``gaps`` metres
ahead on the same line (``backend="boxes"``), or ``RacecarRace-v0``'s scripted cars
(``backend="race"``: every car on pure pursuit along the race's centerline at ``speed``, the
opponents starting ``gaps`` ahead of car 0, which the filter localizes).

`opponents_table()` pools the steps of every seed of one (opponents, method) cell: mean,
median and 95th percentile of the position error (metres), the fraction of steps over
[`DIVERGED_M`][mcl.experiments.metrics.DIVERGED_M], the runs that ever diverged, and the beams beam
skipping left out.

Frames and units: world frame; metres, radians, seconds.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from mcl.experiments.metrics import DIVERGED_M
from mcl.experiments.opponents import OpponentsScenario
from mcl.experiments.run_bounds import check_duration
from mcl.filter.params import DEFAULT_PARTICLES
from mcl.filter.sensor_params import SensorModelParams
from mcl.wrappers.error_log import read_error_log
from mcl.wrappers.localization import TRACKING_INIT_SPREAD, LocalizationConfig
from mcl.wrappers.single import LocalizationWrapper

__all__ = [
    "BACKENDS",
    "METHODS",
    "OpponentRun",
    "OpponentRunResult",
    "opponents_table",
    "run_opponents",
]

METHODS: dict[str, dict[str, Any]] = {
    "plain": {},
    "beam_skip": {"beam_skip": True},
    "beam_skip_short": {"beam_skip": True, "beam_skip_short_only": True},
}
"""Sensor-model settings of each method of the table (`SensorModelParams` fields)."""

BACKENDS: tuple[str, ...] = ("boxes", "race")
"""Where the opponents come from: car-sized boxes held ahead, or ``RacecarRace-v0``'s cars."""

_GOLDEN = 0.6180339887498949  # start points of successive seeds spread round the loop


@dataclass(frozen=True)
class OpponentRun:
    """One localized drive among opponents.

    Attributes:
        map: bundled map with a loop ([`mcl.agents.track.track_for_map()`][mcl.agents.track.track_for_map]).
        opponents: cars close ahead (0 = alone).
        method: a key of `METHODS`.
        seed: reset seed (env, filter and start point).
        duration: seconds of simulated time.
        speed: m/s of the car (and of the opponents, which keep their gaps).
        gaps: metres of loop from the car's rear axle to each opponent's centre (boxes backend).
        n_particles: particles of the filter.
        backend: a key of `BACKENDS`.
        sensor: extra `SensorModelParams` settings as (name, value) pairs.
    """

    map: str = "basement_loop"
    opponents: int = 0
    method: str = "plain"
    seed: int = 0
    duration: float = 30.0
    speed: float = 2.0
    gaps: tuple[float, ...] = (2.0, 3.2, 4.4)
    n_particles: int = DEFAULT_PARTICLES
    backend: str = "boxes"
    sensor: tuple[tuple[str, Any], ...] = field(default=())

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"OpponentRun.method = {self.method!r}; choose one of {list(METHODS)}")
        if self.backend not in BACKENDS:
            raise ValueError(f"OpponentRun.backend = {self.backend!r}; choose one of {BACKENDS}")
        check_duration("OpponentRun", self.duration)
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"OpponentRun.speed = {self.speed!r} must be positive m/s")

    def config(self) -> LocalizationConfig:
        """The filter's settings: the defaults, this method's sensor settings, ``n_particles``."""
        sensor = SensorModelParams(**{**METHODS[self.method], **dict(self.sensor)})
        return LocalizationConfig(sensor=sensor).with_particles(self.n_particles)

    @property
    def run_id(self) -> str:
        """A file-name-safe name."""
        return f"{self.backend}_k{self.opponents}_{self.method}_seed{self.seed}"


@dataclass(frozen=True)
class OpponentRunResult:
    """A run's log and what else it counted.

    Attributes:
        run: the run.
        log_path: its CSV error log (`mcl.wrappers.error_log`).
        collisions: steps with any contact.
        skipped_beams: beams left out over beams scored, over the corrected steps.
        converged: fraction of the corrected steps on which the cloud counted as converged.
        wall_s: seconds of wall time.
    """

    run: OpponentRun
    log_path: Path
    collisions: int
    skipped_beams: float
    converged: float
    wall_s: float


def _start_pose(track: Any, seed: int) -> np.ndarray:
    s = track.length * ((seed * _GOLDEN) % 1.0)
    x, y = track.point_at(s)
    return np.array([x, y, track.heading_at(s)])


def run_opponents(run: OpponentRun, log_path: str | Path) -> OpponentRunResult:
    """Drive ``run`` (see the module docstring), logging the error to ``log_path``."""
    from mcl.agents.track import track_for_map
    from racecar_sim.drivers import PurePursuit
    from racecar_sim.env import RacecarEnv

    t0 = time.perf_counter()
    track = track_for_map(run.map)
    start = _start_pose(track, run.seed)
    if run.backend == "race":
        return _run_race(run, log_path, t0)
    settings: dict[str, Any] = {"terminate_on_collision": False}
    if run.opponents:
        settings["obstacles"] = {"boxes": run.opponents}
    env = RacecarEnv(run.map, **settings)
    pursuit = PurePursuit(track.points, speed=run.speed, loop=True, car=env.car_params)
    scenario = OpponentsScenario(n=run.opponents, gaps=run.gaps, track=track)
    wrapped = LocalizationWrapper(env, run.config(), log_path=log_path)
    options = {**scenario.reset_options(), "pose": start}
    return _drive(run, wrapped, options, lambda obs, info: pursuit(obs, info["pose"]),
                  lambda k: scenario.before_step(wrapped, k, 0.0, None), log_path, t0)  # fmt: skip


def _run_race(run: OpponentRun, log_path: str | Path, t0: float) -> OpponentRunResult:
    """The race backend (module docstring): ``LocalizationWrapper(gym.make("RacecarRace-v0"))``."""
    import gymnasium as gym

    import racecar_sim  # noqa: F401  (registers RacecarRace-v0)
    from racecar_sim.drivers import PurePursuit

    k = run.opponents
    env = gym.make(
        "RacecarRace-v0",
        map=run.map,
        opponents=k,
        opponent_driver="pure_pursuit",
        opponent_speeds=[run.speed] * k,
        terminate_on_collision=False,
    )
    line = env.unwrapped.track
    s0 = line.length * ((run.seed * _GOLDEN) % 1.0)
    arc = [s0, *(s0 + g for g in run.gaps[:k])]
    poses = np.array([[*line.point_at(s), line.heading_at(s)] for s in arc])
    pursuit = PurePursuit(line.points, speed=run.speed, loop=True, car=env.unwrapped.car_params)
    wrapped = LocalizationWrapper(env, run.config(), log_path=log_path)
    options = {"poses": poses, "init": "pose", "init_spread": TRACKING_INIT_SPREAD}
    return _drive(run, wrapped, options, lambda obs, info: pursuit(obs, info["pose"]),
                  lambda step: None, log_path, t0)  # fmt: skip


def _drive(run, wrapped, options, driver, before_step, log_path, t0) -> OpponentRunResult:
    sensor = wrapped.sensor_model
    n_steps = max(1, round(run.duration / wrapped.dt))
    collisions = skipped = scored = converged = corrected = 0
    try:
        obs, info = wrapped.reset(seed=run.seed, options=options)
        for k in range(1, n_steps + 1):
            before_step(k)
            obs, _, terminated, truncated, info = wrapped.step(driver(obs, info))
            collisions += bool(info.get("collision"))
            if info["localization"]["corrected"]:
                decision = sensor.last_beam_skip
                corrected += 1
                converged += decision.converged
                skipped += decision.skipped
                scored += decision.n_beams
            if terminated or truncated:
                break
    finally:
        wrapped.close()
    return OpponentRunResult(
        run=run,
        log_path=Path(log_path),
        collisions=collisions,
        skipped_beams=skipped / scored if scored else 0.0,
        converged=converged / corrected if corrected else 0.0,
        wall_s=time.perf_counter() - t0,
    )


def opponents_table(
    results: list[OpponentRunResult], diverged_m: float = DIVERGED_M
) -> list[dict[str, Any]]:
    """One row per (backend, opponents, method): the seeds' steps pooled (module docstring)."""
    cells: dict[tuple[str, int, str], list[OpponentRunResult]] = {}
    for r in results:
        cells.setdefault((r.run.backend, r.run.opponents, r.run.method), []).append(r)
    rows = []
    for (backend, k, method), group in sorted(
        cells.items(), key=lambda kv: (kv[0][0], kv[0][1], list(METHODS).index(kv[0][2]))
    ):
        logs = [read_error_log(r.log_path) for r in group]
        err = np.concatenate([log.position_error for log in logs])
        rows.append(
            {
                "backend": backend,
                "opponents": k,
                "method": method,
                "seeds": len(group),
                "steps": int(err.size),
                "mean_m": float(err.mean()),
                "median_m": float(np.median(err)),
                "p95_m": float(np.percentile(err, 95)),
                "max_m": float(err.max()),
                "diverged_steps": float(np.mean(err > diverged_m)),
                "diverged_runs": int(
                    sum(bool((log.position_error > diverged_m).any()) for log in logs)
                ),
                "skipped_beams": float(np.mean([r.skipped_beams for r in group])),
                "collisions": int(sum(r.collisions for r in group)),
                "update_ms": float(np.mean(np.concatenate([log.update_s for log in logs])) * 1e3),
            }
        )
    return rows


def run_row(result: OpponentRunResult, diverged_m: float = DIVERGED_M) -> dict[str, Any]:
    """A run's CSV row: its settings and its own error statistics."""
    err = read_error_log(result.log_path).position_error
    run = {k: v for k, v in asdict(result.run).items() if k not in ("gaps", "sensor")}
    return {
        **run,
        "mean_m": float(err.mean()),
        "median_m": float(np.median(err)),
        "p95_m": float(np.percentile(err, 95)),
        "max_m": float(err.max()),
        "diverged_steps": float(np.mean(err > diverged_m)),
        "skipped_beams": result.skipped_beams,
        "converged": result.converged,
        "collisions": result.collisions,
        "wall_s": result.wall_s,
    }


def with_method(run: OpponentRun, method: str) -> OpponentRun:
    """The same run with another method."""
    return replace(run, method=method)
