"""Tests of racecar_sim.validation: one checker for numbers and one reader for YAML settings files."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from racecar_sim.config import EnvConfig, LidarParams, from_yaml, load_config
from racecar_sim.validation import check_number, read_yaml_mapping


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
    with pytest.raises(ValueError, match=r"^lidar_rate = 'abc' must be a number in \[0.1, 1000\]$"):
        EnvConfig(lidar_rate="abc")
    with pytest.raises(ValueError, match=r"^n_beams = 0 must be an integer in \[1, 10000\]$"):
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
