"""The car's geometry, limits and tire parameters (`CarParams`), in SI units."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from racecar_sim.settings.bounds import BOUNDS, check
from racecar_sim.settings.params import positive as _positive
from racecar_sim.settings.validation import check_number

__all__ = ["CarParams"]

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

    The single-track car (``car_model="single_track"``, [`racecar_sim.car.models.single_track`][racecar_sim.car.models.single_track])
    also uses the following; their defaults are F1TENTH's as f1tenth_gym gives them
    (``F110Env.f1tenth_vehicle_params`` in ``f1tenth_gym/envs/f110_env.py``, branch dev-dynamics,
    for the CommonRoad single-track model). The fields above keep their values (the kinematic car's are unchanged); for
    the F1TENTH car throughout (wheelbase 0.3302, mass 3.74, ...) use `f1tenth()`.

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
        # racecar_sim.settings.bounds holds the fields' bounds and their reason
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
