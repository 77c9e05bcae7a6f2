"""Recorded drives: drive once, store what the filter would see, replay it through any filter.

[record_drive][mcl.experiments.recorded.record_drive] runs a ``RacecarSim-v0`` env
([RacecarEnv][racecar_sim.env.RacecarEnv]) with a driver, as ``racecar-sim drive`` does (world
map, scene, noise profile, driver, seed, duration), and keeps per step the scan, the odometry, the
true pose and the time, plus the lidar's geometry and the maps' paths, in a
[RecordedDrive][mcl.experiments.recorded.RecordedDrive] (an ``.npz`` file with
[save][mcl.experiments.recorded.RecordedDrive.save] / [load][mcl.experiments.recorded.RecordedDrive.load]).
[localize_recorded][mcl.experiments.recorded.localize_recorded] feeds it through the same filter
code as [LocalizationWrapper][mcl.wrappers.single.LocalizationWrapper]
(``mcl.wrappers.localization.start_filter``, ``predict`` with the step's odometry, the lost
flag's [LostDetector][mcl.filter.lost.LostDetector] advanced by it,
``mcl.wrappers.localization.correct_with_scan`` on a fresh scan, the detector observing it and
asking for its recovery): with the same seed it gives the online run's estimates and lost flags
bit for bit. A peer filter (nav2's amcl, ``mcl.bench.peer_amcl``) gets the very same drives.

The drive does not depend on the filter: the wall follower steers by the scan and pure pursuit by
the true pose, so recording without a filter drives the trajectory of the localized run.

Frames and units: world frame of the map; poses [x, y, theta] of the rear axle in metres and
radians; odometry the VESC's car-frame twist [vx m/s, vy m/s, omega rad/s] as the env reports it
(float32); scans in metres along the beam angles (radians, car frame, from the lidar at
``mount_offset`` metres ahead of the rear axle); times in seconds.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mcl.experiments.run_bounds import check_duration
from mcl.filter.angles import wrap_angle
from mcl.filter.lost import LostDetector
from mcl.filter.motion_model import MotionModel
from mcl.filter.sensor_model import SensorModel
from mcl.wrappers.localization import (
    LocalizationConfig,
    as_localization_config,
    correct_with_scan,
    filter_rng,
    start_filter,
)
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import OccupancyMap, resolve_map

__all__ = ["LocalizedRun", "RecordedDrive", "localize_recorded", "localized_run", "record_drive"]

_FORMAT = 1  # version of the .npz layout
_ARRAYS = ("time", "dt_steps", "truth", "odom", "fresh", "scans", "beam_angles")


@dataclass(frozen=True, eq=False)
class RecordedDrive:
    """One drive as the filter sees it, with the truth.

    Step 0 is the reset (a fresh scan, no odometry); steps 1..n follow ``env.step``.

    Attributes:
        time: (n+1,) simulated seconds of each step.
        dt_steps: (n+1,) seconds each step lasted (0 at the reset).
        truth: (n+1, 3) true pose [x m, y m, theta rad] of the rear axle, world frame.
        odom: (n+1, 3) the odometry the filter sees: the env's ``obs["odom"]`` car-frame twist
            [vx m/s, vy m/s, omega rad/s] as reported (float32); row 0 is zeros.
        fresh: (n+1,) bool, whether the step carried a fresh scan (``info["new_scan"]``).
        scans: (number of fresh steps, n_beams) ranges in metres of the fresh scans, in step order
            (float32 as the env reports them); ``max_range`` means no return.
        beam_angles: (n_beams,) beam angles, radians in the car frame.
        mount_offset: metres from the rear axle forward to the lidar.
        max_range: the lidar's longest range, metres.
        dt: the env's step, seconds (the filter's prediction interval).
        world_map: the map the car drove in (bundled name or YAML path, as given).
        filter_map: the map a filter should hold (name or path), None = ``world_map``.
        settings: how the drive was made: driver, seed, duration, scene, noise profile, the env
            settings (a JSON-able mapping).
    """

    time: np.ndarray
    dt_steps: np.ndarray
    truth: np.ndarray
    odom: np.ndarray
    fresh: np.ndarray
    scans: np.ndarray
    beam_angles: np.ndarray
    mount_offset: float
    max_range: float
    dt: float
    world_map: str
    filter_map: str | None = None
    settings: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        n = len(self.time)
        if n < 1:
            raise ValueError("RecordedDrive: no steps")
        for name, shape in (("dt_steps", (n,)), ("truth", (n, 3)), ("odom", (n, 3)),
                            ("fresh", (n,))):  # fmt: skip
            if np.shape(getattr(self, name)) != shape:
                got = np.shape(getattr(self, name))
                raise ValueError(f"RecordedDrive.{name} has shape {got}, expected {shape}")
        n_fresh = int(np.count_nonzero(self.fresh))
        if np.shape(self.scans) != (n_fresh, len(self.beam_angles)):
            raise ValueError(
                f"RecordedDrive.scans has shape {np.shape(self.scans)}, expected "
                f"({n_fresh} fresh steps, {len(self.beam_angles)} beams)"
            )
        if not bool(self.fresh[0]):
            raise ValueError("RecordedDrive: step 0 (the reset) must carry a fresh scan")

    @property
    def n_steps(self) -> int:
        """Steps after the reset."""
        return len(self.time) - 1

    @property
    def scan_rows(self) -> np.ndarray:
        """(n+1,) row of ``scans`` holding each step's latest fresh scan."""
        return np.cumsum(self.fresh) - 1

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the drive to ``path`` (``.npz``, compressed); returns the path written."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {
            "format": _FORMAT,
            "mount_offset": self.mount_offset,
            "max_range": self.max_range,
            "dt": self.dt,
            "world_map": self.world_map,
            "filter_map": self.filter_map,
            "settings": dict(self.settings or {}),
        }
        arrays = {name: np.asarray(getattr(self, name)) for name in _ARRAYS}
        np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> RecordedDrive:
        """The drive saved at ``path`` by [save][mcl.experiments.recorded.RecordedDrive.save].

        Raises:
            ValueError: not a recorded drive (or of another format version).
        """
        with np.load(path, allow_pickle=False) as data:
            if "meta" not in data.files:
                raise ValueError(f"{path}: not a recorded drive (no 'meta' entry)")
            meta = json.loads(str(data["meta"]))
            if meta.get("format") != _FORMAT:
                raise ValueError(f"{path}: recorded drive format {meta.get('format')}, "
                                 f"this version reads {_FORMAT}")  # fmt: skip
            arrays = {name: data[name] for name in _ARRAYS}
        return cls(
            **arrays,
            mount_offset=float(meta["mount_offset"]),
            max_range=float(meta["max_range"]),
            dt=float(meta["dt"]),
            world_map=meta["world_map"],
            filter_map=meta["filter_map"],
            settings=meta["settings"],
        )


def record_drive(
    world_map: str | os.PathLike[str],
    *,
    filter_map: str | os.PathLike[str] | None = None,
    scene: str | None = None,
    noise_profile: str | None = None,
    driver: str = "wall",
    seed: int = 0,
    duration: float = 60.0,
    env: Mapping[str, Any] | None = None,
    kidnap_at: float | None = None,
) -> RecordedDrive:
    """Drive ``world_map`` for ``duration`` simulated seconds and record it.

    The env is built as ``racecar-sim drive`` and the experiments build it
    ([run_one][mcl.experiments.runs.run_one]): ``terminate_on_collision=False`` unless ``env``
    says otherwise, then ``env``, ``noise_profile`` and ``scene``; reset with ``seed``; the driver
    ([make_driver][mcl.experiments.runs.make_driver]) steers by the scan (``"wall"``) or the
    truth. The drive ends early when the env terminates or truncates.

    Args:
        world_map: the world (bundled name or map YAML).
        filter_map: the map a filter should hold (stored, not used here); None = the world.
        scene: ``"clean"``, ``"cluttered"``, ``"none"`` or None (``racecar_sim.world.scenes``).
        noise_profile: e.g. ``"mit_racecar"``; None = the env's own (ideal) settings.
        driver: a key of [DRIVERS][mcl.experiments.runs.DRIVERS].
        seed: the reset seed (start pose, sensor noise, obstacles).
        duration: simulated seconds.
        env: further [EnvConfig][racecar_sim.settings.config.EnvConfig] settings.
        kidnap_at: seconds after the reset (more than 0, less than ``duration``) at which the
            car is carried to a random free pose at least 2 m away, as `racecar-sim lost-flag`
            kidnaps it ([KidnapScenario][mcl.experiments.scenarios.KidnapScenario], drawn from the
            [scenario_rng][mcl.experiments.runs.scenario_rng] of ``seed``: the same kidnap as
            that command's kidnap drive of this seed); None: no kidnap. The drive's
            ``settings`` hold ``kidnap_at`` (None without a kidnap) and ``kidnap_to``.
    """
    from mcl.experiments.runs import make_driver, scenario_rng  # imports the wrapper: here only
    from mcl.experiments.scenarios import KidnapScenario

    check_duration("record_drive", duration)
    if kidnap_at is not None and check_duration("record_drive", kidnap_at, "kidnap_at") >= duration:
        raise ValueError(f"record_drive.kidnap_at = {kidnap_at} s must be under duration = {duration} s")
    settings: dict[str, Any] = {"terminate_on_collision": False, **dict(env or {})}
    if noise_profile is not None:
        settings["noise_profile"] = noise_profile
    if scene is not None:
        settings["scene"] = scene
    sim = RacecarEnv(_map(str(world_map)), **settings)
    kidnap = None if kidnap_at is None else KidnapScenario(kidnap_time=kidnap_at)
    rng = scenario_rng(seed)
    try:
        drive_fn = make_driver(driver, sim, seed)
        obs, info = sim.reset(seed=seed)
        n = max(1, round(duration / sim.dt))
        times, dts, truth, odom, fresh, scans = [], [], [], [], [], []

        def keep(obs: Mapping[str, Any], info: Mapping[str, Any], dt: float, new: bool) -> None:
            times.append(float(info["time"]))
            dts.append(dt)
            truth.append(np.asarray(info["pose"], dtype=np.float64))
            fresh.append(new)
            if new:
                scans.append(np.array(obs["scan"]))

        keep(obs, info, 0.0, True)
        odom.append(np.zeros(3, dtype=np.asarray(obs["odom"]).dtype))
        for k in range(1, n + 1):
            if kidnap is not None:
                kidnap.before_step(sim, k, (k - 1) * sim.dt, rng)
            obs, _, terminated, truncated, info = sim.step(drive_fn(obs, info))
            keep(obs, info, float(sim.dt), bool(info.get("new_scan", True)))
            odom.append(np.array(obs["odom"]))
            if terminated or truncated:
                break
        lidar = sim.lidar
        return RecordedDrive(
            time=np.array(times),
            dt_steps=np.array(dts),
            truth=np.stack(truth),
            odom=np.stack(odom),
            fresh=np.array(fresh, dtype=bool),
            scans=np.stack(scans),
            beam_angles=np.asarray(lidar.angles, dtype=np.float64).copy(),
            mount_offset=float(lidar.params.mount_offset),
            max_range=float(lidar.params.max_range),
            dt=float(sim.dt),
            world_map=str(world_map),
            filter_map=None if filter_map is None else str(filter_map),
            settings={"driver": driver, "seed": seed, "duration": duration, "scene": scene,
                      "noise_profile": noise_profile, "env": _jsonable(dict(env or {})),
                      "kidnap_at": None if kidnap is None or not kidnap.kidnap_to else kidnap.kidnap_time,
                      "kidnap_to": None if kidnap is None else kidnap.kidnap_to},
        )  # fmt: skip
    finally:
        sim.close()


@dataclass(frozen=True, eq=False)
class LocalizedRun:
    """A filter's estimates along a [RecordedDrive][mcl.experiments.recorded.RecordedDrive].

    Attributes:
        estimate: (n+1, 3) estimate [x m, y m, theta rad] after each step, world frame.
        position_error: (n+1,) metres from the true position.
        heading_error: (n+1,) radians, estimate minus truth wrapped to [-pi, pi).
        n_particles: (n+1,) particles after each step.
        lost: (n+1,) bool, the filter's ``lost`` flag after each step (all False for a filter
            without one, e.g. amcl).
    """

    estimate: np.ndarray
    position_error: np.ndarray
    heading_error: np.ndarray
    n_particles: np.ndarray
    lost: np.ndarray


def localize_recorded(
    drive: RecordedDrive,
    config: LocalizationConfig | Mapping[str, Any] | None = None,
    filter_map: str | os.PathLike[str] | OccupancyMap | None = None,
    seed: int | None = None,
) -> LocalizedRun:
    """Replay ``drive`` through our particle filter, as
    [LocalizationWrapper][mcl.wrappers.single.LocalizationWrapper] runs it online.

    The filter starts on the reset's true pose (``config.init="pose"``, spread
    ``config.filter.init_spread``) or uniformly (``"global"``) with the generator
    ``mcl.wrappers.localization.filter_rng`` derives from ``seed``, is corrected by the reset's
    scan, then per step predicts with the odometry held for ``drive.dt`` and corrects on a fresh
    scan; the lost flag ([LostDetector][mcl.filter.lost.LostDetector], ``config.lost``) follows
    every step and asks for its recovery as it does online. With the drive's seed the estimates
    and the flags equal the online run's bit for bit.

    Args:
        drive: the recorded drive.
        config: the filter's settings (None: the defaults); not the adaptive filter.
        filter_map: the map the filter holds (name, YAML or map); None = ``drive.filter_map``,
            else the drive's world.
        seed: the filter's seed; None = the drive's reset seed.

    Raises:
        ValueError: ``config`` asks for the adaptive filter.
    """
    config = as_localization_config(config)
    if config.adaptive is not None:
        raise ValueError("localize_recorded runs the particle filter; set adaptive=None")
    if seed is None:
        seed = int((drive.settings or {}).get("seed", 0))
    if filter_map is None:
        filter_map = drive.filter_map or drive.world_map
    grid = filter_map if isinstance(filter_map, OccupancyMap) else _map(str(filter_map))
    pf = start_filter(
        grid, config, _sensor_model(grid, config, drive), MotionModel(config.motion),
        filter_rng(seed), config.init, drive.truth[0], None,
    )  # fmt: skip
    detector = LostDetector(config.lost)
    n = len(drive.time)
    estimate = np.empty((n, 3))
    counts = np.empty(n, dtype=np.int64)
    lost = np.zeros(n, dtype=bool)
    scans, odom, fresh, dt = drive.scans, drive.odom, drive.fresh, drive.dt
    row = 0
    correct_with_scan(pf, scans[0], drive.max_range, detector)
    estimate[0], counts[0], lost[0] = pf.estimate(), pf.n_particles, detector.lost
    for k in range(1, n):
        pf.predict(np.asarray(odom[k], dtype=np.float64), dt)
        detector.advance(dt, odom[k])
        if fresh[k]:
            row += 1
            correct_with_scan(pf, scans[row], drive.max_range, detector)
        estimate[k], counts[k], lost[k] = pf.estimate(), pf.n_particles, detector.lost
    return localized_run(estimate, drive.truth, counts, lost)


def localized_run(
    estimate: np.ndarray,
    truth: np.ndarray,
    n_particles: np.ndarray | None = None,
    lost: np.ndarray | None = None,
) -> LocalizedRun:
    """A [LocalizedRun][mcl.experiments.recorded.LocalizedRun] of estimates (n, 3) against the
    truth (n, 3), errors as ``mcl.wrappers.localization.pose_error`` takes them (vectorised);
    ``n_particles`` -1 and ``lost`` False where not given."""
    estimate = np.asarray(estimate, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    position = np.hypot(estimate[:, 0] - truth[:, 0], estimate[:, 1] - truth[:, 1])
    heading = wrap_angle(estimate[:, 2] - truth[:, 2])
    if n_particles is None:
        n_particles = np.full(len(estimate), -1, dtype=np.int64)
    lost = np.zeros(len(estimate), dtype=bool) if lost is None else np.asarray(lost, dtype=bool)
    return LocalizedRun(estimate, position, heading, np.asarray(n_particles), lost)


@lru_cache(maxsize=4)
def _map(spec: str) -> OccupancyMap:
    """A map loaded once per process."""
    return resolve_map(spec)


_SENSOR_MODELS: dict[tuple[Any, ...], SensorModel] = {}


def _sensor_model(
    grid: OccupancyMap, config: LocalizationConfig, drive: RecordedDrive
) -> SensorModel:
    """The sensor model of ``config`` for the drive's lidar on ``grid``, shared by the replays
    of a process (its lookup table is built once)."""
    angles = np.asarray(drive.beam_angles, dtype=np.float64)
    key = (id(grid), config.sensor, drive.mount_offset, angles.tobytes())
    model = _SENSOR_MODELS.get(key)
    if model is None:
        params = replace(config.sensor, mount_offset=float(drive.mount_offset))
        model = SensorModel(grid, params, beam_angles=angles)
        if len(_SENSOR_MODELS) >= 4:
            _SENSOR_MODELS.pop(next(iter(_SENSOR_MODELS)))
        _SENSOR_MODELS[key] = model
    return model


def _jsonable(value: Any) -> Any:
    """``value`` with tuples as lists and other objects as their ``repr`` (for the metadata)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return repr(value)
