"""Numba kernels of the particle filter's per-update steps: motion, resampling, moments.

A few passes over the particles each, without numpy temporaries: at 4 000 particles the numpy
versions spent more time allocating arrays and in per-call overhead than computing (issue 14's
update profile: predict 0.31 ms, resample 0.19 ms, estimate + covariance 0.27 ms; these kernels
do the same arithmetic in about a quarter of that). What remained was mostly libm: ``np.mod``'s
float remainder in every wrap (`wrap_near()` shifts instead, bit for bit the same) and a call
to ``sin`` and ``cos`` per heading (`sincos_into()` evaluates fdlibm's polynomials in a loop
that vectorises, within one ulp of libm); and the resampling merge's branch mispredictions
(`systematic_resample()` counts instead). Frames and units as in
[`mcl.filter.motion_model`][mcl.filter.motion_model] and [`mcl.filter.particle_filter`][mcl.filter.particle_filter]: world poses ``[x, y, theta]`` in metres
and radians, theta wrapped to [-pi, pi) as [`mcl.filter.angles.wrap_angle()`][mcl.filter.angles.wrap_angle] does.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from racecar_sim.raycast.rand import normal, uniform

__all__ = [
    "bayes_step", "bayes_update", "compose_into", "covariance_about", "exp_shifted_into",
    "heading_sincos",
    "move_noisy", "move_noisy_into", "noise_into", "pose_moments", "sincos_into", "sincos_near",
    "systematic_pick", "systematic_resample", "wrap", "wrap_near",
]  # fmt: skip

_TWO_PI = 2.0 * math.pi


@nb.njit(cache=True, inline="always")
def wrap(a):
    """One angle (radians) wrapped to [-pi, pi), the arithmetic of [`mcl.filter.angles.wrap_angle()`][mcl.filter.angles.wrap_angle]."""
    out = np.mod(a + math.pi, _TWO_PI) - math.pi
    return out - _TWO_PI if out >= math.pi else out


@nb.njit(cache=True, inline="always")
def wrap_near(a):
    """``(wrap(a), ok)`` for an angle within about one turn of [-pi, pi) (radians): a shift by
    2 pi or none, bit for bit `wrap()`, without its float remainder (a library call the
    compiler evaluates on every iteration of a loop, even when a branch skips it: ~7 ns). ``ok``
    is False when ``a + pi`` is outside [-2 pi, 4 pi) or NaN; the value is then not wrapped and
    the caller redoes it with `wrap()`.

    In range the remainder is exact: ``mod(x, 2 pi)`` is ``x`` on [0, 2 pi), ``x - 2 pi`` on
    [2 pi, 4 pi) (exact by Sterbenz's lemma) and the rounded ``x + 2 pi`` on [-2 pi, 0), which is
    what numpy's floor-mod adds to the (exact) C remainder of a negative ``x``.
    """
    x = a + math.pi
    r = x
    if x >= _TWO_PI:
        r = x - _TWO_PI
    elif x < 0.0:
        r = x + _TWO_PI
    out = r - math.pi
    out = out - _TWO_PI if out >= math.pi else out
    return out, (x >= -_TWO_PI) & (x < 2.0 * _TWO_PI)


# fdlibm's (Sun, 1993) kernels of sin and cos on [-pi/4, pi/4] and its two-step Cody-Waite
# reduction by pi/2 (k_sin.c, k_cos.c, e_rem_pio2.c).
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2, _PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
SINCOS_LIMIT = 1e5
"""Largest ``|angle|`` (radians) `sincos_near()` reduces; beyond it the kernels use libm."""


@nb.njit(cache=True, inline="always")
def sincos_near(x):
    """``(sin x, cos x, ok)`` without branches, so that loops over it vectorise (libm's sin and
    cos are calls, ~10 ns a particle; this is ~2 ns in a vector loop). Within one ulp of libm
    (about 3 % of the values differ from it, by one ulp). ``ok`` is False when
    ``|x| > SINCOS_LIMIT`` or x is not finite; the values are then not to be used.
    """
    k = np.floor(x * _INV_PIO2 + 0.5)  # x = k pi/2 + y0 + y1, |y0| <= pi/4 (about)
    t = x - k * _PIO2_1  # exact: k * _PIO2_1 has at most 53 bits for |k| < 2**20
    w = k * _PIO2_2  # always fdlibm's second step (good to 118 bits; it takes it when needed)
    r = t - w
    w = k * _PIO2_2T - ((t - r) - w)
    y0 = r - w
    y1 = (r - y0) - w
    z = y0 * y0
    v = z * y0
    rs = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
    s = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * _S1)
    rc = z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    hz = 0.5 * z
    one_minus = 1.0 - hz
    c = one_minus + (((1.0 - one_minus) - hz) + (z * rc - y0 * y1))
    q = k - 4.0 * np.floor(k * 0.25)  # quadrant 0..3
    sin_x = s if q == 0.0 else (c if q == 1.0 else (-s if q == 2.0 else -c))
    cos_x = c if q == 0.0 else (-s if q == 1.0 else (-c if q == 2.0 else s))
    return sin_x, cos_x, abs(x) <= SINCOS_LIMIT


@nb.njit(cache=True)
def sincos_into(theta, sin_out, cos_out):
    """``sin_out[i], cos_out[i]``: `sincos_near()` of ``theta[i]`` (contiguous 1-D arrays),
    libm's where it is out of range."""
    ok = True
    for i in range(theta.shape[0]):
        s, c, near = sincos_near(theta[i])
        sin_out[i] = s
        cos_out[i] = c
        ok &= near
    if not ok:
        for i in range(theta.shape[0]):
            if not abs(theta[i]) <= SINCOS_LIMIT:
                sin_out[i] = math.sin(theta[i])
                cos_out[i] = math.cos(theta[i])


@nb.njit(cache=True)
def heading_sincos(particles):
    """``(sin, cos)`` (N,) of the headings ``particles[:, 2]`` by `sincos_into()`."""
    n = particles.shape[0]
    theta = np.empty(n)
    for i in range(n):
        theta[i] = particles[i, 2]
    sin_t = np.empty(n)
    cos_t = np.empty(n)
    sincos_into(theta, sin_t, cos_t)
    return sin_t, cos_t


@nb.njit(cache=True)
def compose_into(particles, odometry, out):
    """``out[i]``: pose ``particles[i]`` (N, 3) moved by the car-frame displacement
    ``odometry[j]`` (``j = i``, or 0 when ``odometry`` is (1, 3)), theta wrapped."""
    shared = odometry.shape[0] == 1
    ok = True
    sin_t, cos_t = heading_sincos(particles)
    for i in range(particles.shape[0]):
        j = 0 if shared else i
        th = particles[i, 2]
        c = cos_t[i]
        s = sin_t[i]
        dx = odometry[j, 0]
        dy = odometry[j, 1]
        out[i, 0] = particles[i, 0] + c * dx - s * dy
        out[i, 1] = particles[i, 1] + s * dx + c * dy
        out[i, 2], near = wrap_near(th + odometry[j, 2])
        ok &= near
    if not ok:
        for i in range(particles.shape[0]):
            out[i, 2] = wrap(particles[i, 2] + odometry[0 if shared else i, 2])


@nb.njit(cache=True, inline="always")
def _draw(state, gaussian):
    """(new state, one noise draw): a standard normal, or a uniform on [-1, 1)."""
    if gaussian:
        return normal(state)
    state, u = uniform(state)
    return state, 2.0 * u - 1.0


@nb.njit(cache=True)
def noise_into(coefficients, gaussian, seed, out):
    """``out`` (N, 3): per-particle odometry noise, ``coefficients[k]`` times a standard normal
    (``gaussian``) or a uniform on [-1, 1), drawn from the `racecar_sim.raycast.rand` stream
    ``seed`` in the order particle 0 (dx, dy, dtheta), particle 1, ..."""
    state = np.uint64(seed)
    for i in range(out.shape[0]):
        for k in range(3):
            state, z = _draw(state, gaussian)
            out[i, k] = z * coefficients[k]


@nb.njit(cache=True)
def move_noisy_into(particles, odometry, coefficients, gaussian, seed, out):
    """``out[i]``: ``particles[i]`` moved by ``odometry`` (3,) plus the noise `noise_into()`
    draws for particle ``i`` with the same seed (the same doubles), in one pass without
    temporaries. Car-frame displacement, world poses, theta wrapped."""
    state = np.uint64(seed)
    ok = True
    sin_t, cos_t = heading_sincos(particles)
    for i in range(particles.shape[0]):
        state, z0 = _draw(state, gaussian)
        state, z1 = _draw(state, gaussian)
        state, z2 = _draw(state, gaussian)
        dx = odometry[0] + z0 * coefficients[0]
        dy = odometry[1] + z1 * coefficients[1]
        dth = odometry[2] + z2 * coefficients[2]
        th = particles[i, 2]
        c = cos_t[i]
        s = sin_t[i]
        out[i, 0] = particles[i, 0] + c * dx - s * dy
        out[i, 1] = particles[i, 1] + s * dx + c * dy
        theta, near = wrap_near(th + dth)
        out[i, 2] = theta if near else th + dth  # unwrapped: outside [-pi, pi), redone below
        ok &= near
    if not ok:
        for i in range(particles.shape[0]):
            if not -math.pi <= out[i, 2] < math.pi:
                out[i, 2] = wrap(out[i, 2])


@nb.njit(cache=True)
def move_noisy(particles, odometry, coefficients, gaussian, seed):
    """`move_noisy_into()` into a new (N, 3) array, returned (one call from Python)."""
    out = np.empty(particles.shape)
    move_noisy_into(particles, odometry, coefficients, gaussian, seed, out)
    return out


@nb.njit(cache=True)
def bayes_step(log_weights, log_likelihood):
    """`bayes_update()` into new arrays: ``(new_log_weights, new_weights, top, total,
    sum_w2)`` (one call from Python)."""
    new_log_weights = np.empty(log_weights.shape[0])
    new_weights = np.empty(log_weights.shape[0])
    top, total, sum_w2 = bayes_update(log_weights, log_likelihood, new_log_weights, new_weights)
    return new_log_weights, new_weights, top, total, sum_w2


@nb.njit(cache=True, error_model="numpy")
def bayes_update(log_weights, log_likelihood, new_log_weights, new_weights):
    """Bayes rule in log space: ``new_log_weights`` = ``log_weights`` + ``log_likelihood`` (NaN
    and +inf likelihoods count as -inf), normalised so that ``new_weights = exp(...)`` sums to 1.

    Returns ``(top, total, sum_w2)``: the largest unnormalised log-weight (-inf or not finite:
    nothing was written after the first pass, the caller recovers), the sum of
    ``exp(lw - top)`` (so the log of the mean likelihood is ``top + log(total)`` when the old
    weights were normalised) and the sum of the squared new weights (Kish's ESS is its inverse).
    """
    n = log_weights.shape[0]
    top = -math.inf
    for i in range(n):
        ll = log_likelihood[i]
        if math.isnan(ll) or ll == math.inf:
            ll = -math.inf
        lw = log_weights[i] + ll
        new_log_weights[i] = lw
        if lw > top:
            top = lw
    if not math.isfinite(top):
        return top, 0.0, 0.0
    exp_shifted_into(new_log_weights, top, new_weights)
    total = 0.0
    for i in range(n):
        total += new_weights[i]
    shift = top + math.log(total)
    for i in range(n):  # without the sums, so that it vectorises
        new_weights[i] /= total
        new_log_weights[i] -= shift
    sum_w2 = 0.0
    for i in range(n):
        sum_w2 += new_weights[i] * new_weights[i]
    return top, total, sum_w2


# fdlibm's exp (e_exp.c): x = k ln2 + r, exp(r) by a rational approximation, times 2**k.
_P1, _P2, _P3 = 1.66666666666666019037e-01, -2.77777777770155933842e-03, 6.61375632143793436117e-05
_P4, _P5 = -1.65339022054652515390e-06, 4.13813679705723846039e-08
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e00
_EXP_LOW, _EXP_HIGH = -708.0, 709.0  # normal results, 2**k a normal double
_TWO52_BIAS = 4503599627370496.0 + 1023.0  # k + this: k + 1023 in the low bits of the double


@nb.njit(cache=True, error_model="numpy")
def exp_shifted_into(values, shift, out):
    """``out[i] = exp(values[i] - shift)`` (contiguous 1-D float64 arrays) in loops that
    vectorise (libm's exp is a call, ~5 ns a value; this ~1.5 ns): within one ulp of libm (about
    10 % of the values differ from it, by one ulp); libm's where ``values[i] - shift`` is outside
    [-708, 709] (subnormal, zero or infinite results), infinite or NaN.

    ``2**k`` is built from its bits: ``k + 2**52 + 1023`` holds ``k + 1023`` in its low bits,
    which a shift by 52 moves into the exponent field.
    """
    n = values.shape[0]
    scale = np.empty(n)
    ok = True
    for i in range(n):
        x = values[i] - shift
        ok &= (x >= _EXP_LOW) & (x <= _EXP_HIGH)
        x = min(max(x, _EXP_LOW), _EXP_HIGH)
        k = np.floor(x * _INV_LN2 + 0.5)
        hi = x - k * _LN2_HI
        lo = k * _LN2_LO
        r = hi - lo
        t = r * r
        c = r - t * (_P1 + t * (_P2 + t * (_P3 + t * (_P4 + t * _P5))))
        out[i] = 1.0 - ((lo - (r * c) / (2.0 - c)) - hi)
        scale[i] = k + _TWO52_BIAS
    bits = scale.view(np.int64)
    for i in range(n):
        bits[i] = bits[i] << 52
    for i in range(n):
        out[i] *= scale[i]
    if not ok:
        for i in range(n):
            x = values[i] - shift
            if not (x >= _EXP_LOW and x <= _EXP_HIGH):
                out[i] = math.exp(x)


@nb.njit(cache=True)
def systematic_pick(cdf, offset, n):
    """(n,) int64 indexes: for pointers ``(offset + k) / n`` the first bin whose cumulative
    weight ``cdf`` (ascending, ending at 1) exceeds the pointer, at most the first bin that
    reaches the end (the last with weight: a pointer that rounds up to 1 draws no empty bin).

    The pointers are ascending, so one merge over both is enough (what ``np.searchsorted(cdf,
    pointers, side="right")`` answers, without its binary searches).
    """
    out = np.empty(n, dtype=np.int64)
    last = np.searchsorted(cdf, cdf[cdf.shape[0] - 1])  # the first bin at the end
    j = 0
    for k in range(n):
        ptr = (offset + k) / n
        while j < last and cdf[j] <= ptr:
            j += 1
        out[k] = j
    return out


@nb.njit(cache=True)
def pose_moments(particles, weights, with_covariance):
    """Weighted mean pose (3,) and, when asked, the (3, 3) covariance about it (else zeros).

    The mean is the arithmetic mean of x, y and the circular mean of theta (the direction of
    the weighted sum of unit vectors, 0 when they cancel); the covariance wraps the heading
    deviations around that mean. ``weights`` sum to 1.
    """
    n = particles.shape[0]
    mx = 0.0
    my = 0.0
    ms = 0.0
    mc = 0.0
    sin_t, cos_t = heading_sincos(particles)
    for i in range(n):
        w = weights[i]
        mx += w * particles[i, 0]
        my += w * particles[i, 1]
        ms += w * sin_t[i]
        mc += w * cos_t[i]
    mean = np.empty(3)
    mean[0] = mx
    mean[1] = my
    mean[2] = wrap(math.atan2(ms, mc))
    cov = covariance_about(particles, weights, mean) if with_covariance else np.zeros((3, 3))
    return mean, cov


@nb.njit(cache=True)
def covariance_about(particles, weights, mean):
    """(3, 3) weighted covariance of the poses about ``mean`` (3,), heading deviations wrapped;
    ``weights`` sum to 1."""
    cov, ok = _covariance(particles, weights, mean, True)
    return cov if ok else _covariance(particles, weights, mean, False)[0]


@nb.njit(cache=True, inline="always")
def _covariance(particles, weights, mean, near):
    """`covariance_about()` with the heading deviations wrapped by `wrap_near()` when
    ``near`` (then ``ok`` says whether every deviation was in its range), else by `wrap()`."""
    cov = np.zeros((3, 3))
    ok = True
    for i in range(particles.shape[0]):
        w = weights[i]
        d0 = particles[i, 0] - mean[0]
        d1 = particles[i, 1] - mean[1]
        if near:
            d2, inside = wrap_near(particles[i, 2] - mean[2])
            ok &= inside
        else:
            d2 = wrap(particles[i, 2] - mean[2])
        cov[0, 0] += w * d0 * d0
        cov[0, 1] += w * d0 * d1
        cov[0, 2] += w * d0 * d2
        cov[1, 1] += w * d1 * d1
        cov[1, 2] += w * d1 * d2
        cov[2, 2] += w * d2 * d2
    cov[1, 0] = cov[0, 1]
    cov[2, 0] = cov[0, 2]
    cov[2, 1] = cov[1, 2]
    return cov, ok


@nb.njit(cache=True, error_model="numpy")
def systematic_resample(particles, weights, offset, n):
    """Systematic resampling of ``particles`` (N, 3) by ``weights`` (N,): ``(idx, drawn)`` with
    ``idx`` the (n,) int64 indexes `systematic_pick()` gives for pointers
    ``(offset + k) / n`` on the normalised cumulative weights (``cumsum(w / sum(w))``, then
    divided by its last element so that it ends at exactly 1, as
    [`mcl.filter.resampling.systematic()`][mcl.filter.resampling.systematic] does; the sum here is a plain running one), and
    ``drawn = particles[idx]``. The weights must be non-negative and finite with a positive sum
    (the filter's always are).

    Without the merge's data-dependent branches (a misprediction or two per pointer, most of its
    time): ``idx[k]`` is the number of bins ``j`` whose cumulative weight is at or below pointer
    ``k``, i.e. whose first pointer not below it, ``e_j``, is at most ``k``. ``e_j`` is
    ``ceil(n cdf_j - offset)``, corrected by a step where rounding puts a pointer on the other side
    of ``cdf_j`` (rare, so well predicted); a histogram of the ``e_j`` and its running sum give
    ``idx``.
    """
    m = weights.shape[0]
    total = 0.0
    for i in range(m):
        total += weights[i]
    cdf = np.empty(m)
    for i in range(m):  # the divisions in loops of their own, which vectorise
        cdf[i] = weights[i] / total
    run = 0.0
    for i in range(m):
        run += cdf[i]
        cdf[i] = run
    last = cdf[m - 1]
    for i in range(m):
        cdf[i] /= last
    pointers = np.empty(n + 1)
    for k in range(n + 1):
        pointers[k] = (offset + k) / n
    starts = np.zeros(n + 1, dtype=np.int64)  # starts[e]: bins whose first pointer >= cdf is e
    for j in range(m):
        c = cdf[j]
        e = min(max(math.ceil(c * n - offset), 0), n)
        while e > 0 and pointers[e - 1] >= c:
            e -= 1
        while e < n and pointers[e] < c:
            e += 1
        starts[e] += 1
    top = m - 1  # the last bin with weight: a pointer rounded up to 1 draws no empty bin
    while top > 0 and cdf[top - 1] >= 1.0:
        top -= 1
    idx = np.empty(n, dtype=np.int64)
    drawn = np.empty((n, 3))
    below = 0
    for k in range(n):
        below += starts[k]
        j = min(below, top)
        idx[k] = j
        drawn[k, 0] = particles[j, 0]
        drawn[k, 1] = particles[j, 1]
        drawn[k, 2] = particles[j, 2]
    return idx, drawn
