"""The software prefetch intrinsic: it compiles to a prefetch and changes no result."""

from __future__ import annotations

import platform

import numba as nb
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numba.core.errors import TypingError

from racecar_sim.raycast.prefetch import prefetch


@nb.njit
def _sum_prefetching(a, ahead):
    flat = a.reshape(-1)
    s = 0.0
    for i in range(flat.shape[0]):
        prefetch(a, i + ahead)  # past the end too: a prefetch never faults
        s += flat[i]
    return s


@given(
    st.integers(1, 300),
    st.integers(1, 5),
    st.integers(-64, 4096),
    st.sampled_from([np.float64, np.uint16, np.int32]),
)
def test_a_sum_with_prefetches_is_the_plain_sum(n, m, ahead, dtype) -> None:
    a = (np.arange(n * m) % 97).astype(dtype).reshape(n, m)
    assert _sum_prefetching(a, ahead) == float(a.sum())


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 instruction name")
def test_it_compiles_to_a_prefetch_instruction() -> None:
    a = np.zeros((4, 3), dtype=np.uint16)
    _sum_prefetching(a, 1)
    asm = "".join(_sum_prefetching.inspect_asm().values())
    assert "prefetcht0" in asm


def test_a_non_contiguous_array_is_refused() -> None:
    @nb.njit
    def strided(a):
        prefetch(a[:, ::2], 0)

    with pytest.raises(TypingError):
        strided(np.zeros((4, 4)))
