"""Every setting of the simulator: the car, the lidar, the odometry and the env, in SI units.

Frozen dataclasses validated once when built. Every class can be built from a mapping or a YAML file
with :func:`from_mapping` / :func:`from_yaml`; unknown keys raise a ``ValueError`` naming them.
:class:`EnvConfig` gathers the env's keywords (see :class:`racecar_sim.env.RacecarEnv`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from racecar_sim.bounds import BOUNDS, MAX_SUBSTEPS, check
from racecar_sim.imu import ImuParams
from racecar_sim.maps import OccupancyMap
from racecar_sim.noise_profiles import profile_document
from racecar_sim.obstacles import ObstacleParams
from racecar_sim.scan_effects import OdometryBias, ScanEffects
from racecar_sim.scenes import scene_obstacles
from racecar_sim.validation import check_number, read_yaml_mapping, short
from racecar_sim.vehicle import check_car_model

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

T = TypeVar("T")


def from_mapping(cls: type[T], mapping: dict[str, Any] | None) -> T:
    """Build dataclass ``cls`` from a mapping, defaults for missing keys.

    Raises:
        ValueError: a key is not a field of ``cls``, or a value is rejected by its validation.
    """
    mapping = dict(mapping or {})
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(mapping) - names)
    if unknown:
        raise ValueError(f"unknown {cls.__name__} parameter(s) {short(unknown, 200)}; known: {sorted(names)}")
    return cls(**mapping)


def nested(value: Any, cls: type[T], owner: str) -> T:
    """A nested parameter dataclass from an instance of ``cls`` or a mapping of its fields.

    ``owner`` names the field in errors (e.g. ``"ParticleFilterParams.kld"``).

    Raises:
        ValueError: the mapping has an unknown key or a rejected value, or ``value`` is neither.
    """
    if isinstance(value, cls):
        return value
    if isinstance(value, dict) or hasattr(value, "keys"):
        try:
            return from_mapping(cls, dict(value))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{owner}: {exc}") from exc
    raise ValueError(f"{owner} must be a {cls.__name__} or a mapping, got {short(value)}")


def from_yaml(cls: type[T], path: str | os.PathLike[str], section: str | None = None) -> T:
    """Build dataclass ``cls`` from a YAML file (optionally from one top-level ``section``)."""
    path = Path(path)
    data = read_yaml_mapping(path)
    if section is not None:
        data = data.get(section, {}) or {}
    try:
        return from_mapping(cls, data)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"parameter file {path}: {exc}") from exc


def _positive(owner: str, obj: Any, *names: str) -> None:
    for name in names:
        check_number(owner, name, getattr(obj, name), low=0.0, low_open=True)


_F1TENTH_REAR_SHARE = 0.17145 / (0.15875 + 0.17145)  # lr / (lf + lr), f1tenth_gym's parameters


@dataclass(frozen=True)
class CarParams:
    """A 1/10-scale F1TENTH / MIT RSS racecar (kinematic bicycle about the rear axle).

    Attributes:
        wheelbase: metres between the axles.
        max_steer: radians, limit of the front wheel angle (both directions).
        max_steer_rate: radians per second the steering servo can turn.
        max_speed: metres per second forwards.
        max_reverse_speed: metres per second backwards (a positive number).
        max_accel: metres per second squared when speeding up.
        max_decel: metres per second squared when braking.
        length: metres, bumper to bumper.
        width: metres.
        rear_overhang: metres from the rear axle back to the rear bumper.
        mass: kilograms.

    The single-track car (``car_model="single_track"``, :mod:`racecar_sim.vehicle.single_track`)
    also uses the following; their defaults are F1TENTH's as f1tenth_gym gives them
    (``F110Env.f1tenth_vehicle_params`` in ``f1tenth_gym/envs/f110_env.py``, branch dev-dynamics,
    for the CommonRoad single-track model). The fields above keep their values (the kinematic car's are unchanged); for
    the F1TENTH car throughout (wheelbase 0.3302, mass 3.74, ...) use :meth:`f1tenth`.

    Attributes:
        cg_to_rear: metres from the rear axle forwards to the centre of gravity (``lr``; the front
            axle is ``wheelbase - cg_to_rear`` ahead of it, ``lf``); None = F1TENTH's share of the
            wheelbase, ``0.17145 / (0.15875 + 0.17145)`` of it (0.17135 m at 0.33 m).
        cg_height: metres, height of the centre of gravity (``h``, longitudinal load transfer).
        yaw_inertia: kg m², moment of inertia about the vertical axis (``I``).
        friction: tire-road friction coefficient (``mu``).
        cornering_front: front cornering stiffness per unit load, 1/rad (``C_Sf``).
        cornering_rear: rear cornering stiffness per unit load, 1/rad (``C_Sr``).
        v_switch: m/s above which the motor's power limits the acceleration to
            ``max_accel * v_switch / v``.
        kinematic_below: m/s below which the car is the kinematic bicycle.
        dynamic_above: m/s above which it is fully dynamic (blended in between).
    """

    wheelbase: float = 0.33
    max_steer: float = 0.42
    max_steer_rate: float = 3.2
    max_speed: float = 7.0
    max_reverse_speed: float = 2.0
    max_accel: float = 7.5
    max_decel: float = 9.5
    length: float = 0.55
    width: float = 0.30
    rear_overhang: float = 0.11
    mass: float = 3.5
    cg_to_rear: float | None = None
    cg_height: float = 0.074
    yaw_inertia: float = 0.04712
    friction: float = 1.0489
    cornering_front: float = 4.718
    cornering_rear: float = 5.4562
    v_switch: float = 7.319
    kinematic_below: float = 0.5
    dynamic_above: float = 1.0

    @classmethod
    def f1tenth(cls, **overrides: Any) -> CarParams:
        """The F1TENTH car as f1tenth_gym's defaults give it (its ``params``: lf + lr, s_max,
        sv_max, a_max, m, v_max), with ``overrides``; the kinematic car's footprint is kept."""
        values: dict[str, Any] = {
            "wheelbase": 0.15875 + 0.17145, "max_steer": 0.4189, "max_steer_rate": 3.2,
            "max_accel": 9.51, "max_decel": 9.51, "mass": 3.74, "max_speed": 20.0,
            "cg_to_rear": 0.17145,
        }  # fmt: skip
        values.update(overrides)
        return cls(**values)

    def __post_init__(self) -> None:
        # racecar_sim.bounds holds the fields' bounds and their reason
        for f in dataclasses.fields(self):
            if f"car.{f.name}" in BOUNDS and getattr(self, f.name) is not None:
                check("CarParams", f.name, getattr(self, f.name), f"car.{f.name}")
        _positive("CarParams", self, "wheelbase", "max_steer_rate", "max_speed", "max_accel")
        _positive("CarParams", self, "max_decel", "length", "width", "mass")
        _positive("CarParams", self, "cg_height", "yaw_inertia", "friction", "cornering_front")
        _positive("CarParams", self, "cornering_rear", "v_switch", "kinematic_below")
        if self.cg_to_rear is None:
            object.__setattr__(self, "cg_to_rear", self.wheelbase * _F1TENTH_REAR_SHARE)
        check_number("CarParams", "cg_to_rear", self.cg_to_rear, low=0, high=self.wheelbase,
                     low_open=True, high_open=True)  # fmt: skip
        check_number("CarParams", "dynamic_above", self.dynamic_above, low=self.kinematic_below,
                     low_open=True)  # fmt: skip
        check_number("CarParams", "max_steer", self.max_steer, low=0, high=math.pi / 2,
                     low_open=True, high_open=True)  # fmt: skip
        check_number("CarParams", "max_reverse_speed", self.max_reverse_speed, low=0)
        check_number("CarParams", "rear_overhang", self.rear_overhang, low=0, high=self.length,
                     high_open=True)  # fmt: skip


@dataclass(frozen=True)
class LidarParams:
    """A planar scanning lidar (defaults: the MIT RSS racecar's Hokuyo as used in the lab).

    Beams are spread evenly over ``fov`` centred on the car's heading, first beam at ``-fov / 2``
    (right), last at ``+fov / 2`` (left), both ends included.

    Noise follows the four parts of the beam model (Probabilistic Robotics, 6.3), each beam drawing
    one of: a random return (probability ``p_rand``, uniform in [0, max_range]), a max-range drop-out
    (``p_max``, reported as ``max_range``), a short return from an unmapped obstacle (``p_short``, an
    exponential distance with rate ``short_lambda`` truncated to the true range), otherwise the true
    range plus Gaussian noise of ``sigma`` metres. Ranges are clipped to [0, max_range].

    Attributes:
        n_beams: number of beams per scan.
        fov: radians covered by the scan.
        max_range: metres; also the value of a drop-out.
        mount_offset: metres ahead of the rear axle along the car's x axis.
        rate: scans per second; between scans the last scan is repeated.
        sigma: metres, standard deviation of the Gaussian range noise.
        p_short: probability of a short return per beam.
        short_lambda: 1/metres, rate of the exponential short-return distance.
        p_max: probability of a max-range drop-out per beam.
        p_rand: probability of a uniformly random return per beam.
    """

    n_beams: int = 1080
    fov: float = 4.71
    max_range: float = 10.0
    mount_offset: float = 0.275
    rate: float = 40.0
    sigma: float = 0.01
    p_short: float = 0.01
    short_lambda: float = 1.0
    p_max: float = 0.005
    p_rand: float = 0.005

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # bounds and reasons: racecar_sim.bounds
            key = "lidar_rate" if f.name == "rate" else f.name
            check("LidarParams", f.name, getattr(self, f.name), key)
        if self.p_short + self.p_max + self.p_rand > 1:
            raise ValueError("LidarParams: p_short + p_max + p_rand must not exceed 1")

    @property
    def angles(self):  # -> np.ndarray, imported lazily to keep this module light
        """(n_beams,) beam angles in the car frame, radians."""
        import numpy as np

        if self.n_beams == 1:
            return np.zeros(1)
        return np.linspace(-self.fov / 2, self.fov / 2, self.n_beams)


@dataclass(frozen=True)
class OdometryNoise:
    """Noise of the wheel odometry's car-frame twist (vx, vy, omega), like a VESC's /odom.

    Each reported component is ``true * (1 + N(0, proportional**2)) + N(0, additive**2)``.

    Attributes:
        proportional: (vx, vy, omega) standard deviations as a fraction of the true value.
        additive: (vx, vy, omega) standard deviations in m/s, m/s, rad/s.
    """

    proportional: tuple[float, float, float] = (0.02, 0.0, 0.05)
    additive: tuple[float, float, float] = (0.005, 0.0, 0.005)

    def __post_init__(self) -> None:
        for name in ("proportional", "additive"):
            given = getattr(self, name)
            try:
                value = tuple(float(v) for v in given)
            except (TypeError, ValueError):
                value = ()
            if len(value) != 3:
                raise ValueError(f"OdometryNoise.{name} must be three numbers, got {short(given)}")
            for v in value:  # bounds and reasons: racecar_sim.bounds
                check("OdometryNoise", name, v, f"odom_{name}")
            object.__setattr__(self, name, value)


# ---------------------------------------------------------------------- the env's settings
_LIDAR = LidarParams()
_ODOM = OdometryNoise()


@dataclass(frozen=True)
class EnvConfig:
    """Every setting of :class:`RacecarEnv` (SI units), with defaults.

    Attributes:
        map: bundled map name, map YAML path or :class:`OccupancyMap`; None = the default map.
        n_beams: lidar beams per scan.
        fov: radians covered by the scan, centred on the heading.
        max_range: metres, longest lidar range (and the value of a drop-out).
        mount_offset: metres from the rear axle forwards to the lidar.
        lidar_rate: scans per second.
        dt: seconds of control per :meth:`RacecarEnv.step`.
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
        car: the car's geometry and limits, a :class:`CarParams` or a mapping of its fields.
        noise_profile: a named set of these settings (:mod:`racecar_sim.noise_profiles`, e.g.
            ``"mit_racecar"``) applied under the explicit ones; None = none.
        scan_effects: correlated lidar failures replacing the four-part noise
            (:class:`racecar_sim.scan_effects.ScanEffects` or a mapping of its fields); None = off.
        odom_bias: systematic odometry error (:class:`racecar_sim.scan_effects.OdometryBias` or a
            mapping ``{scale, offset}``); None = none.
        obstacles: unmapped boxes and walking people (:class:`racecar_sim.obstacles.ObstacleParams`
            or a mapping of its fields); None = none.
        odom_lead: seconds by which the wheel odometry leads the body's motion (the body gets each
            command this much later, rounded to whole steps; :mod:`racecar_sim.vesc`); 0 = none.
        imu: a yaw-rate gyro in ``obs["imu"]`` (:class:`racecar_sim.vesc.ImuParams`, a mapping
            ``{sigma, bias}`` or True for its defaults); None = no IMU.
        track: the race track for progress, laps, lap times and rank in the info
            (:func:`racecar_sim.race.track.resolve_track`): a centerline CSV in f1tenth's format,
            ``"auto"`` (derived from a loop map) or a ``Track``; None = no track.
        car_model: ``"kinematic"`` (the kinematic bicycle) or ``"single_track"`` (tire slip, a
            friction limit): :mod:`racecar_sim.vehicle`.
        max_map_cells: the most cells (width x height) a map may have; None = the default
            (:func:`racecar_sim.maps.limits.max_map_cells`, 4 million). Checked before the map's
            image is decoded.
        scene: what the room adds to the map (:mod:`racecar_sim.scenes`): ``"clean"`` (openings
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
        check("", "odom_lead", self.odom_lead)  # bounds and their reason: racecar_sim.bounds
        obstacles = scene_obstacles(self.scene, self.obstacles)
        object.__setattr__(self, "obstacles", ObstacleParams.from_setting(obstacles))
        if isinstance(self.car, Mapping):
            object.__setattr__(self, "car", from_mapping(CarParams, dict(self.car)))
        elif not isinstance(self.car, CarParams):
            raise ValueError(f"car must be a CarParams or a mapping, got {short(self.car)}")
        # The env's own names in messages (``lidar_rate``, not ``LidarParams.rate``); bounds and
        # their reasons: racecar_sim.bounds.
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
        """The lidar settings as :class:`LidarParams`."""
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
        """The odometry settings as :class:`OdometryNoise`."""
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
    """Read env settings from a YAML mapping whose keys are :class:`EnvConfig` field names.

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
        from racecar_sim.noise_profiles import load_profile

        values = {**load_profile(values["noise_profile"]), **values}
    unknown = sorted(set(values) - _SETTINGS)
    if unknown:
        raise ValueError(
            f"unknown RacecarEnv setting(s) {short(unknown, 200)}; known: {sorted(_SETTINGS | {'config'})}"
        )
    return EnvConfig(**values)
