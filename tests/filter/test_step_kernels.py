"""The numba step kernels against the plain numpy formulas they replace (same numbers)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mcl.filter.angles import circular_mean, wrap_angle
from mcl.filter.step_kernels import (
    compose_into,
    covariance_about,
    exp_shifted_into,
    heading_sincos,
    move_noisy,
    move_noisy_into,
    noise_into,
    pose_moments,
    sincos_into,
    sincos_near,
    systematic_pick,
    systematic_resample,
    wrap,
    wrap_near,
)

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(deadline=None)
@given(st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=50))
def test_wrap_is_wrap_angle_bit_for_bit(angles):
    a = np.array(angles)
    want = wrap_angle(a)
    got = np.array([wrap(x) for x in a])
    assert np.array_equal(got, want)
    assert ((got >= -math.pi) & (got < math.pi)).all()


@settings(max_examples=50, deadline=None)
@given(
    w=arrays(np.float64, st.integers(1, 60), elements=st.floats(0, 10)),
    offset=st.floats(0, 1, exclude_max=True),
    n=st.integers(1, 80),
)
@example(w=np.array([1.0, 0.0]), offset=0.9999999999999998, n=3)  # the last pointer rounds up to 1
def test_systematic_pick_is_searchsorted(w, offset, n):
    """The merge gives what a binary search per pointer gives, including zero-weight bins (never
    drawn) and pointers that round up to the end (clipped to the last bin with weight)."""
    if w.sum() <= 0:
        w[0] = 1.0
    cdf = np.cumsum(w / w.sum())
    cdf /= cdf[-1]
    pointers = (offset + np.arange(n)) / n
    want = np.minimum(np.searchsorted(cdf, pointers, side="right"), np.searchsorted(cdf, 1.0))
    got = systematic_pick(cdf, offset, n)
    assert np.array_equal(got, want)
    assert (w[got] > 0).all()


@settings(max_examples=50, deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=finite),
    raw=st.lists(st.floats(0.01, 10), min_size=40, max_size=40),
)
def test_pose_moments_match_the_numpy_formulas(p, raw):
    p[:, 2] = wrap_angle(p[:, 2])
    w = np.array(raw[: p.shape[0]])
    w /= w.sum()
    mean, cov = pose_moments(p, w, True)
    np.testing.assert_allclose(mean[:2], w @ p[:, :2], rtol=1e-12, atol=1e-9)
    theta = circular_mean(p[:, 2], w)
    assert abs(wrap_angle(mean[2] - theta)) <= 1e-9
    dev = p - mean
    dev[:, 2] = wrap_angle(dev[:, 2])
    np.testing.assert_allclose(cov, (dev * w[:, None]).T @ dev, rtol=1e-9, atol=1e-9)
    assert np.array_equal(pose_moments(p, w, False)[0], mean)


@settings(deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 20), st.just(3)), elements=finite),
    odo=arrays(np.float64, 3, elements=st.floats(-5, 5)),
)
def test_compose_into_matches_the_formula(p, odo):
    out = np.empty_like(p)
    compose_into(p, odo.reshape(1, 3), out)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    np.testing.assert_allclose(out[:, 0], p[:, 0] + c * odo[0] - s * odo[1], atol=1e-9)
    np.testing.assert_allclose(out[:, 1], p[:, 1] + s * odo[0] + c * odo[1], atol=1e-9)
    assert np.array_equal(out[:, 2], wrap_angle(p[:, 2] + odo[2]))


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, st.integers(1, 40), elements=st.floats(-50.0, 0.0)),
    st.data(),
)
def test_bayes_update_matches_the_numpy_formulas(old, data):
    """Normalised log-weights, weights, the log mean likelihood and Kish's sum of squares as the
    numpy code computed them; NaN and +inf likelihoods count as impossible."""
    from mcl.filter.step_kernels import bayes_step, bayes_update

    n = old.size
    old = old - np.log(np.exp(old).sum())  # normalised, as the filter keeps them
    choices = st.one_of(st.floats(-300.0, 10.0), st.sampled_from([np.nan, np.inf, -np.inf]))
    ll = np.array(data.draw(st.lists(choices, min_size=n, max_size=n)))
    lw, w = np.empty(n), np.empty(n)
    top, total, sum_w2 = bayes_update(old, ll, lw, w)
    want = old + np.where(np.isnan(ll) | (ll == np.inf), -np.inf, ll)
    assert top == want.max()
    if not np.isfinite(top):
        return
    step = bayes_step(old, ll)  # the same into new arrays
    assert np.array_equal(step[0], lw) and np.array_equal(step[1], w)
    assert step[2:] == (top, total, sum_w2)
    np.testing.assert_allclose(total, np.exp(want - top).sum(), rtol=1e-12)
    expected_w = np.exp(want - top) / np.exp(want - top).sum()
    np.testing.assert_allclose(w, expected_w, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(np.exp(lw), expected_w, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(sum_w2, np.dot(expected_w, expected_w), rtol=1e-12)


_TURN = 2.0 * math.pi
_EDGES = [
    k * _TURN - math.pi + d for k in range(-3, 4) for d in (0.0, 1e-15, -1e-15, 4e-16, -4e-16)
] + [0.0, -0.0, math.pi, -math.pi, 5e-324, -5e-324, 1e300, -1e300, math.nan]


@settings(deadline=None)
@given(
    st.lists(st.one_of(st.floats(-30.0, 30.0), st.sampled_from(_EDGES)), min_size=1, max_size=40)
)
def test_wrap_near_is_wrap_bit_for_bit_where_it_says_ok(angles):
    """In its range (a + pi in [-2 pi, 4 pi)) the shift equals the float remainder, sign of zero
    included; outside it (or NaN) it says so."""
    for a in angles:
        got, ok = wrap_near(a)
        x = a + math.pi
        assert ok == (-_TURN <= x < 2 * _TURN)
        if ok:
            want = wrap(a)
            assert got == want and math.copysign(1, got) == math.copysign(1, want), a


def test_wrap_near_is_wrap_over_its_whole_range():
    """Dense over [-3 pi, 3 pi) (all of its range): every value as the remainder gives it."""
    angles = np.random.default_rng(3).uniform(-3 * math.pi, 3 * math.pi, 20_000)
    for a in angles.tolist():
        got, ok = wrap_near(a)
        assert ok and got == wrap(a), a


def _cloud_with_copies(p, copies):
    """The poses repeated as resampling repeats them (consecutive copies), headings 0.0 and -0.0
    among them."""
    p = np.repeat(p, copies, axis=0)
    p[::5, 2] = 0.0
    p[1::7, 2] = -0.0
    return p


@settings(max_examples=60, deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 15), st.just(3)), elements=finite),
    copies=st.integers(1, 4),
    odo=arrays(np.float64, 3, elements=st.floats(-5, 5)),
    dtheta=st.sampled_from([0.0, 0.3, 12.0, -40.0]),
    gaussian=st.booleans(),
    seed=st.integers(0, 2**62),
)
def test_move_noisy_into_is_compose_of_the_noise_bit_for_bit(
    p, copies, odo, dtheta, gaussian, seed
):
    """Odometry plus :func:`noise_into`'s draws, composed by :func:`compose_into`: the same
    doubles, with copies of a heading, headings +-0 and turns large enough to need the full
    remainder."""
    p = _cloud_with_copies(p, copies)
    p[:, 2] = wrap_angle(p[:, 2]) if dtheta == 0.0 else p[:, 2]
    odo = odo.copy()
    odo[2] += dtheta
    coefficients = np.array([0.02, 0.01, 0.5])
    noise = np.empty_like(p)
    noise_into(coefficients, gaussian, seed, noise)
    want = np.empty_like(p)
    compose_into(p, odo[None, :] + noise, want)
    got = np.empty_like(p)
    move_noisy_into(p, odo, coefficients, gaussian, seed, got)
    assert np.array_equal(got, want)
    assert np.array_equal(move_noisy(p, odo, coefficients, gaussian, seed), want)
    assert np.array_equal(np.signbit(got), np.signbit(want))
    assert np.array_equal(got[:, 2], wrap_angle(p[:, 2] + (odo[None, :] + noise)[:, 2]))


@settings(max_examples=60, deadline=None)
@given(
    p=arrays(np.float64, st.tuples(st.integers(1, 15), st.just(3)), elements=finite),
    copies=st.integers(1, 4),
    raw=st.lists(st.floats(0.01, 10), min_size=60, max_size=60),
    wrapped=st.booleans(),
)
def test_pose_moments_are_the_plain_loop_bit_for_bit(p, copies, raw, wrapped):
    """The mean (from :func:`sincos_into`'s sines and cosines) and the covariance (headings
    wrapped by a shift in range, by the remainder outside it) as a plain Python loop over the
    same formula, in the same order, computes them."""
    p = _cloud_with_copies(p, copies)
    if wrapped:
        p[:, 2] = wrap_angle(p[:, 2])
    w = np.array(raw[: p.shape[0]])
    w /= w.sum()
    sin_t, cos_t = np.empty(p.shape[0]), np.empty(p.shape[0])
    sincos_into(np.ascontiguousarray(p[:, 2]), sin_t, cos_t)  # tested against libm below
    mx = my = ms = mc = 0.0
    for (x, y, _), wi, s, c in zip(p.tolist(), w.tolist(), sin_t, cos_t, strict=True):
        mx, my = mx + wi * x, my + wi * y
        ms, mc = ms + wi * s, mc + wi * c
    want_mean = np.array([mx, my, float(wrap_angle(math.atan2(ms, mc)))])
    mean, cov = pose_moments(p, w, True)
    assert np.array_equal(mean, want_mean)
    want = np.zeros((3, 3))
    for (x, y, th), wi in zip(p.tolist(), w.tolist(), strict=True):
        d = np.array([x - mean[0], y - mean[1], float(wrap_angle(th - mean[2]))])
        for a, b in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
            want[a, b] += wi * d[a] * d[b]
    want[1, 0], want[2, 0], want[2, 1] = want[0, 1], want[0, 2], want[1, 2]
    assert np.array_equal(cov, want)
    assert np.array_equal(covariance_about(p, w, mean), want)


@settings(max_examples=80, deadline=None)
@given(
    counts=arrays(np.int64, st.integers(1, 60), elements=st.integers(0, 1000)),
    offset=st.floats(0, 1, exclude_max=True),
    n=st.integers(1, 90),
)
# the last pointer, (offset + 2) / 3, rounds up to 1: clipped to the last bin, it drew the empty one
@example(counts=np.array([1, 0]), offset=0.9999999999999998, n=3)
def test_systematic_resample_is_numpy_systematic(counts, offset, n):
    """Integer weights, whose sums are exact in any order: the same indexes as numpy's
    cumulative sum and binary search, and the particles copied from them."""
    if counts.sum() == 0:
        counts[-1] = 3
    w = counts.astype(np.float64)
    particles = np.arange(3 * w.size, dtype=np.float64).reshape(-1, 3) * 0.5
    cdf = np.cumsum(w / w.sum())
    cdf /= cdf[-1]
    pointers = (offset + np.arange(n)) / n
    want = np.minimum(np.searchsorted(cdf, pointers, side="right"), np.searchsorted(cdf, 1.0))
    idx, drawn = systematic_resample(particles, w, offset, n)
    assert np.array_equal(idx, want)
    assert np.array_equal(drawn, particles[want])
    assert (w[idx] > 0).all()


@settings(max_examples=80, deadline=None)
@given(
    w=arrays(np.float64, st.integers(1, 60), elements=st.floats(0, 10)),
    offset=st.one_of(st.just(0.0), st.floats(0, 1, exclude_max=True)),
    n=st.integers(1, 90),
)
def test_systematic_resample_is_the_merge_on_its_cumulative_weights(w, offset, n):
    """Any float weights: the counted picks are the merge's (:func:`systematic_pick`) on the
    same cumulative weights (a running total, ``cumsum(w / total)`` ending at 1), ties
    included."""
    if w.sum() <= 0:
        w[0] = 1.0
    cdf = np.cumsum(w / np.add.accumulate(w)[-1])  # accumulate: the running (not pairwise) sum
    cdf /= cdf[-1]
    idx, _ = systematic_resample(np.zeros((w.size, 3)), w, offset, n)
    assert np.array_equal(idx, systematic_pick(cdf, offset, n))


@settings(max_examples=50, deadline=None)
@given(
    w=arrays(np.float64, st.integers(1, 60), elements=st.floats(0, 10)),
    seed=st.integers(0, 2**32),
    n=st.integers(1, 90),
)
def test_resample_particles_keeps_systematic_counts(w, seed, n):
    """Any float weights: every particle drawn floor or ceil of n w_i / sum(w) times (the
    systematic invariant), zero weights never, from one draw of the generator as
    :func:`mcl.filter.resampling.systematic`; the other methods are their function plus the copy."""
    from mcl.filter.resampling import resample, resample_particles

    if w.sum() <= 0:
        w[0] = 1.0
    particles = np.column_stack([np.arange(w.size), -np.arange(w.size), np.zeros(w.size)]) * 1.0
    rng = np.random.default_rng(seed)
    idx, drawn = resample_particles("systematic", particles, w, rng, n)
    counts = np.bincount(idx, minlength=w.size)
    expected = n * w / w.sum()
    assert (counts >= np.floor(expected - 1e-9)).all() and (
        counts <= np.ceil(expected + 1e-9)
    ).all()
    assert (counts[w == 0] == 0).all()
    assert np.array_equal(drawn, particles[idx])
    assert rng.random() == np.random.default_rng(seed).random(2)[1]
    for method in ("multinomial", "stratified"):
        idx, drawn = resample_particles(method, particles, w, np.random.default_rng(seed), n)
        assert np.array_equal(idx, resample(method, w, np.random.default_rng(seed), n))
        assert np.array_equal(drawn, particles[idx])


def test_move_noisy_into_takes_the_sine_of_each_signed_zero_heading():
    """Headings 0.0 then -0.0 compare equal, but their sines differ in sign, which shows in an
    exactly-zero result: ``-0.0 - sin(h) * 1.0`` is -0.0 for h = 0.0 and +0.0 for h = -0.0."""
    seed = 7
    z = np.empty((2, 3))
    noise_into(np.ones(3), True, seed, z)
    coefficients = np.array([-0.0 if z[1, 0] > 0 else 0.0, 0.0, 0.0])  # noise of dx: -0.0
    particles = np.array([[-0.0, 0.0, 0.0], [-0.0, 0.0, -0.0]])
    out = np.empty_like(particles)
    move_noisy_into(particles, np.array([-0.0, 1.0, 0.0]), coefficients, True, seed, out)
    assert math.copysign(1.0, out[1, 0]) == 1.0


_LIBM_EDGES = [0.0, -0.0, 5e-324, -5e-324, 1e-300, math.pi, -math.pi, math.pi / 2, 1e5, -1e5]


def _ulps(got, want):
    return abs(got - want) / np.spacing(abs(want))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(st.floats(-4.0, 4.0), st.floats(-1e5, 1e5), st.sampled_from(_LIBM_EDGES)),
        min_size=1,
        max_size=50,
    )
)
def test_sincos_is_libm_within_one_ulp(angles):
    """In range: sin and cos within one ulp of libm's (math.sin, math.cos), zeros signed as
    libm signs them."""
    theta = np.array(angles)
    s, c = np.empty_like(theta), np.empty_like(theta)
    sincos_into(theta, s, c)
    for a, si, ci in zip(angles, s.tolist(), c.tolist(), strict=True):
        assert _ulps(si, math.sin(a)) <= 1.0 and _ulps(ci, math.cos(a)) <= 1.0, a
        assert math.copysign(1.0, si) == math.copysign(1.0, math.sin(a)), a
        assert sincos_near(a)[2]


def test_sincos_is_libm_within_one_ulp_densely_and_near_multiples_of_half_pi():
    """Dense over the headings' range and where the reduction by pi/2 cancels most bits."""
    rng = np.random.default_rng(5)
    near = [k * math.pi / 2 + d for k in range(-8, 9) for d in np.linspace(-1e-7, 1e-7, 201)]
    theta = np.concatenate([rng.uniform(-math.pi, math.pi, 20_000), near])
    s, c = np.empty_like(theta), np.empty_like(theta)
    sincos_into(theta, s, c)
    assert (
        max(_ulps(si, math.sin(a)) for a, si in zip(theta.tolist(), s.tolist(), strict=True)) <= 1
    )
    assert (
        max(_ulps(ci, math.cos(a)) for a, ci in zip(theta.tolist(), c.tolist(), strict=True)) <= 1
    )


def test_sincos_outside_its_range_is_libm():
    """Beyond SINCOS_LIMIT and for inf and NaN: libm's values (what numba's math.sin gives)."""
    from mcl.filter.step_kernels import SINCOS_LIMIT

    big = [2 * SINCOS_LIMIT, -3e7, 1e300, -1e300]
    theta = np.array([*big, math.inf, -math.inf, math.nan])
    s, c = np.empty_like(theta), np.empty_like(theta)
    sincos_into(theta, s, c)
    assert s[:4].tolist() == [math.sin(a) for a in big]
    assert c[:4].tolist() == [math.cos(a) for a in big]
    assert np.isnan(s[4:]).all() and np.isnan(c[4:]).all()
    assert not sincos_near(2 * SINCOS_LIMIT)[2] and not sincos_near(math.nan)[2]
    p = np.column_stack([np.zeros((theta.size, 2)), theta])
    hs, hc = heading_sincos(p)
    assert np.array_equal(hs, s, equal_nan=True) and np.array_equal(hc, c, equal_nan=True)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(-720.0, 0.0),
            st.floats(-1.0, 1.0),
            st.sampled_from([0.0, -0.0, -708.0, 709.0, -745.0, -746.0, 710.0, -math.inf]),
        ),
        min_size=1,
        max_size=50,
    ),
    st.sampled_from([0.0, 3.5, -120.25]),
)
def test_exp_shifted_is_libm_within_one_ulp(values, shift):
    """exp(v - shift) within one ulp of libm's (math.exp); libm's own value (zero, subnormal,
    infinite) outside the normal range."""
    v = np.array(values)
    out = np.empty_like(v)
    exp_shifted_into(v, shift, out)
    for x, got in zip((v - shift).tolist(), out.tolist(), strict=True):
        want = math.exp(x) if x < 709.5 else math.inf
        if -708.0 <= x <= 709.0:
            assert _ulps(got, want) <= 1.0, x
        else:
            assert got == want, x


def test_exp_shifted_is_libm_within_one_ulp_densely():
    """Dense over the log-weights' range [-708, 0] (and the bottom of [0, 709])."""
    v = np.concatenate([np.random.default_rng(6).uniform(-708.0, 0.0, 20_000), [0.0, 709.0]])
    out = np.empty_like(v)
    exp_shifted_into(v, 0.0, out)
    assert max(_ulps(g, math.exp(x)) for x, g in zip(v.tolist(), out.tolist(), strict=True)) <= 1
    assert out[-2] == 1.0


@pytest.mark.parametrize(
    ("n", "offset", "c", "estimate_off_by"),
    [
        (2648, 0.6875, 0.15962518882175228, 1),  # pointers found by search near ties
        (9562, 0.648547207079825, 0.7862004337175361, 1),
        (48, 0.1875, 0.6705729166666667, -1),
        (2982, 0.7221648081421175, 0.48749904923143605, -1),
    ],
)
def test_systematic_resample_corrects_the_rounded_first_pointer(n, offset, c, estimate_off_by):
    """Where ``ceil(n c - offset)`` is one off the first pointer not below ``c`` (rounding of
    the product against that of the pointers), the kernel still gives the merge's picks."""
    first = int(np.searchsorted((offset + np.arange(n + 1)) / n, c, side="left"))
    assert math.ceil(c * n - offset) - first == estimate_off_by
    w = np.array([c, 1.0 - c])
    assert w.sum() == 1.0  # so the cumulative weights are exactly [c, 1]
    idx, _ = systematic_resample(np.zeros((2, 3)), w, offset, n)
    assert np.array_equal(idx, systematic_pick(np.array([c, 1.0]), offset, n))
