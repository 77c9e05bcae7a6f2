"""The physical bounds of every number setting, with the reason for each: one table that the
parameter dataclasses check against (`check()`) and docs/settings.md shows.

A bound keeps a setting where the simulator's work stays bounded (no setting makes a step, a scan
or a reset take minutes or gigabytes) and where its physics still means something. Settings that
depend on each other (``dt`` and ``substep``, ``mount_offset`` and the car) are checked together
by the dataclass that holds both; those rules are in `RULES`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from racecar_sim.settings.validation import check_number

__all__ = ["BOUNDS", "MAX_SUBSTEPS", "RULES", "Bound", "check", "markdown_table"]


@dataclass(frozen=True)
class Bound:
    """An interval for a number setting (``low_open`` / ``high_open`` exclude the ends;
    ``allow_inf``: an infinite end is a value too, e.g. "never")."""

    low: float
    high: float
    unit: str
    reason: str
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    allow_inf: bool = False

    def text(self) -> str:
        """The interval as ``[a, b]`` / ``(a, b)`` text."""
        lo = "(" if self.low_open else "["
        hi = ")" if self.high_open else "]"
        return f"{lo}{_g(self.low)}, {_g(self.high)}{hi}"


def _g(value: float) -> str:
    if value == math.pi / 2:
        return "pi/2"
    if value == 2 * math.pi:
        return "2 pi"
    return f"{value:g}"


MAX_SUBSTEPS = 1000
"""Most physics substeps in one env step (``ceil(dt / substep)``)."""

_PROB = "a probability"
BOUNDS: dict[str, Bound] = {
    # the env's clock
    "dt": Bound(1e-3, 1.0, "s", "1 kHz control is faster than any racecar's loop; at 1 s a car at "
                "top speed moves 7 m between commands"),
    "substep": Bound(1e-4, 0.1, "s", "below 0.1 ms pymunk's work per step explodes; above 0.1 s a "
                     "car at 7 m/s crosses 14 cells of 5 cm and passes walls"),
    "lidar_rate": Bound(0.1, 1000.0, "Hz", "planar lidars turn at 5-50 Hz; below 0.1 Hz a drive "
                        "never scans, above 1 kHz nothing is gained (at most one scan per step)"),
    # the lidar
    "n_beams": Bound(1, 10_000, "beams", "real planar lidars have 360-3600 beams; each beam costs "
                     "every scan and every particle", integer=True),
    "fov": Bound(0.0, 2 * math.pi, "rad", "a scan covers at most a full turn", low_open=True),
    "max_range": Bound(0.0, 1000.0, "m", "longer than any planar lidar (Hokuyo 30 m, SICK 80 m)",
                       low_open=True),
    "mount_offset": Bound(-5.0, 5.0, "m", "on the car: the env checks it lies within the car's "
                          "length, from the rear bumper to the front one"),
    "range_sigma": Bound(0.0, 100.0, "m", "range noise beyond 100 m leaves no scan"),
    "sigma": Bound(0.0, 100.0, "m", "range noise beyond 100 m leaves no scan"),
    "short_lambda": Bound(0.0, 1000.0, "1/m", "an exponential scale of a millimetre is already a "
                          "return at the lidar", low_open=True),
    "p_short": Bound(0.0, 1.0, "", _PROB),
    "p_max": Bound(0.0, 1.0, "", _PROB),
    "p_rand": Bound(0.0, 1.0, "", _PROB),
    # the env
    "collision_penalty": Bound(0.0, 1e9, "reward", "finite and not negative"),
    "start_clearance": Bound(0.0, 10.0, "m", "more room than a race track's width; the env also "
                             "refuses a clearance the map cannot give"),
    "odom_proportional": Bound(0.0, 1.0, "fraction", "noise of 100 % of the true speed"),
    "odom_additive": Bound(0.0, 10.0, "m/s, rad/s", "noise of 10 m/s is more than the top speed"),
    "max_map_cells": Bound(1, 1e10, "cells", "see the map limits", integer=True),
    "odom_lead": Bound(0.0, 1.0, "s", "a VESC's odometry leads by about 0.13 s; each step of lead "
                       "is a command held in a queue"),
    "imu.sigma": Bound(0.0, 10.0, "rad/s", "noise beyond the car's fastest turn"),
    "imu.bias": Bound(-10.0, 10.0, "rad/s", "a bias beyond the car's fastest turn"),
    # the car
    "car.wheelbase": Bound(0.05, 10.0, "m", "from a 1/18 model car to a bus"),
    "car.max_steer": Bound(0.0, math.pi / 2, "rad", "a wheel turned 90 degrees is not steering",
                           low_open=True, high_open=True),
    "car.max_steer_rate": Bound(0.0, 100.0, "rad/s", "a servo is at most ~10 rad/s",
                                low_open=True),
    "car.max_speed": Bound(0.0, 100.0, "m/s", "360 km/h; faster crosses many cells per substep",
                           low_open=True),
    "car.max_reverse_speed": Bound(0.0, 100.0, "m/s", "as max_speed"),
    "car.max_accel": Bound(0.0, 100.0, "m/s^2", "10 g", low_open=True),
    "car.max_decel": Bound(0.0, 100.0, "m/s^2", "10 g", low_open=True),
    "car.length": Bound(0.05, 20.0, "m", "from a 1/18 model car to a truck"),
    "car.width": Bound(0.05, 5.0, "m", "from a 1/18 model car to a truck"),
    "car.rear_overhang": Bound(0.0, 20.0, "m", "behind the rear axle, less than the length"),
    "car.mass": Bound(0.0, 1e5, "kg", "up to a loaded truck", low_open=True),
    "car.cg_to_rear": Bound(0.0, 10.0, "m", "between the axles (also checked against wheelbase)",
                            low_open=True),
    "car.cg_height": Bound(0.0, 5.0, "m", "a bus's centre of gravity is below 2 m", low_open=True),
    "car.yaw_inertia": Bound(0.0, 1e6, "kg m^2", "up to a loaded truck", low_open=True),
    "car.friction": Bound(0.0, 5.0, "", "racing slicks reach about 2", low_open=True),
    "car.cornering_front": Bound(0.0, 1000.0, "1/rad", "per unit load; tires are near 5",
                                 low_open=True),
    "car.cornering_rear": Bound(0.0, 1000.0, "1/rad", "per unit load; tires are near 5",
                                low_open=True),
    "car.v_switch": Bound(0.0, 100.0, "m/s", "as max_speed", low_open=True),
    "car.kinematic_below": Bound(0.0, 100.0, "m/s", "as max_speed", low_open=True),
    "car.dynamic_above": Bound(0.0, 100.0, "m/s", "as max_speed (and above kinematic_below)",
                               low_open=True),
    # unmapped obstacles
    "obstacles.boxes": Bound(0, 500, "boxes", "each box is tried for and cast against every beam "
                             "of every scan", integer=True),
    "obstacles.people": Bound(0, 100, "people", "each person walks every step and is cast against "
                              "every beam", integer=True),
    "obstacles.box_size": Bound(0.0, 10.0, "m", "a box larger than a room blocks the map",
                                low_open=True),
    "obstacles.person_speed": Bound(0.0, 10.0, "m/s", "faster than a sprinter"),
    "obstacles.person_radius": Bound(0.0, 2.0, "m", "wider than any person", low_open=True),
    "obstacles.leg_radius": Bound(0.0, 1.0, "m", "thicker than any leg", low_open=True),
    "obstacles.stop_distance": Bound(0.0, 100.0, "m", "beyond the lidar's usual range"),
    "obstacles.keep_out": Bound(0.0, 100.0, "m", "beyond the lidar's usual range"),
}
"""Setting name (``car.``, ``obstacles.`` for nested ones) -> its bound."""

RULES: tuple[tuple[str, str], ...] = (
    ("ceil(dt / substep) <= 1000", "a step runs at most 1000 physics substeps"),
    ("-rear_overhang <= mount_offset <= length - rear_overhang",
     "the lidar sits on the car (rear axle frame)"),
    ("p_short + p_max + p_rand <= 1", "probabilities of one beam's outcomes"),
    ("rear_overhang < length", "the rear axle lies on the car"),
    ("box_size: smallest <= largest", "an interval"),
    ("scans per step: min(lidar_rate * dt, 1)", "a step takes at most one scan; a faster lidar "
     "scans every step"),
)
"""Bounds between settings: (rule, reason)."""


def check(
    owner: str,
    name: str,
    value: Any,
    key: str | None = None,
    table: dict[str, Bound] | None = None,
) -> float | int:
    """``value`` checked against ``table[key or name]`` (default table `BOUNDS`); the
    message names ``owner.name`` and the bound's unit.

    Raises:
        ValueError: one line, ``"owner.name = value must be a number in [low, high] unit"``.
    """
    b = (BOUNDS if table is None else table)[key or name]
    return check_number(
        owner,
        name,
        value,
        low=b.low,
        high=b.high,
        low_open=b.low_open,
        high_open=b.high_open,
        integer=b.integer,
        allow_inf=b.allow_inf,
        unit=b.unit,
    )


def markdown_table(table: dict[str, Bound] | None = None) -> str:
    """The bounds as a Markdown table (setting, interval, unit, reason)."""
    rows = ["| setting | bounds | unit | reason |", "|---|---|---|---|"]
    for name, b in (BOUNDS if table is None else table).items():
        rows.append(f"| `{name}` | {b.text()} | {b.unit} | {b.reason} |")
    return "\n".join(rows)
