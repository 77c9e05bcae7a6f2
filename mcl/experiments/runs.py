"""One localized drive: a run = (map, driver, scenario, filter settings, seed, duration).

`run_one()` builds a ``RacecarSim-v0`` env on the map, wraps it in
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] with an error log, lets the driver drive for the
duration, and returns the run's error statistics. The experiment (`mcl.experiments`) and the
main job (``scripts/drive.py``) are both made of such runs.

Reproducibility: the env, the filter and the scenario each get their own stream from the run's
seed, and the drivers act on the scan (wall follower) or on the *true* pose (pure pursuit, unless
``drive_on="estimate"``), so runs that differ only in the filter's settings drive the same true
trajectory through the same sensor noise.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mcl.experiments.heap import TRIM_EVERY_S, release_free_heap
from mcl.experiments.metrics import DIVERGED_M, ErrorStats, error_stats
from mcl.experiments.run_bounds import check_duration
from mcl.experiments.scenarios import make_scenario
from mcl.filter.motion_model import MotionModelParams
from mcl.filter.params import DEFAULT_PARTICLES
from mcl.filter.sensor_model import SensorModel
from mcl.wrappers.error_log import read_error_log
from mcl.wrappers.hooks import StepHook
from mcl.wrappers.localization import LocalizationConfig
from mcl.wrappers.single import LocalizationWrapper
from racecar_sim.drivers import PurePursuit, WallFollower, waypoints_from_drive
from racecar_sim.env import EnvConfig, RacecarEnv
from racecar_sim.maps import DEFAULT_MAP, OccupancyMap, resolve_map

__all__ = [
    "DRIVERS",
    "DRIVE_ON",
    "RunResult",
    "RunSpec",
    "make_driver",
    "run_one",
    "scenario_rng",
]

DRIVE_ON: tuple[str, ...] = ("truth", "estimate")
"""Which pose a pose-based driver (pure pursuit) steers by."""

_SCENARIO_STREAM = 2  # spawn index of the scenario's stream in the run seed's SeedSequence
_WAYPOINT_SECONDS = 600.0  # simulated seconds the wall follower may take to close a loop
_RUN_ENV_DEFAULTS: dict[str, Any] = {"terminate_on_collision": False}

def scenario_rng(seed: int) -> np.random.Generator:
    """The generator a run with reset seed ``seed`` gives its scenario (e.g. where a kidnap
    carries the car): a stream of its own, spawned from ``seed``, so the env's and the filter's
    draws are the same with and without a scenario."""
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(_SCENARIO_STREAM + 1)[-1])


StepDriver = Callable[[Mapping[str, Any], Mapping[str, Any]], np.ndarray]
"""``driver(obs, info) -> action`` as used by `run_one()`."""


@dataclass(frozen=True)
class RunSpec:
    """Everything that defines one run (picklable, so it can go to a worker process).

    Attributes:
        map: bundled map name or map YAML path.
        driver: a key of `DRIVERS` (``"wall"`` or ``"pursuit"``).
        scenario: a key of [`mcl.experiments.scenarios.SCENARIOS`][mcl.experiments.scenarios.SCENARIOS].
        motion: the filter's motion noise (scheme, coefficients per update).
        seed: reset seed; the env's, the filter's and the scenario's streams derive from it.
        duration: seconds of simulated time.
        n_particles: particles of the filter.
        series: label of the experiment series the run belongs to (e.g. ``"uniform"``).
        nominal: the series' coefficient for this run, in the series' own units (plots' x).
        env: extra [`racecar_sim.env.EnvConfig`][racecar_sim.env.EnvConfig] settings as (name, value) pairs; runs
            default to ``terminate_on_collision=False`` so that each lasts its full duration.
        drive_on: ``"truth"`` or ``"estimate"``: the pose pure pursuit steers by.
        config: the filter's settings (sensor model, particle filter, ...) apart from ``motion``
            and ``n_particles``; None for [`LocalizationConfig`][mcl.wrappers.localization.LocalizationConfig] defaults.
        scenario_settings: keyword arguments of the scenario as (name, value) pairs.
        filter_map: bundled name or YAML path of the map the filter holds, when it differs from
            the world ``map`` (same world frame; size and resolution may differ); None = ``map``.
        driver_settings: keyword arguments of the driver as (name, value) pairs (``"racing"``:
            ``speed`` m/s, ``lookahead`` m).
        filter_seed: seeds the filter's random generator instead of ``seed`` (the wrapper's
            reset option ``filter_seed``): the same drive, another draw of the filter's motion
            noise and resampling; None: from ``seed``.
    """

    map: str = DEFAULT_MAP
    driver: str = "wall"
    scenario: str = "tracking"
    motion: MotionModelParams = field(default_factory=MotionModelParams)
    seed: int = 0
    duration: float = 60.0
    n_particles: int = DEFAULT_PARTICLES
    series: str = "run"
    nominal: float = math.nan
    env: tuple[tuple[str, Any], ...] = ()
    drive_on: str = "truth"
    config: LocalizationConfig | None = None
    scenario_settings: tuple[tuple[str, Any], ...] = ()
    filter_map: str | None = None
    driver_settings: tuple[tuple[str, Any], ...] = ()
    filter_seed: int | None = None

    def __post_init__(self) -> None:
        if self.driver not in DRIVERS:
            raise ValueError(f"RunSpec.driver = {self.driver!r}; choose one of {sorted(DRIVERS)}")
        if self.drive_on not in DRIVE_ON:
            raise ValueError(f"RunSpec.drive_on = {self.drive_on!r}; choose one of {DRIVE_ON}")
        check_duration("RunSpec", self.duration)
        n = self.n_particles
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ValueError(f"RunSpec.n_particles = {n!r} must be a positive integer")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"RunSpec.seed = {self.seed!r} must be a non-negative integer")
        fs = self.filter_seed
        if fs is not None and (isinstance(fs, bool) or not isinstance(fs, int) or fs < 0):
            raise ValueError(
                f"RunSpec.filter_seed = {fs!r} must be None or a non-negative integer"
            )
        object.__setattr__(self, "env", tuple((str(k), v) for k, v in dict(self.env).items()))
        settings = tuple((str(k), v) for k, v in dict(self.scenario_settings).items())
        object.__setattr__(self, "scenario_settings", settings)
        drive = tuple((str(k), v) for k, v in dict(self.driver_settings).items())
        object.__setattr__(self, "driver_settings", drive)
        if self.config is not None and not isinstance(self.config, LocalizationConfig):
            raise ValueError(f"RunSpec.config = {self.config!r} must be a LocalizationConfig")
        # the filter's bounds (mcl.filter.bounds) apply now, not when the run starts
        (self.config or LocalizationConfig()).with_particles(n)

    @property
    def env_settings(self) -> dict[str, Any]:
        """The RacecarEnv settings of the run (run defaults, then ``env``)."""
        return {**_RUN_ENV_DEFAULTS, **dict(self.env)}

    @property
    def dt(self) -> float:
        """Seconds per env step."""
        return float(self.env_settings.get("dt", EnvConfig.dt))

    @property
    def n_steps(self) -> int:
        """Env steps the run takes (= rows of its complete error log)."""
        return max(1, round(self.duration / self.dt))

    @property
    def run_id(self) -> str:
        """A file-name-safe name: series, coefficient, seed (and the filter's seed when given)."""
        coeff = "" if math.isnan(self.nominal) else f"_c{self.nominal:g}"
        draw = "" if self.filter_seed is None else f"_filter{self.filter_seed}"
        return f"{self.series}{coeff}_seed{self.seed}{draw}".replace("/", "-")


@dataclass(frozen=True)
class RunResult:
    """How a run went.

    Attributes:
        spec: the run.
        status: ``"ok"``, ``"skipped"`` (complete log found, not run again) or ``"failed"``.
        stats: error statistics from the log (None when the run failed before logging).
        log_path: the CSV error log.
        wall_s: seconds of wall time the run took (0 when skipped).
        n_collisions: steps with wall contact (-1 when not known, e.g. skipped).
        error: for a failed run, the exception and where it happened.
        outcome: what the scenario reports after the run (its ``outcome()``, if it has one).
    """

    spec: RunSpec
    status: str
    stats: ErrorStats | None
    log_path: Path
    wall_s: float = 0.0
    n_collisions: int = -1
    error: str = ""
    outcome: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------- drivers
def _wall_driver(env: RacecarEnv, seed: int, drive_on: str) -> StepDriver:
    follower = WallFollower.for_env(env)
    return lambda obs, info: follower(obs)


def _pursuit_driver(env: RacecarEnv, seed: int, drive_on: str) -> StepDriver:
    follower = WallFollower.for_env(env)
    max_steps = round(_WAYPOINT_SECONDS / env.dt)
    try:
        waypoints = waypoints_from_drive(env, follower, seed=seed, max_steps=max_steps)
    except RuntimeError as exc:
        raise RuntimeError(
            f"pure pursuit needs a loop of waypoints, recorded by following the wall from the "
            f"start of seed {seed}: {exc}"
        ) from exc
    return _pursue(PurePursuit(waypoints, loop=True, car=env.car_params), drive_on)


def _pursue(pursuit: PurePursuit, drive_on: str) -> StepDriver:
    if drive_on == "truth":
        return lambda obs, info: pursuit(obs, info["pose"])
    return lambda obs, info: pursuit(obs, obs["pose_estimate"])


def _racing_driver(
    env: RacecarEnv, seed: int, drive_on: str, speed: float = 6.0, lookahead: float | None = None
) -> StepDriver:
    """Pure pursuit round the map's loop ([`mcl.agents.track.track_for_map()`][mcl.agents.track.track_for_map]) at ``speed``
    m/s everywhere, corners included; look-ahead 0.3 s of travel (at least 1 m) unless given."""
    from mcl.agents.track import track_for_map

    ahead = max(1.0, 0.3 * speed) if lookahead is None else lookahead
    points = track_for_map(env.map.name).points
    return _pursue(PurePursuit(points, lookahead=ahead, speed=speed, car=env.car_params), drive_on)


DRIVERS: dict[str, Callable[..., StepDriver]] = {
    "wall": _wall_driver,
    "pursuit": _pursuit_driver,
    "racing": _racing_driver,
}
"""Driver factories ``factory(env, seed, drive_on, **settings) -> driver(obs, info)`` by name. They
may drive the bare env before the run (pure pursuit records its waypoints so)."""


def make_driver(
    name: str,
    env: RacecarEnv,
    seed: int,
    drive_on: str = "truth",
    settings: Mapping[str, Any] | None = None,
) -> StepDriver:
    """The driver ``name`` for the bare env ``env`` (see `DRIVERS`), with its ``settings``."""
    try:
        factory = DRIVERS[name]
    except KeyError:
        raise ValueError(f"unknown driver {name!r}; choose one of {sorted(DRIVERS)}") from None
    try:
        return factory(env, seed, drive_on, **dict(settings or {}))
    except TypeError as exc:
        raise ValueError(
            f"driver {name!r}: bad driver settings {dict(settings or {})}: {exc}"
        ) from None


# ---------------------------------------------------------------------- per-process caches
@lru_cache(maxsize=4)
def _load_map(spec: str) -> OccupancyMap:
    """The map of a run, loaded once per process."""
    return resolve_map(spec)


_SENSOR_MODELS: dict[tuple[Any, ...], SensorModel] = {}


def _sensor_model(grid: OccupancyMap, config: LocalizationConfig, env: RacecarEnv) -> SensorModel:
    """A sensor model shared by the runs of a process on the same map and lidar."""
    lidar = env.lidar
    key = (id(grid), config.sensor, float(lidar.params.mount_offset), lidar.angles.tobytes())
    model = _SENSOR_MODELS.get(key)
    if model is None:
        params = replace(config.sensor, mount_offset=float(lidar.params.mount_offset))
        model = SensorModel(grid, params, beam_angles=np.asarray(lidar.angles))
        if len(_SENSOR_MODELS) >= 4:
            _SENSOR_MODELS.pop(next(iter(_SENSOR_MODELS)))
        _SENSOR_MODELS[key] = model
    return model


# ---------------------------------------------------------------------- the run
def run_one(
    spec: RunSpec,
    log_path: str | Path,
    *,
    config: LocalizationConfig | None = None,
    on_frame: Callable[[np.ndarray, dict[str, Any]], None] | None = None,
    frame_every: int = 1,
    progress: bool = False,
    diverged_m: float = DIVERGED_M,
    step_hooks: Callable[[LocalizationWrapper], Sequence[StepHook]] | None = None,
) -> RunResult:
    """Drive ``spec`` with MCL in the loop, logging the error to ``log_path`` (CSV, see
    `mcl.wrappers.error_log`); returns its statistics.

    Args:
        spec: the run.
        log_path: where the error log goes (parents created, an old file replaced).
        config: filter settings besides ``spec.motion`` and ``spec.n_particles`` (defaults:
            ``spec.config``, else `LocalizationConfig`).
        on_frame: when given, called as ``on_frame(frame, info)`` with the ``render()`` frame (RGB
            uint8) and the info of the reset and of every ``frame_every``-th step.
        frame_every: steps between two frames.
        progress: show a tqdm bar over the steps.
        diverged_m: metres of error counted as diverged in the statistics.
        step_hooks: when given, called once with the run's wrapper before its reset; the step
            hooks it returns are attached to the wrapper
            ([`add_step_hook()`][mcl.wrappers.single.LocalizationWrapper.add_step_hook]), so each
            is called with the [`StepRecord`][mcl.wrappers.hooks.StepRecord] of the reset and of
            every step (e.g. a [`DriveRecorder`][mcl.io.bag_writer.DriveRecorder] writing a bag;
            closing it is the caller's job).

    Raises:
        Exception: whatever the map, the env, the driver or the filter raises; the log keeps the
            rows written.
    """
    if isinstance(frame_every, bool) or not isinstance(frame_every, int) or frame_every < 1:
        raise ValueError(f"frame_every must be a positive integer, got {frame_every!r}")
    t_start = time.perf_counter()
    grid = _load_map(spec.map)
    base = config if config is not None else spec.config or LocalizationConfig()
    config = replace(base.with_particles(spec.n_particles), motion=spec.motion)
    render_mode = "rgb_array" if on_frame is not None else None
    env = RacecarEnv(grid, render_mode=render_mode, **spec.env_settings)
    driver = make_driver(spec.driver, env, spec.seed, spec.drive_on, dict(spec.driver_settings))
    scenario = make_scenario(spec.scenario, **dict(spec.scenario_settings))
    after_step = getattr(scenario, "after_step", None)
    rng = scenario_rng(spec.seed)
    filter_grid = grid if spec.filter_map is None else _load_map(spec.filter_map)
    wrapped = LocalizationWrapper(
        env,
        config,
        log_path=log_path,
        sensor_model=_sensor_model(filter_grid, config, env),
        filter_map=filter_grid,
    )
    n_collisions = 0
    try:
        for hook in step_hooks(wrapped) if step_hooks is not None else ():
            wrapped.add_step_hook(hook)
        options = scenario.reset_options()
        if spec.filter_seed is not None:
            options = {**options, "filter_seed": spec.filter_seed}
        obs, info = wrapped.reset(seed=spec.seed, options=options)
        if on_frame is not None:
            on_frame(wrapped.render(), info)
        steps: Any = range(1, spec.n_steps + 1)
        if progress:
            from tqdm import tqdm

            steps = tqdm(steps, desc=spec.run_id, unit="step", leave=False)
        trim_every = max(1, round(TRIM_EVERY_S / env.dt))  # steps between two heap trims
        for k in steps:
            if k % trim_every == 0:
                release_free_heap()  # pages the allocator keeps but nothing holds (heap.py)
            scenario.before_step(wrapped, k, (k - 1) * env.dt, rng)
            obs, _, terminated, truncated, info = wrapped.step(driver(obs, info))
            n_collisions += bool(info["collision"])
            if after_step is not None:
                after_step(wrapped, k, info)
            if on_frame is not None and k % frame_every == 0:
                on_frame(wrapped.render(), info)
            if terminated or truncated:
                break
    finally:
        wrapped.close()
    stats = error_stats(read_error_log(log_path), diverged_m)
    return RunResult(
        spec=spec,
        status="ok",
        stats=stats,
        log_path=Path(log_path),
        wall_s=time.perf_counter() - t_start,
        n_collisions=n_collisions,
        outcome=dict(scenario.outcome()) if hasattr(scenario, "outcome") else {},
    )
