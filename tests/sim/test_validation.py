"""Tests of racecar_sim.settings.validation: one checker for numbers and one reader for YAML settings files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from racecar_sim.settings.config import EnvConfig, LidarParams, from_yaml, load_config
from racecar_sim.settings.validation import check_number, read_yaml_mapping


@given(
    low=st.floats(-1e6, 1e6),
    width=st.floats(0.0, 1e6),
    value=st.floats(allow_nan=True, allow_infinity=True),
    low_open=st.booleans(),
    high_open=st.booleans(),
)
@example(low=0.0, width=0.0, value=1e10, low_open=False, high_open=False)  # quoted as 1e+10
def test_a_number_passes_exactly_when_it_is_finite_and_inside_the_interval(
    low: float, width: float, value: float, low_open: bool, high_open: bool
) -> None:
    high = low + width
    inside = (
        math.isfinite(value)
        and (value > low if low_open else value >= low)
        and (value < high if high_open else value <= high)
    )
    try:
        out = check_number("P", "x", value, low=low, high=high, low_open=low_open,
                           high_open=high_open)  # fmt: skip
    except ValueError as exc:
        assert not inside
        message = str(exc)
        assert message.startswith("P.x = ") and " must be " in message
        quoted = message[len("P.x = ") : message.index(" must be ")]
        # the value as given, in its shortest form (1e+10 for 10000000000.0): the same number
        assert float(quoted) == value or (math.isnan(value) and math.isnan(float(quoted)))
    else:
        assert inside and out == value


@pytest.mark.parametrize("value", ["abc", "1.0", None, True, [1.0], math.nan, math.inf])
def test_non_numbers_are_refused_with_the_field_and_the_value(value: object) -> None:
    with pytest.raises(ValueError, match=r"^Owner\.field = .* must be a positive number$"):
        check_number("Owner", "field", value, low=0, low_open=True)


def test_integers_must_be_whole() -> None:
    assert check_number("P", "n", 3, low=1, integer=True) == 3
    with pytest.raises(ValueError, match=r"P\.n = 2\.5 must be an integer >= 1"):
        check_number("P", "n", 2.5, low=1, integer=True)


def test_env_settings_name_the_env_keyword_not_the_inner_class() -> None:
    with pytest.raises(ValueError, match=r"^lidar_rate = 'abc' must be a number in \[0.1, 1000\] Hz$"):
        EnvConfig(lidar_rate="abc")
    with pytest.raises(ValueError, match=r"^n_beams = 0 must be an integer in \[1, 10000\] beams$"):
        EnvConfig(n_beams=0)
    with pytest.raises(ValueError, match=r"^LidarParams.p_max = 2.0 must be a number in \[0, 1\]$"):
        LidarParams(p_max=2.0)


def test_yaml_files_are_read_by_one_reader_that_names_the_file(tmp_path: Path) -> None:
    good = tmp_path / "lidar.yaml"
    good.write_text("lidar:\n  n_beams: 91\n  max_range: 12.5\n")
    assert from_yaml(LidarParams, good, section="lidar") == LidarParams(n_beams=91, max_range=12.5)
    assert read_yaml_mapping(good)["lidar"]["n_beams"] == 91
    (tmp_path / "empty.yaml").write_text("")
    assert read_yaml_mapping(tmp_path / "empty.yaml") == {}
    listing = tmp_path / "list.yaml"
    listing.write_text("- 1\n- 2\n")
    broken = tmp_path / "broken.yaml"
    broken.write_text("a: [1, 2\n")
    for path, problem in ((listing, "expected a mapping"), (broken, "not valid YAML"),
                          (tmp_path / "missing.yaml", "not found")):  # fmt: skip
        with pytest.raises(ValueError, match=problem) as info:
            load_config(path)
        assert str(path) in str(info.value) and "\n" not in str(info.value)
        with pytest.raises(ValueError, match=problem):
            from_yaml(LidarParams, path)


def test_a_masked_array_is_refused_as_an_action_even_with_nothing_masked() -> None:
    from racecar_sim.settings.validation import check_action

    for masked in (np.ma.array([0.1, 1.0], mask=[True, False]), np.ma.array([0.1, 1.0])):
        with pytest.raises(ValueError, match="masked float64 array"):
            check_action(masked, (2,))
    np.testing.assert_array_equal(check_action(np.array([0.1, 1.0]), (2,)), [0.1, 1.0])


@pytest.mark.parametrize("options", [[1, 2], "pose", 3, (("pose", 1),), {1: 2}])
def test_reset_options_that_are_not_a_dict_of_names_are_refused_naming_the_owner(options) -> None:
    from racecar_sim.settings.validation import check_options

    with pytest.raises(ValueError, match=r"^Owner.reset: options"):
        check_options("Owner.reset", options)


def test_reset_options_none_or_a_mapping_become_a_new_dict() -> None:
    from types import MappingProxyType

    from racecar_sim.settings.validation import check_options

    given = {"pose": [1, 2, 3]}
    out = check_options("x", given)
    assert out == given and out is not given
    assert check_options("x", None) == {}
    assert check_options("x", MappingProxyType(given)) == given


@pytest.mark.parametrize(
    ("value", "said"),
    [({"x": 1}, "dict"), ("abc", "str"), ([1.0, 2.0], r"shape \(2,\)"), ([True, 1.0, 0.0], "list"),
     ([1.0, math.nan, 0.0], "nan"), (np.ma.array([1.0, 2.0, 3.0]), "masked"),
     (np.array(["1", "2", "3"]), "<U1")],
)  # fmt: skip
def test_a_pose_that_is_not_three_finite_numbers_is_refused_naming_it(value, said) -> None:
    from racecar_sim.settings.validation import check_poses

    with pytest.raises(ValueError, match=rf"^init_pose must be three finite numbers.*{said}"):
        check_poses("init_pose", value)


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=2, max_size=4),
       st.sampled_from([None, 1]))  # fmt: skip
def test_poses_pass_exactly_when_they_are_finite_of_the_shape(values, rows) -> None:
    from racecar_sim.settings.validation import check_poses

    value = values if rows is None else [values]
    shape_ok = len(values) == 3
    if shape_ok and all(math.isfinite(v) for v in values):
        np.testing.assert_array_equal(check_poses("p", value, rows), np.array(value))
    else:
        with pytest.raises(ValueError, match=r"^p must be"):
            check_poses("p", value, rows)


def test_a_list_holding_a_masked_value_is_refused_as_an_action() -> None:
    from racecar_sim.settings.validation import check_action

    with pytest.raises(ValueError, match=r"got list \[masked, 1.0\]"):
        check_action([np.ma.masked, 1.0], (2,))
    rows = [np.ma.array([0.1, 1.0], mask=[False, True])] * 2
    with pytest.raises(ValueError, match="must be numbers of shape") as info:
        check_action(rows, (2, 2))
    assert "\n" not in str(info.value)  # the masked array's repr is put on one line


@pytest.mark.parametrize("seed", [-1, 2.5, "1", True, np.bool_(True), [1]])
def test_a_seed_that_is_not_a_non_negative_int_is_refused_naming_the_owner(seed) -> None:
    from racecar_sim.settings.validation import check_seed

    with pytest.raises(ValueError, match=r"^Owner.reset: seed must be a non-negative int or None"):
        check_seed("Owner.reset", seed)


def test_a_seed_that_is_a_non_negative_int_or_none_passes() -> None:
    from racecar_sim.settings.validation import check_seed

    assert check_seed("x", None) is None
    assert check_seed("x", np.int64(3)) == 3 and check_seed("x", 2**70) == 2**70
