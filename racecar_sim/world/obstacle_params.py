"""The obstacles' settings ([`ObstacleParams`][racecar_sim.world.obstacle_params.ObstacleParams]):
how many boxes and people, their sizes and pace, and the openings and furniture along the walls.
The obstacles themselves are [`racecar_sim.world.obstacles`][racecar_sim.world.obstacles]."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from racecar_sim.settings.bounds import check
from racecar_sim.settings.validation import check_number, short

__all__ = ["ObstacleParams"]


@dataclass(frozen=True)
class ObstacleParams:
    """How many obstacles and what they are like (metres, seconds).

    Attributes:
        boxes: number of static boxes.
        box_size: (smallest, largest) side length of a box.
        people: number of walking people.
        person_speed: walking speed, m/s.
        person_radius: radius of a person's body for collisions.
        leg_radius: radius of a leg as the lidar sees it.
        stop_distance: a person stops while the car's rear axle is closer than this.
        keep_out: nothing is placed closer than this to the car's start.
        crowd: more people, this many per 100 m² of the map's free floor (added to ``people``).
        furniture: fraction of the map's wall length lined with furniture (boxes with their back
            against a wall, `racecar_sim.world.wall_features`).
        furniture_width: (smallest, largest) width along the wall, metres.
        furniture_depth: (smallest, largest) depth out of the wall, metres.
        openings: fraction of the wall length that is glass or an open door: the lidar sees
            through it to a surface behind the mapped wall.
        opening_width: (smallest, largest) width of an opening, metres.
        opening_depth: metres, mean depth behind the wall (beyond 0.15 m) of what an opening shows.
    """

    boxes: int = 0
    box_size: tuple[float, float] = (0.3, 0.8)
    people: int = 0
    person_speed: float = 1.2
    person_radius: float = 0.25
    leg_radius: float = 0.07
    stop_distance: float = 1.2
    keep_out: float = 2.0
    crowd: float = 0.0
    furniture: float = 0.0
    furniture_width: tuple[float, float] = (0.4, 1.6)
    furniture_depth: tuple[float, float] = (0.3, 0.8)
    openings: float = 0.0
    opening_width: tuple[float, float] = (0.6, 1.6)
    opening_depth: float = 0.5

    def __post_init__(self) -> None:
        name = "obstacles"  # bounds and their reasons: racecar_sim.settings.bounds
        for f in ("boxes", "people", "person_speed", "person_radius", "leg_radius",
                  "stop_distance", "keep_out"):  # fmt: skip
            check(name, f, getattr(self, f), f"obstacles.{f}")
        try:
            size = tuple(float(v) for v in self.box_size)
        except (TypeError, ValueError):
            size = ()
        if len(size) != 2 or not size[0] <= size[1]:
            raise ValueError(
                f"obstacles.box_size must be (smallest, largest) metres, got {short(self.box_size)}"
            )
        for v in size:
            check(name, "box_size", v, "obstacles.box_size")
        object.__setattr__(self, "box_size", size)
        for f in ("furniture_width", "furniture_depth", "opening_width"):
            try:
                pair = tuple(float(v) for v in getattr(self, f))
            except (TypeError, ValueError):
                pair = ()
            if len(pair) != 2 or not (0 < pair[0] <= pair[1] <= 10):
                raise ValueError(
                    f"obstacles.{f} must be (smallest, largest) metres in (0, 10], "
                    f"got {short(getattr(self, f))}"
                )
            object.__setattr__(self, f, pair)
        check_number(name, "crowd", self.crowd, low=0, high=100)
        for f in ("furniture", "openings"):
            check_number(name, f, getattr(self, f), low=0, high=1)
        check_number(name, "opening_depth", self.opening_depth, low=0, high=30, low_open=True)

    @property
    def active(self) -> bool:
        """Whether these settings put anything into the world."""
        return bool(self.boxes or self.people or self.crowd or self.furniture or self.openings)

    @classmethod
    def from_setting(cls, value: Any) -> ObstacleParams | None:
        """From the env's ``obstacles`` setting: None, an ObstacleParams or a mapping of fields."""
        if value is None or isinstance(value, ObstacleParams):
            return value
        if isinstance(value, Mapping):
            known = set(cls.__dataclass_fields__)
            unknown = sorted(set(value) - known)
            if unknown:
                raise ValueError(f"unknown obstacles setting(s) {short(unknown, 200)}; known: {sorted(known)}")
            return cls(**dict(value))
        raise ValueError(f"obstacles must be a mapping of {sorted(cls.__dataclass_fields__)}")
