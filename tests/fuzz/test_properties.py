"""Properties of the readers every input goes through: YAML numbers and step actions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from racecar_sim.settings.validation import check_action, load_yaml, short


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_every_float_reads_back_in_every_way_it_is_written(x: float) -> None:
    for text in (repr(x), f"{x:e}", f"{x:E}", f"{x:.17g}"):
        value = load_yaml(f"v: {text}")["v"]
        assert isinstance(value, int | float) and not isinstance(value, bool), text
        assert value == float(text), text


@given(st.one_of(st.text(max_size=300), st.lists(st.integers(), max_size=400), st.floats()))
def test_short_is_short_and_one_line_for_reprs_of_one_line(value) -> None:
    out = short(value)
    assert len(out) <= 40
    if "\n" not in repr(value):
        assert "\n" not in out


_DTYPES = st.sampled_from(["float64", "float32", "int64", "int8", "uint16", "bool", "complex64",
                           "U3", "S3", "object"])  # fmt: skip


@given(
    hnp.arrays(
        dtype=_DTYPES,
        shape=st.sampled_from([(2,), (1,), (3,), (2, 1), (1, 2), ()]),
        elements=None,
    )
)
def test_an_array_action_is_taken_exactly_when_numeric_of_shape_two_and_finite(arr) -> None:
    numeric = arr.dtype.kind in "fiu"
    finite = numeric and bool(np.isfinite(arr.astype(np.float64)).all())
    if numeric and arr.shape == (2,) and finite:
        out = check_action(arr, (2,))
        assert out.dtype == np.float64 and np.array_equal(out, arr.astype(np.float64))
    else:
        with pytest.raises(ValueError, match="action must be"):
            check_action(arr, (2,))


@given(st.lists(st.one_of(st.floats(), st.integers(-(10**6), 10**6), st.booleans(), st.text()),
                max_size=3))  # fmt: skip
def test_a_list_action_is_taken_exactly_when_two_finite_ints_or_floats(values) -> None:
    ok = (
        len(values) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
        and all(math.isfinite(v) for v in values)
    )
    if ok:
        assert check_action(values, (2,)).tolist() == [float(v) for v in values]
    else:
        with pytest.raises(ValueError, match="action must be"):
            check_action(values, (2,))
