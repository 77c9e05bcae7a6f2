"""The lockstep fallback casts of the ``lut`` query equal the one-ray-at-a-time exact casts."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.raycast.fallback import guided_casts
from racecar_sim.raycast.kernels import cast_ray, cast_ray_from, field_from_occupancy


def one_at_a_time(field, x, y, dx, dy, t0, max_t):
    """What the ``lut`` query did before, ray by ray: the guided cast, else the cast from the pose."""
    out = np.empty(x.size)
    for k in range(x.size):
        t = cast_ray_from(field, x[k], y[k], dx[k], dy[k], t0[k], max_t) if t0[k] > 0.0 else -1.0
        if t < 0.0:
            t = cast_ray(field, x[k], y[k], dx[k], dy[k], max_t)
        out[k] = t
    return out


def run_lockstep(field, x, y, dx, dy, t0, max_t):
    n = x.size
    out = np.full(n, np.nan)
    guided_casts(
        field, x, y, dx, dy, t0, max_t, n, out,
        np.empty((4, n)), np.empty((4, n), dtype=np.int64), np.empty(n, dtype=np.int64),
    )  # fmt: skip
    return out


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    fill=st.floats(0.0, 0.25),
    n=st.integers(1, 300),
    max_t=st.floats(1.0, 80.0),
)
def test_lockstep_equals_one_ray_at_a_time(seed, fill, n, max_t):
    """Any rays: origins anywhere (in walls, off the grid, on cell edges), directions including
    the axes, starts before, at and past the origin, in walls and off the grid; also walls and
    open rooms, so that rays jump, step, clip and hit."""
    rng = np.random.default_rng(seed)
    h, w = rng.integers(3, 60, size=2)
    occupied = rng.random((h, w)) < fill
    occupied[rng.integers(0, h), :] = True  # a long wall
    field = field_from_occupancy(occupied)
    x = rng.uniform(-2.0, w + 4.0, n)
    y = rng.uniform(-2.0, h + 4.0, n)
    x[::7] = np.floor(x[::7])  # on a cell edge
    theta = rng.uniform(-math.pi, math.pi, n)
    theta[::5] = rng.integers(-2, 3, theta[::5].size) * (math.pi / 2)  # along the axes
    dx, dy = np.cos(theta), np.sin(theta)
    dx[::5] = np.round(dx[::5])
    dy[::5] = np.round(dy[::5])
    t0 = rng.uniform(-3.0, 30.0, n)
    t0[::6] = 0.0
    want = one_at_a_time(field, x, y, dx, dy, t0, max_t)
    got = run_lockstep(field, x, y, dx, dy, t0, max_t)
    np.testing.assert_array_equal(got, want)


def test_lockstep_leaves_work_arrays_longer_than_the_rays_alone():
    """Rays past ``n`` are not cast; work arrays longer than ``n`` are fine."""
    occupied = np.zeros((20, 30), dtype=bool)
    occupied[:, 25] = True
    field = field_from_occupancy(occupied)
    x = np.array([3.5, 3.5, 3.5])
    y = np.array([10.5, 10.5, 10.5])
    dx = np.array([1.0, 1.0, 1.0])
    dy = np.zeros(3)
    t0 = np.array([5.0, 0.0, 5.0])
    out = np.full(3, -7.0)
    guided_casts(field, x, y, dx, dy, t0, 100.0, 2, out, np.empty((4, 8)),
                 np.empty((4, 8), dtype=np.int64), np.empty(8, dtype=np.int64))  # fmt: skip
    # the wall's cell starts at pad column 26: 26 - 3.5 cells from the origin
    np.testing.assert_array_equal(out[:2], [22.5, 22.5])
    assert out[2] == -7.0


def test_a_subnormal_direction_component_casts_as_one_ray_at_a_time():
    """A heading a hair off an axis (a direction component of 1e-310, subnormal: 1 / |u|
    overflows) gives the exact cast's finite range, not NaN."""
    occupied = np.zeros((20, 30), dtype=bool)
    occupied[:, 25] = True  # a wall across the x axis
    occupied[17, :] = True  # and one across y
    field = field_from_occupancy(occupied)
    tiny = 1e-310
    dx = np.array([1.0, tiny, -tiny, 1.0])
    dy = np.array([tiny, 1.0, 1.0, -tiny])
    x = np.full(4, 3.5)
    y = np.full(4, 4.5)
    t0 = np.array([2.0, 2.0, 0.0, 0.0])
    got = run_lockstep(field, x, y, dx, dy, t0, 60.0)
    assert np.isfinite(got).all()
    np.testing.assert_array_equal(got, one_at_a_time(field, x, y, dx, dy, t0, 60.0))
