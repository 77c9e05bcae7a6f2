"""Parameter dataclasses: defaults, validation, YAML loading."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from racecar_sim.settings.config import (
    CarParams,
    LidarParams,
    OdometryNoise,
    from_mapping,
    from_yaml,
)


def test_car_defaults_are_a_tenth_scale_racecar() -> None:
    car = CarParams()
    assert 0.3 <= car.wheelbase <= 0.36
    assert 0.35 <= car.max_steer <= 0.45
    assert car.rear_overhang < car.length


def test_lidar_angles_span_the_field_of_view_symmetrically() -> None:
    lidar = LidarParams(n_beams=1081, fov=4.71)
    a = lidar.angles
    assert a.shape == (1081,)
    assert a[0] == pytest.approx(-2.355) and a[-1] == pytest.approx(2.355)
    assert a[540] == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.diff(a) > 0)


@pytest.mark.parametrize(
    ("cls", "kwargs", "name"),
    [
        (CarParams, {"wheelbase": 0.0}, "wheelbase"),
        (CarParams, {"max_steer": 2.0}, "max_steer"),
        (CarParams, {"mass": math.nan}, "mass"),
        (LidarParams, {"n_beams": 0}, "n_beams"),
        (LidarParams, {"p_max": 1.5}, "p_max"),
        (LidarParams, {"sigma": -0.1}, "sigma"),
        (LidarParams, {"p_short": 0.5, "p_max": 0.4, "p_rand": 0.2}, "p_short"),
        (OdometryNoise, {"additive": (0.1, -1.0, 0.0)}, "additive"),
    ],
)
def test_invalid_values_raise_naming_the_field(cls: type, kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        cls(**kwargs)


def test_from_mapping_rejects_unknown_keys_by_name() -> None:
    with pytest.raises(ValueError, match="wheel_base"):
        from_mapping(CarParams, {"wheel_base": 0.3})
    assert from_mapping(CarParams, {"wheelbase": 0.3}).wheelbase == 0.3


def test_from_yaml_reads_a_section(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("lidar:\n  n_beams: 100\n  max_range: 30.0\ncar:\n  mass: 4.0\n")
    assert from_yaml(LidarParams, path, section="lidar") == LidarParams(n_beams=100, max_range=30.0)
    assert from_yaml(CarParams, path, section="car").mass == 4.0
    with pytest.raises(ValueError, match="not found"):
        from_yaml(CarParams, tmp_path / "nope.yaml")


def test_nested_takes_an_instance_or_a_mapping_and_names_the_owner() -> None:
    from racecar_sim.settings.config import nested

    car = CarParams(mass=4.0)
    assert nested(car, CarParams, "Outer.car") is car
    assert nested({"mass": 5.0}, CarParams, "Outer.car") == CarParams(mass=5.0)
    with pytest.raises(ValueError, match=r"Outer\.car: unknown CarParams parameter"):
        nested({"masss": 5.0}, CarParams, "Outer.car")
    with pytest.raises(ValueError, match=r"Outer\.car must be a CarParams or a mapping"):
        nested(3, CarParams, "Outer.car")
