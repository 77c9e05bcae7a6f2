"""SensorModelParams.lut_sort_extent: from YAML to the caster, checked, and the same weights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.filter.sensor_model import SensorModel, SensorModelParams
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.sensors.lidar import Lidar
from racecar_sim.settings.config import from_yaml


def test_yaml_sets_the_casters_sort_extent(tmp_path, room) -> None:
    path = tmp_path / "mcl.yaml"
    path.write_text("localization:\n  sensor: {lut_sort_extent: .inf}\n")
    config = from_yaml(LocalizationConfig, path, section="localization")
    assert config.sensor.lut_sort_extent == math.inf
    sm = SensorModel(room, config.sensor)
    assert sm.caster is not None and sm.caster.lut_params.sort_extent == math.inf
    path.write_text("localization:\n  sensor: {lut_sort_extent: 2.5}\n")
    config = from_yaml(LocalizationConfig, path, section="localization")
    assert SensorModel(room, config.sensor).caster.lut_params.sort_extent == 2.5
    assert SensorModel(room).caster.lut_params.sort_extent == 10.0  # the default


@pytest.mark.parametrize("bad", [-1.0, math.nan, "wide", True, None])
def test_a_bad_extent_is_one_line_naming_the_setting(bad) -> None:
    with pytest.raises(
        ValueError, match=r"^SensorModelParams\.lut_sort_extent = .* must be a number >= 0 m$"
    ):
        SensorModelParams(lut_sort_extent=bad)


def test_sorted_and_unsorted_models_give_the_same_log_likelihoods(room) -> None:
    # 0.5 m: the room's global cloud is sorted; inf: never
    poses = room.sample_free_poses(np.random.default_rng(3), 2000)
    scan = Lidar(room).measure(np.array([6.0, 0.0, 0.4]), np.random.default_rng(5))
    sorted_, plain = (
        SensorModel(room, SensorModelParams(lut_sort_extent=e, parallel=False))
        for e in (0.5, math.inf)
    )
    got = sorted_.log_evaluate(poses, scan)
    assert np.array_equal(got, plain.log_evaluate(poses, scan))
    assert np.ptp(got) > 1.0  # the poses are told apart
