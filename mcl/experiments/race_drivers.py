"""Who drives each car of a race: driver names, and the one factory that builds a driver for a car.

Names (``racecar-sim race --drivers``):

- ``racing``: the racing driver that knows the other cars
  ([RacingDriver][racecar_sim.race.racing_driver.RacingDriver]: it follows a slower car at a safe
  gap, passes where the track is wide enough and gives way to a faster car behind). It reads where
  every car is from the race's [Traffic][racecar_sim.race.traffic.Traffic] picture (the cars' true
  poses, as an opponent sees them, put on the track once per step by the race) and steers on the
  pose it is given (the truth, or the car's MCL estimate);
- ``wall``: the lidar wall follower on the car's own scan
  (``WallFollower.for_env(race.cars[i], speed=v)``); it sees the other cars as lidar hits, so it
  slows for a car in its path, but it does not plan round one;
- ``pursuit``: pure pursuit on the track's centerline at a constant speed, on the pose it is given
  (the truth, or the car's MCL estimate); blind to the other cars;
- ``policy:FILE``: a lap policy trained by ``racecar-sim train-agent`` (its ``model.zip``; extra
  ``[rl]``), on the pose it is given ([PolicyDriver][mcl.agents.policy_driver.PolicyDriver]).

Every driver is called as ``driver(obs, pose) -> [steer rad, speed m/s]`` and may have a
``reset()``; [`make_driver`][mcl.experiments.race_drivers.make_driver] is the only place that builds
them, so a new kind of driver joins every race through it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from racecar_sim.drivers import Driver, PurePursuit, WallFollower

if TYPE_CHECKING:
    from racecar_sim.race.traffic import Traffic

__all__ = [
    "DRIVER_NAMES",
    "DriverError",
    "DriverSpec",
    "drive_pose",
    "knows_the_others",
    "make_driver",
    "parse_drivers",
]

DRIVER_NAMES: Mapping[str, str] = {
    "racing": "knows the other cars: follows, passes where the track is wide enough, gives way",
    "wall": "the lidar wall follower (sees the other cars as lidar hits)",
    "pursuit": "pure pursuit on the track's centerline (blind to the other cars)",
    "policy:FILE": "a policy trained by racecar-sim train-agent (its model.zip; extra [rl])",
}
"""Driver names and what each is."""


class DriverError(ValueError):
    """A driver that cannot be built: a policy file that is missing or not a lap policy, or a
    policy without stable-baselines3 (the message says which)."""


@dataclass(frozen=True)
class DriverSpec:
    """One car's driver: ``kind`` is ``"racing"``, ``"wall"``, ``"pursuit"`` or ``"policy"`` (then
    ``path`` is its model file)."""

    kind: str
    path: Path | None = None

    @property
    def name(self) -> str:
        """The name as given on the command line (a policy by its folder: ``policy:truth``)."""
        if self.path is None:
            return self.kind
        return f"policy:{self.path.parent.name or self.path.name}"


def parse_drivers(text: str, n_cars: int) -> tuple[DriverSpec, ...]:
    """``n_cars`` drivers from comma-separated names (one name: every car).

    Raises:
        ValueError: an unknown name, a ``policy:`` without a file, or a count that is neither
            one nor ``n_cars``.
    """
    specs = []
    for item in (part.strip() for part in text.split(",")):
        kind, sep, rest = item.partition(":")
        if kind == "policy" and sep:
            if not rest.strip():
                raise ValueError("policy: needs its file, e.g. policy:runs/agent/truth/model.zip")
            specs.append(DriverSpec("policy", Path(rest.strip())))
        elif item in ("racing", "wall", "pursuit"):
            specs.append(DriverSpec(item))
        else:
            raise ValueError(f"unknown driver {item!r}; drivers: {', '.join(DRIVER_NAMES)}")
    if len(specs) == 1:
        specs *= n_cars
    if len(specs) != n_cars:
        raise ValueError(f"{len(specs)} drivers for {n_cars} cars: give one, or one per car")
    return tuple(specs)


def knows_the_others(specs: tuple[DriverSpec, ...]) -> bool:
    """Whether any of ``specs`` reads the race's traffic picture (a ``racing`` driver)."""
    return any(spec.kind == "racing" for spec in specs)


def make_driver(
    spec: DriverSpec, race: Any, car: int, speed: float, traffic: Traffic | None = None
) -> Driver:
    """The driver of car ``car`` of ``race`` (a
    [`racecar_sim.RaceEnv`][racecar_sim.race.env.RaceEnv] with a track) at ``speed`` m/s;
    a ``racing`` driver reads ``traffic``, which the race resets after its reset and updates
    after every step.

    Raises:
        DriverError: a policy file that is missing or not a lap policy, or a policy without
            stable-baselines3 (extra ``[rl]``).
        ValueError: a ``racing`` driver without ``traffic``.
    """
    if spec.kind == "racing":
        if traffic is None:
            raise ValueError("a racing driver needs the race's Traffic")
        from racecar_sim.race.racing_driver import RacingDriver

        return RacingDriver(traffic, car, speed=speed)
    if spec.kind == "wall":
        return WallFollower.for_env(race.cars[car], speed=speed)
    if spec.kind == "pursuit":
        return PurePursuit(race.track.points, speed=speed, loop=True, car=race.car_params)
    if spec.kind == "policy" and spec.path is not None:
        from mcl.agents.policy_driver import load_policy_driver

        try:
            return load_policy_driver(spec.path, race.cars[car], race.track, speed)
        except (ImportError, OSError, ValueError) as exc:
            raise DriverError(f"{spec.name} ({spec.path}): {exc}") from None
    raise ValueError(f"no driver {spec!r}")


def drive_pose(obs: Mapping[str, Any], info: Mapping[str, Any], localized: bool) -> np.ndarray:
    """The pose a car drives on: its MCL estimate in a localized race, else the true pose."""
    return np.asarray(obs["pose_estimate"] if localized else info["pose"], dtype=np.float64)
