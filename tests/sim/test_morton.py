"""Z-order sorting of poses before the lut cast: the order, its inverse, and unchanged ranges."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from racecar_sim.raycast import RayCaster
from racecar_sim.raycast.morton import cell_extent, morton_codes, radix_order, spread_order


def _interleave(x: int, y: int) -> int:
    """Reference Z-order code: bit b of x goes to bit 2b, bit b of y to bit 2b + 1."""
    code = 0
    for b in range(32):
        code |= ((x >> b) & 1) << (2 * b)
        code |= ((y >> b) & 1) << (2 * b + 1)
    return code


cells = arrays(np.float64, st.integers(2, 300), elements=st.floats(0.0, 5000.0))


@given(cells, st.data())
def test_the_scatter_inverts_the_sort_and_the_order_follows_the_codes(gu, data) -> None:
    gv = data.draw(arrays(np.float64, gu.shape, elements=st.floats(0.0, 5000.0)))
    order = spread_order(gu, gv, 0.0)
    assert order is not None
    assert np.array_equal(np.sort(order), np.arange(gu.size))  # a permutation
    values = np.arange(gu.size, dtype=np.float64) * 1.5 - 7.0  # one result per pose
    cast_sorted = values[order]  # what a cast in Z-order computes, pose by pose
    back = np.empty_like(values)
    back[order] = cast_sorted
    assert np.array_equal(back, values)
    codes = [_interleave(int(u), int(v)) for u, v in zip(gu[order], gv[order], strict=True)]
    assert codes == sorted(codes)


@given(st.integers(0, 2**31 - 1), st.integers(0, 2**31 - 1))
def test_codes_interleave_the_bits_of_the_cells(x, y) -> None:
    out = np.empty(1, dtype=np.uint64)
    morton_codes(np.array([x + 0.75]), np.array([y + 0.25]), out)
    assert int(out[0]) == _interleave(x, y)


def test_narrow_clouds_are_not_sorted_and_off_map_poses_clamp() -> None:
    gu = np.array([10.0, 12.0, 11.0])
    gv = np.array([5.0, 9.0, 6.0])
    assert cell_extent(gu, gv) == 4.0
    assert spread_order(gu, gv, 4.5) is None
    assert spread_order(gu, gv, math.inf) is None
    assert spread_order(gu, gv, 4.0) is not None
    out = np.empty(2, dtype=np.uint64)
    morton_codes(np.array([-3.0, 1e12]), np.array([-1.0, 0.0]), out)
    assert out[0] == 0 and int(out[1]) == _interleave(2**31 - 1, 0)


def test_sorted_casts_equal_unsorted_casts_bit_for_bit(default_map) -> None:
    rng = np.random.default_rng(3)
    poses = default_map.sample_free_poses(rng, 600)
    poses[:5, :2] = [-50.0, -50.0]  # off the map: every range 0
    angles = np.linspace(-2.3, 2.3, 37)
    sorted_ = RayCaster(default_map, 10.0, method="lut", parallel=False)
    plain = RayCaster(default_map, 10.0, method="lut", parallel=False)
    plain.lut_params = dataclasses.replace(plain.lut_params, sort_extent=math.inf)
    gu, gv = sorted_.grid_cells(poses)
    assert spread_order(gu, gv, sorted_.lut_params.sort_extent / default_map.resolution) is not None
    assert np.array_equal(sorted_.cast(poses, angles), plain.cast(poses, angles))
    rows = rng.normal(size=(angles.size, 200))
    for offset in (0.0, 0.27):
        a = sorted_.cast_score(poses, angles, rows, 19.8, offset=offset)
        b = plain.cast_score(poses, angles, rows, 19.8, offset=offset)
        assert np.array_equal(a, b)
    two = RayCaster(default_map, 10.0, method="lut", parallel=True)
    assert np.array_equal(two.cast(poses, angles), plain.cast(poses, angles))


@given(arrays(np.uint64, st.integers(0, 400), elements=st.integers(0, 2**64 - 1)))
def test_the_radix_sort_orders_like_a_stable_argsort(codes) -> None:
    assert np.array_equal(radix_order(codes), np.argsort(codes, kind="stable"))
