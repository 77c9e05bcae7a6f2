"""The ``lut`` table's format: what an entry holds, and where a table ray hits.

Table
    For every free cell and each of ``K`` directions ``theta_k = 2 pi k / K`` (map frame), a range
    stored in the low 15 bits of a uint16 in units of ``cap / 32000`` cells, ``cap`` being the max
    range plus two cells. Rows exist for free cells only (``index`` maps a cell to its row, -1 for
    occupied cells), so the table holds ``2 K`` bytes per free cell: 223 MB for the Stata basement
    at K = 360.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

__all__ = [
    "CAP_MARGIN",
    "CODE_MAX",
    "FLAG",
    "FLAG_ABOVE",
    "FLAG_EPS",
    "RANGE_MASK",
    "LutTable",
    "foot_hit",
]

CODE_MAX = 32000
"""Range code of the cap range (the low 15 bits of an entry)."""
RANGE_MASK = 0x7FFF
"""Bits of an entry holding the range code."""
FLAG = 0x8000
"""Bit of entry ``k`` set when rays ``k`` and ``k + 1`` see one straight face (module docstring)."""
FLAG_ABOVE = 1.0
"""Cells: pairs of table ranges differing by more are checked for the planar flag."""
FLAG_EPS = 0.15
"""Cells: how far the middle ray's exact range may lie from the interpolated one for the flag."""
CAP_MARGIN = 2.0
"""Cells stored beyond max_range, so a pose offset inside its cell stays right."""


@dataclass(frozen=True, eq=False)
class LutTable:
    """A built range table (pad frame, cells; see the module docstring).

    Attributes:
        table: uint16 (n_free, K) entries, one row per free cell: the range code in the low
            15 bits (`RANGE_MASK`), the planar flag in the high bit (`FLAG`).
        index: int32 (H + 2, W + 2) row of each free pad-frame cell, -1 elsewhere.
        unit: cells per code unit.
        sub_lines: sweep lines per cell width used to build it.
        cos_k: float64 (K + 1,) cosines of the table directions (the last repeats the first).
        sin_k: float64 (K + 1,) their sines.
        build_seconds: wall time of the build.
        n_flagged: entries with the planar flag.
    """

    table: np.ndarray
    index: np.ndarray
    unit: float
    sub_lines: int
    cos_k: np.ndarray
    sin_k: np.ndarray
    build_seconds: float
    n_flagged: int = 0

    @property
    def n_angles(self) -> int:
        """K, the number of table directions."""
        return int(self.table.shape[1])

    @property
    def nbytes(self) -> int:
        """Bytes held by the table and its index."""
        return int(self.table.nbytes + self.index.nbytes)


@nb.njit(cache=True, inline="always")
def foot_hit(cx, cy, c, s, r, sub, inv_sub):
    """Hit point (x, y) of the table ray of direction (c, s) and range r for centre (cx, cy)."""
    sn = (cy * c - cx * s) * sub
    dl = (math.floor(sn) + 0.5 - sn) * inv_sub
    return cx - dl * s + r * c, cy + dl * c + r * s
