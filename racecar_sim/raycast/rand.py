"""A fast seeded random stream inside numba kernels: the lidar's beam noise (seeded once per scan
from the env's generator) and the particle filter's motion noise (seeded once per predict from the
filter's generator, [`mcl.filter.step_kernels`][mcl.filter.step_kernels]).

A scan needs one uniform and (for most beams) one standard normal per beam. Drawn through numpy's
``Generator`` that is two calls and ~14 us per 1080-beam scan, most of it the normals; here the
kernel draws them itself from a stream seeded once per scan from the env's generator (so the same
env seed still gives the same scans), ~2.5 us per 1080 beams with
`uniforms_and_normals()`, whose beam ``i`` takes the SplitMix64 outputs of counters
``2i + 1`` and ``2i + 2`` so that the beams are drawn in vectorised loops:

* `next_u64()`: SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number
  generators", OOPSLA 2014): a 64-bit counter stepped by the golden-ratio increment and mixed;
  the state is one ``uint64`` passed in and returned.
* `uniform()`: a double in [0, 1) from the top 53 bits.
* `normal()`: a standard normal by Marsaglia and Tsang's ziggurat ("The Ziggurat Method for
  Generating Random Variables", J. Stat. Softw. 5(8), 2000) with 128 layers on 32 random bits,
  the tail beyond ``r`` by Marsaglia's exponential method. About 98.8 % of the draws take the
  fast path (one 64-bit draw, a table look-up, a multiply). The tables are computed here at import
  from the layer area and tail start (`ZIGGURAT_R`, `ZIGGURAT_V`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = [
    "ZIGGURAT_R", "ZIGGURAT_V", "next_u64", "normal", "normals", "seed_from", "uniform", "uniforms",
    "uniforms_and_normals",
]

ZIGGURAT_R = 3.442619855899
"""Start of the normal ziggurat's tail (standard deviations), 128 layers."""
ZIGGURAT_V = 9.91256303526217e-3
"""Area of each of the 128 layers under ``exp(-x²/2)``."""

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_S32 = np.uint64(32)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2**-53
_HALF_RANGE = 2147483648  # 2**31


def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """kn (int64 acceptance bounds), wn (x per unit of the 32-bit draw), fn (exp(-x²/2)) per layer."""
    m1 = float(_HALF_RANGE)
    kn = np.zeros(128, dtype=np.int64)
    wn = np.zeros(128)
    fn = np.zeros(128)
    dn = tn = ZIGGURAT_R
    q = ZIGGURAT_V / math.exp(-0.5 * dn * dn)  # width of the base strip (its area is v too)
    kn[0] = int((dn / q) * m1)
    kn[1] = 0
    wn[0] = q / m1
    wn[127] = dn / m1
    fn[0] = 1.0
    fn[127] = math.exp(-0.5 * dn * dn)
    for i in range(126, 0, -1):
        dn = math.sqrt(-2.0 * math.log(ZIGGURAT_V / dn + math.exp(-0.5 * dn * dn)))
        kn[i + 1] = int((dn / tn) * m1)
        tn = dn
        fn[i] = math.exp(-0.5 * dn * dn)
        wn[i] = dn / m1
    return kn, wn, fn


_KN, _WN, _FN = _tables()


def seed_from(rng: np.random.Generator) -> int:
    """A stream seed (non-negative int64) drawn from ``rng``: one raw 64-bit draw of its bits."""
    return int(rng.bit_generator.random_raw()) >> 1


@nb.njit(cache=True, inline="always")
def _mix(z):
    """SplitMix64's output function of a counter value."""
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@nb.njit(cache=True, inline="always")
def next_u64(state):
    """SplitMix64: (new state, a uniform uint64)."""
    state = state + _GOLDEN
    return state, _mix(state)


@nb.njit(cache=True, inline="always")
def uniform(state):
    """(new state, a double uniform in [0, 1) with 53 random bits)."""
    state, z = next_u64(state)
    return state, float(z >> _S11) * _TO_UNIT


@nb.njit(cache=True)
def _normal_slow(state, hz, iz):
    """The ziggurat's rejection path for a draw ``hz`` in layer ``iz`` outside its box."""
    r = ZIGGURAT_R
    while True:
        x = hz * _WN[iz]
        if iz == 0:  # the tail beyond r: Marsaglia's method with two exponentials
            while True:
                state, u1 = uniform(state)
                state, u2 = uniform(state)
                x = -math.log(1.0 - u1) / r
                y = -math.log(1.0 - u2)
                if y + y >= x * x:
                    break
            return state, (r + x) if hz > 0 else -(r + x)
        state, u = uniform(state)
        if _FN[iz] + u * (_FN[iz - 1] - _FN[iz]) < math.exp(-0.5 * x * x):
            return state, x
        state, z = next_u64(state)
        hz = np.int64(z >> _S32) - _HALF_RANGE
        iz = hz & 127
        if abs(hz) < _KN[iz]:
            return state, hz * _WN[iz]


@nb.njit(cache=True, inline="always")
def normal(state):
    """(new state, a standard normal draw) by the ziggurat."""
    state, z = next_u64(state)
    hz = np.int64(z >> _S32) - _HALF_RANGE  # uniform over the signed 32-bit integers
    iz = hz & 127
    if abs(hz) < _KN[iz]:
        return state, hz * _WN[iz]
    return _normal_slow(state, hz, iz)


@nb.njit(cache=True)
def normals(seed, out):
    """Fill float64 ``out`` with standard normals from the stream seeded by ``seed`` (int64)."""
    state = np.uint64(seed)
    for i in range(out.shape[0]):
        state, out[i] = normal(state)


@nb.njit(cache=True)
def uniforms(seed, out):
    """Fill float64 ``out`` with uniforms in [0, 1) from the stream seeded by ``seed`` (int64)."""
    state = np.uint64(seed)
    for i in range(out.shape[0]):
        state, out[i] = uniform(state)


@nb.njit(cache=True, error_model="numpy")
def uniforms_and_normals(seed, u, z) -> None:
    """Fill float64 ``u`` with uniforms in [0, 1) and ``z`` with standard normals, element ``i``
    from counters ``2i + 1`` and ``2i + 2`` of the SplitMix64 sequence seeded by ``seed`` (int64).

    Every element is its own draw (no element waits for the one before), so the loops have no
    branch and vectorise; the ~1.2 % of normals outside their ziggurat box are redone after them,
    each from a SplitMix64 stream seeded by its counter's output.
    """
    n = u.shape[0]
    raw = np.empty(n, dtype=np.uint64)
    c = np.uint64(seed)
    for i in range(n):
        c += _GOLDEN
        a = _mix(c)
        c += _GOLDEN
        raw[i] = _mix(c)
        u[i] = np.int64(a >> _S11) * _TO_UNIT
    slow = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        hz = np.int64(raw[i] >> _S32) - _HALF_RANGE
        iz = np.int64(raw[i] >> _S32) & 127
        z[i] = hz * _WN[iz]
        slow[m] = i
        m += abs(hz) >= _KN[iz]
    for j in range(m):
        i = slow[j]
        hz = np.int64(raw[i] >> _S32) - _HALF_RANGE
        _, z[i] = _normal_slow(raw[i], hz, hz & 127)
