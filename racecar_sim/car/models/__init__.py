"""Car models: one module per model, each a numba function over the car's state array.

``car_model`` picks one by name (`CAR_MODELS`):

* ``"kinematic"`` ([`kinematic`][racecar_sim.car.models.kinematic], the default): the kinematic bicycle
  about the rear axle; the car goes where its wheels point, at any speed.
* ``"single_track"`` ([`single_track`][racecar_sim.car.models.single_track]): the single-track model with tire
  slip, yaw rate and body slip angle as states, and tires that saturate at the friction limit.

Both share the actuators (steering rate, acceleration and braking limits) and the state layout of
[`racecar_sim.car.free_steps.STATE_FIELDS`][racecar_sim.car.free_steps.STATE_FIELDS]; [`racecar_sim.car.free_steps.advance()`][racecar_sim.car.free_steps.advance] steps either
in free space, and [`racecar_sim.car.physics.RacecarPhysics`][racecar_sim.car.physics.RacecarPhysics] among walls.
"""

from __future__ import annotations

from racecar_sim.car.models import single_track

__all__ = ["CAR_MODELS", "MODEL_INDEX", "check_car_model", "model_params"]

CAR_MODELS = ("kinematic", "single_track")
"""The car models by name."""

MODEL_INDEX = {name: i for i, name in enumerate(CAR_MODELS)}
"""A model's number in the free-step constants array."""


def check_car_model(name: object, owner: str = "car_model") -> str:
    """``name`` if it names a car model, else ``ValueError`` naming ``owner`` and the models."""
    if name not in MODEL_INDEX:
        raise ValueError(f"{owner} must be one of {list(CAR_MODELS)}, got {name!r}")
    return str(name)


def model_params(car, car_model: str) -> list[float]:
    """The model's parameters from a [`CarParams`][racecar_sim.settings.config.CarParams] (the kinematic car's
    are the actuator limits already in the constants: none)."""
    check_car_model(car_model)
    if car_model == "single_track":
        return single_track.params_array(car).tolist()
    return []
