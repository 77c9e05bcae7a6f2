"""Every setting of the simulator in one place: `EnvConfig`, the env's keywords (see
[`racecar_sim.env.RacecarEnv`][racecar_sim.env.RacecarEnv]), in SI units, with the YAML settings file and the merge of
settings, profile and scene.

Frozen dataclasses validated once when built. Every class can be built from a mapping or a YAML file
with `from_mapping()` / `from_yaml()` ([`racecar_sim.settings.params`][racecar_sim.settings.params]); unknown keys raise a
``ValueError`` naming them. The parts live by job and are re-exported here: the car
([`racecar_sim.car.models.params`][racecar_sim.car.models.params]), the lidar and the odometry noise
([`racecar_sim.sensors.params`][racecar_sim.sensors.params]).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from racecar_sim.car.models import check_car_model
from racecar_sim.car.models.params import CarParams
from racecar_sim.maps import OccupancyMap
from racecar_sim.sensors.imu import ImuParams
from racecar_sim.sensors.noise_profiles import profile_document
from racecar_sim.sensors.params import LidarParams, OdometryNoise
from racecar_sim.sensors.scan_effects import OdometryBias, ScanEffects
from racecar_sim.settings.bounds import MAX_SUBSTEPS, check
from racecar_sim.settings.params import from_mapping, from_yaml, nested
from racecar_sim.settings.validation import check_number, read_yaml_mapping, short
from racecar_sim.world.obstacle_params import ObstacleParams
from racecar_sim.world.scenes import scene_obstacles

__all__ = [
    "CarParams",
    "EnvConfig",
    "LidarParams",
    "OdometryNoise",
    "from_mapping",
    "from_yaml",
    "load_config",
    "merge_settings",
    "nested",
]

# ---------------------------------------------------------------------- the env's settings
_LIDAR = LidarParams()
_ODOM = OdometryNoise()


@dataclass(frozen=True)
class EnvConfig:
    """Every setting of `RacecarEnv` (SI units), with defaults.

    Attributes:
        map: bundled map name, map YAML path or `OccupancyMap`; None = the default map.
        n_beams: lidar beams per scan.
        fov: radians covered by the scan, centred on the heading.
        max_range: metres, longest lidar range (and the value of a drop-out).
        mount_offset: metres from the rear axle forwards to the lidar.
        lidar_rate: scans per second.
        dt: seconds of control per `RacecarEnv.step()`.
        substep: longest physics substep, seconds.
        terminate_on_collision: end the episode when the car touches a wall.
        collision_penalty: reward subtracted on a step with wall contact.
        start_clearance: metres of free space kept around the car's footprint at a random start.
        range_sigma: metres, Gaussian range noise of the lidar.
        p_short: probability per beam of a short return.
        short_lambda: 1/metres, rate of the short-return distance.
        p_max: probability per beam of a max-range drop-out.
        p_rand: probability per beam of a uniformly random return.
        odom_proportional: odometry (vx, vy, omega) noise as a fraction of the true value.
        odom_additive: odometry (vx, vy, omega) additive noise, m/s, m/s, rad/s.
        car: the car's geometry and limits, a `CarParams` or a mapping of its fields.
        noise_profile: a named set of these settings ([`racecar_sim.sensors.noise_profiles`][racecar_sim.sensors.noise_profiles], e.g.
            ``"mit_racecar"``) applied under the explicit ones; None = none.
        scan_effects: correlated lidar failures replacing the four-part noise
            ([`racecar_sim.sensors.scan_effects.ScanEffects`][racecar_sim.sensors.scan_effects.ScanEffects] or a mapping of its fields); None = off.
        odom_bias: systematic odometry error ([`racecar_sim.sensors.scan_effects.OdometryBias`][racecar_sim.sensors.scan_effects.OdometryBias] or a
            mapping ``{scale, offset}``); None = none.
        obstacles: unmapped boxes and walking people ([`racecar_sim.world.obstacle_params.ObstacleParams`][racecar_sim.world.obstacle_params.ObstacleParams]
            or a mapping of its fields); None = none.
        odom_lead: seconds by which the wheel odometry leads the body's motion (the body gets each
            command this much later, rounded to whole steps; [`racecar_sim.sensors.vesc`][racecar_sim.sensors.vesc]); 0 = none.
        imu: a yaw-rate gyro in ``obs["imu"]`` ([`racecar_sim.sensors.vesc.ImuParams`][racecar_sim.sensors.vesc.ImuParams], a mapping
            ``{sigma, bias}`` or True for its defaults); None = no IMU.
        track: the race track for progress, laps, lap times and rank in the info
            (`racecar_sim.world.track.resolve_track()`): a centerline CSV in f1tenth's format,
            ``"auto"`` (derived from a loop map) or a ``Track``; None = no track.
        car_model: ``"kinematic"`` (the kinematic bicycle) or ``"single_track"`` (tire slip, a
            friction limit): `racecar_sim.car.models`.
        max_map_cells: the most cells (width x height) a map may have; None = the default
            (`racecar_sim.maps.limits.max_map_cells()`, 4 million). Checked before the map's
            image is decoded.
        scene: what the room adds to the map (`racecar_sim.world.scenes`): ``"clean"`` (openings
            in the walls: glass, open doors), ``"cluttered"`` (also furniture and people) or
            ``"none"``; its obstacle settings go under ``obstacles``. None = none.
    """

    map: str | os.PathLike[str] | OccupancyMap | None = None
    n_beams: int = _LIDAR.n_beams
    fov: float = _LIDAR.fov
    max_range: float = _LIDAR.max_range
    mount_offset: float = _LIDAR.mount_offset
    lidar_rate: float = _LIDAR.rate
    dt: float = 0.025
    substep: float = 0.005
    terminate_on_collision: bool = True
    collision_penalty: float = 1.0
    start_clearance: float = 0.1
    range_sigma: float = _LIDAR.sigma
    p_short: float = _LIDAR.p_short
    short_lambda: float = _LIDAR.short_lambda
    p_max: float = _LIDAR.p_max
    p_rand: float = _LIDAR.p_rand
    odom_proportional: tuple[float, float, float] = _ODOM.proportional
    odom_additive: tuple[float, float, float] = _ODOM.additive
    car: CarParams = field(default_factory=CarParams)
    noise_profile: str | None = None
    scan_effects: Any = None
    odom_bias: Any = None
    obstacles: Any = None
    odom_lead: float = 0.0
    imu: Any = None
    track: Any = None
    car_model: str = "kinematic"
    max_map_cells: int | None = None
    scene: str | None = None

    def __post_init__(self) -> None:
        check_car_model(self.car_model)
        if self.max_map_cells is not None:
            check_number("", "max_map_cells", self.max_map_cells, low=1, integer=True)
        track = self.track
        if not (track is None or isinstance(track, str | os.PathLike) or type(track).__name__ == "Track"):
            raise ValueError(f"track must be a CSV path, 'auto', a Track or None, got {short(track)}")
        if self.noise_profile is not None:
            profile_document(self.noise_profile)  # an unknown name fails here, listing the profiles
        if self.scan_effects is not None:
            object.__setattr__(self, "scan_effects", ScanEffects.from_mapping(self.scan_effects))
        if self.odom_bias is not None and not isinstance(self.odom_bias, OdometryBias):
            if not isinstance(self.odom_bias, Mapping) or set(self.odom_bias) - {"scale", "offset"}:
                raise ValueError(f"odom_bias must be a mapping {{scale, offset}}, got {short(self.odom_bias)}")
            object.__setattr__(self, "odom_bias", OdometryBias(**dict(self.odom_bias)))
        object.__setattr__(self, "imu", ImuParams.from_setting(self.imu))
        check("", "odom_lead", self.odom_lead)  # bounds and their reason: racecar_sim.settings.bounds
        obstacles = scene_obstacles(self.scene, self.obstacles)
        object.__setattr__(self, "obstacles", ObstacleParams.from_setting(obstacles))
        if isinstance(self.car, Mapping):
            object.__setattr__(self, "car", from_mapping(CarParams, dict(self.car)))
        elif not isinstance(self.car, CarParams):
            raise ValueError(f"car must be a CarParams or a mapping, got {short(self.car)}")
        # The env's own names in messages (``lidar_rate``, not ``LidarParams.rate``); bounds and
        # their reasons: racecar_sim.settings.bounds.
        for name in ("n_beams", "dt", "substep", "max_range", "lidar_rate", "short_lambda",
                     "collision_penalty", "start_clearance", "range_sigma", "p_short", "p_max",
                     "p_rand", "fov", "mount_offset"):  # fmt: skip
            check("", name, getattr(self, name))
        if math.ceil(self.dt / self.substep - 1e-9) > MAX_SUBSTEPS:
            raise ValueError(
                f"dt / substep = {self.dt:g} / {self.substep:g} s needs more than {MAX_SUBSTEPS} "
                "physics substeps a step; raise substep or lower dt"
            )
        car = self.car
        if not -car.rear_overhang <= self.mount_offset <= car.length - car.rear_overhang:
            raise ValueError(
                f"mount_offset = {self.mount_offset:g} m puts the lidar off the car: it must lie "
                f"in [{-car.rear_overhang:g}, {car.length - car.rear_overhang:g}] m from the rear "
                "axle (car.length, car.rear_overhang)"
            )
        if not isinstance(self.terminate_on_collision, bool):
            raise ValueError(
                f"terminate_on_collision must be true or false, got {short(self.terminate_on_collision)}"
            )
        # Build the sensor parameters once so that bad values fail here, naming the setting.
        self.lidar_params()
        self.odometry_noise()

    def lidar_params(self) -> LidarParams:
        """The lidar settings as `LidarParams`."""
        try:
            return LidarParams(
                n_beams=self.n_beams,
                fov=self.fov,
                max_range=self.max_range,
                mount_offset=self.mount_offset,
                rate=self.lidar_rate,
                sigma=self.range_sigma,
                p_short=self.p_short,
                short_lambda=self.short_lambda,
                p_max=self.p_max,
                p_rand=self.p_rand,
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"lidar settings (n_beams, fov, max_range, mount_offset, lidar_rate, range_sigma, "
                f"p_short, short_lambda, p_max, p_rand): {exc}"
            ) from exc

    def odometry_noise(self) -> OdometryNoise:
        """The odometry settings as `OdometryNoise`."""
        try:
            return OdometryNoise(
                proportional=tuple(self.odom_proportional),  # type: ignore[arg-type]
                additive=tuple(self.odom_additive),  # type: ignore[arg-type]
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"odometry settings (odom_proportional, odom_additive): {exc}"
            ) from exc


_SETTINGS = frozenset(f.name for f in dataclasses.fields(EnvConfig))


def load_config(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read env settings from a YAML mapping whose keys are `EnvConfig` field names.

    A relative ``map`` path is taken relative to the YAML file when such a file exists there.

    Raises:
        ValueError: the file is missing, not a mapping, or has a key that is not a setting (named).
    """
    path = Path(path)
    data = read_yaml_mapping(path, "env config file")
    unknown = sorted(set(data) - _SETTINGS)
    if unknown:
        raise ValueError(
            f"env config file {path}: unknown setting(s) {short(unknown, 200)}; known: {sorted(_SETTINGS)}"
        )
    spec = data.get("map")
    with contextlib.suppress(OSError):  # a name too long for a path is the map loader's to refuse
        if isinstance(spec, str) and not Path(spec).is_absolute() and (path.parent / spec).is_file():
            data["map"] = str(path.parent / spec)
    return data


def merge_settings(
    config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None,
    overrides: dict[str, Any],
) -> EnvConfig:
    """EnvConfig from defaults < ``config`` (file, mapping or EnvConfig) < keyword ``overrides``."""
    if config is None:
        values: dict[str, Any] = {}
    elif isinstance(config, EnvConfig):
        values = {f.name: getattr(config, f.name) for f in dataclasses.fields(EnvConfig)}
    elif isinstance(config, Mapping):
        values = dict(config)
    else:
        values = load_config(config)
    # A keyword left at None means "not given": the config file or the default applies.
    values.update({k: v for k, v in overrides.items() if v is not None})
    if values.get("noise_profile") is not None:
        from racecar_sim.sensors.noise_profiles import load_profile

        values = {**load_profile(values["noise_profile"]), **values}
    unknown = sorted(set(values) - _SETTINGS)
    if unknown:
        raise ValueError(
            f"unknown RacecarEnv setting(s) {short(unknown, 200)}; known: {sorted(_SETTINGS | {'config'})}"
        )
    return EnvConfig(**values)
