"""Ray casting on an occupancy grid: one API for the simulated lidar and for particles.

A ray starts at a pose's position and runs along ``theta + angle`` (world frame). Its range is the
distance in metres to where it *enters* the first occupied cell (unknown cells and everything beyond
the image border count as occupied), clipped to ``max_range``. A pose inside an occupied cell, or
off the map, gives 0 on every ray. Casting is done in the grid's own axis-aligned frame (see
[`racecar_sim.maps`][racecar_sim.maps]), so a map origin with a yaw is handled by rotating the ray, not the grid.

Methods (``METHODS``)
---------------------
``"exact"``
    Amanatides–Woo grid traversal in numba that jumps through free space by a one-byte field of
    safe jump lengths (the distance between the cell's square and the nearest occupied square,
    rounded down), so it stays exact to floating-point rounding (agrees with a brute-force
    slab-method reference to 1e-6 m). For the simulated lidar, and the reference of the others.
``"lut"``
    A table of ranges over free cells and ``LutParams.n_angles`` directions, answered by the pose's
    cell and the two bracketing directions (the true ray against the line through their hits),
    with an exact cast (started just before the table's hit) where the two disagree and the table
    does not flag them as one straight face; see [`racecar_sim.raycast.lut`][racecar_sim.raycast.lut] (query) and
    [`racecar_sim.raycast.lut_build`][racecar_sim.raycast.lut_build] (table, [`lut_table`][racecar_sim.raycast.lut_table]). For many poses (particles): about 6x the exact
    method's rays per second on the Stata basement. Building the table takes seconds and ``2 K``
    bytes per free cell, so it is cached (below).
``"march"``
    Sphere tracing on the same jump field: steps of ``max(jump, MarchParams.min_step)`` cells until
    a sample lands in an occupied cell, then a bisection. Simple, but it can step over a corner at
    a grazing angle, and it is *slower* than ``"exact"`` (about 0.6x): the fixed steps near walls
    cost more than exact cell steps. Kept as the plain approximate reference.

Every method runs on the calling thread below
`PARALLEL_MIN_RAYS` rays per cast (one lidar scan), and in
chunks over numba's threads above it (``RayCaster(..., parallel=...)`` overrides).

Error of the approximate methods (absolute, vs ``"exact"``, default parameters, 1500 poses uniform
in free space, 100 beams over the full turn, ``max_range`` 10 m). Bounds are checked by
``tests/test_raycast.py``; ``scripts/bench_raycast.py`` measures them on the full maps:

=========  ==================================  ======================  ======================
method     map                                 mean: measured (bound)  p99: measured (bound)
=========  ==================================  ======================  ======================
``lut``    Stata basement, 0.05 m              0.008 m (0.02 m)        0.056 m (0.10 m)
``lut``    Stata, densest 500x500-cell window  0.005 m (0.02 m)        0.050 m (0.10 m)
``lut``    test rooms, 0.05 m                  0.009 m (0.02 m)        0.043 m (0.10 m)
``march``  Stata basement, 0.05 m              0.005 m (0.03 m)        0.060 m (0.10 m)
``march``  Stata, densest 500x500-cell window  0.005 m (0.03 m)        0.002 m (0.10 m)
``march``  test rooms, 0.05 m                  0.016 m (0.03 m)        0.051 m (0.10 m)
=========  ==================================  ======================  ======================

The largest errors (up to the full range) are rare: a thin obstacle or a corner that both table
rays, or the march steps, pass.

Caching
-------
Building a caster prepares per-map data (the jump field; for ``"lut"`` the table). It is kept in
a module-level least-recently-used cache, keyed by a hash of the occupancy grid's contents, and for
tables also the range in cells (``max_range / resolution``) and the table parameters (tables are in
the grid frame, so the origin and the query parameters ``tolerance`` and ``guide`` do not matter).
Least recently used entries are dropped while the cache holds more than `CACHE_BYTES` (the
newest entry always stays). A particle filter and an experiment script that
build casters for the same map and range therefore share one table. ``RayCaster(..., cache=False)``
bypasses it; `clear_cache()` empties it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast.kernels import (
    PARALLEL_MIN_RAYS,
    exact_rays,
    field_from_occupancy,
    grid_frame,
    march_rays,
    padded_occupancy,
)
from racecar_sim.raycast.lut import LutParams, LutTable, build_lut, lut_rays, lut_score
from racecar_sim.raycast.table_cache import CACHE_BYTES, cached, clear_cache, digest

__all__ = [
    "CACHE_BYTES",
    "METHODS",
    "LutParams",
    "MarchParams",
    "RayCaster",
    "clear_cache",
]

METHODS: tuple[str, ...] = ("exact", "lut", "march")
"""Names accepted by `RayCaster`'s ``method``."""

_DTYPES = (np.dtype(np.float64), np.dtype(np.float32))


@dataclass(frozen=True)
class MarchParams:
    """Parameters of the ``"march"`` ray casting method.

    Attributes:
        min_step: cells (fractions of the map resolution), at most 1; the shortest step near
            walls. Smaller cuts fewer corners and is slower.
        refine: bisections of the last step once a sample lands in an occupied cell; the range
            is then within ``min_step / 2 ** (refine + 1)`` cells of a wall crossing.
    """

    min_step: float = 0.5
    refine: int = 3

    def __post_init__(self) -> None:
        if not (
            isinstance(self.min_step, int | float)
            and not isinstance(self.min_step, bool)
            and 0.05 <= self.min_step <= 1.0
        ):
            raise ValueError(f"MarchParams.min_step = {self.min_step!r} must be in [0.05, 1] cells")
        if (
            not isinstance(self.refine, int)
            or isinstance(self.refine, bool)
            or not (0 <= self.refine <= 30)
        ):
            raise ValueError(f"MarchParams.refine = {self.refine!r} must be an integer in [0, 30]")


# ---------------------------------------------------------------------- caster
class RayCaster:
    """Casts rays from poses on an occupancy map.

    Args:
        occupancy_map: the map (world frame defined by its origin).
        max_range: metres; ranges are clipped to it.
        method: one of `METHODS`.
        lut: parameters of ``"lut"`` (defaults if None).
        march: parameters of ``"march"`` (defaults if None).
        dtype: float64 (default) or float32 for the returned ranges (float32 halves their memory;
            it is not faster, the kernels compute in float64).
        cache: share prepared data (field, table) through the module-level cache.
        parallel: spread rays over numba's threads; None (default) does so from
            `PARALLEL_MIN_RAYS` rays per cast.

    Raises:
        ValueError: unknown method or dtype, max_range not a positive finite number, parameters
            of the wrong type.
    """

    def __init__(
        self,
        occupancy_map: OccupancyMap,
        max_range: float,
        method: str = "exact",
        *,
        lut: LutParams | None = None,
        march: MarchParams | None = None,
        dtype: type | np.dtype | str = np.float64,
        cache: bool = True,
        parallel: bool | None = None,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"unknown ray casting method {method!r}; choose one of {METHODS}")
        if not isinstance(occupancy_map, OccupancyMap):
            raise ValueError(f"occupancy_map must be an OccupancyMap, got {type(occupancy_map)}")
        if (
            not isinstance(max_range, int | float | np.floating | np.integer)
            or isinstance(max_range, bool)
            or not (max_range > 0 and math.isfinite(max_range))
        ):
            raise ValueError(f"max_range must be a positive number of metres, got {max_range!r}")
        if lut is not None and not isinstance(lut, LutParams):
            raise ValueError(f"lut must be a LutParams, got {type(lut).__name__}")
        if march is not None and not isinstance(march, MarchParams):
            raise ValueError(f"march must be a MarchParams, got {type(march).__name__}")
        try:
            out_dtype = np.dtype(dtype)
        except TypeError as exc:
            raise ValueError(f"dtype must be float64 or float32, got {dtype!r}") from exc
        if out_dtype not in _DTYPES:
            raise ValueError(f"dtype must be float64 or float32, got {out_dtype}")
        self.map = occupancy_map
        self.max_range = float(max_range)
        self.method = method
        self.lut_params = lut or LutParams()
        self.march_params = march or MarchParams()
        self.dtype = out_dtype
        self.parallel = parallel
        res = occupancy_map.resolution
        self._max_cells = self.max_range / res
        self._beam_memo: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        content = digest(occupancy_map.occupied)
        self._field: np.ndarray = cached(
            ("field", content), lambda: field_from_occupancy(occupancy_map.occupied), cache
        )
        self._lut: LutTable | None = None
        if method == "lut":
            p = self.lut_params
            self._lut = cached(
                ("lut", content, self._max_cells, p.n_angles, p.sub_lines),
                lambda: build_lut(
                    padded_occupancy(occupancy_map.occupied),
                    self._field,
                    self._max_cells,
                    p.n_angles,
                    p.sub_lines,
                ),
                cache,
            )

    # ------------------------------------------------------------------ info
    @property
    def field(self) -> np.ndarray:
        """The pad-frame jump field of the exact traversal (shared through the cache; read-only use)."""
        return self._field

    @property
    def table(self) -> LutTable | None:
        """The ``"lut"`` table (shared through the cache), None for other methods."""
        return self._lut

    def __repr__(self) -> str:
        return (
            f"RayCaster(map={self.map.name!r}, max_range={self.max_range}, method={self.method!r})"
        )

    # ------------------------------------------------------------------ casting
    def grid_cells(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u, v), each (N,): the world ``poses`` (N, 3) in the casters' grid frame, in cells (the
        map frame divided by the resolution, shifted by the one-cell pad), as the casts see them."""
        gu, gv, *_ = self._grid_frame(poses)
        return gu, gv

    def _grid_frame(self, poses: np.ndarray) -> tuple[np.ndarray, ...]:
        """World poses (N, 3) -> pad-frame position in cells and map-frame heading (radians)."""
        uv = self.map.world_to_map(poses[:, :2]) / self.map.resolution + 1.0
        heading = poses[:, 2] - self.map.yaw
        return (
            np.ascontiguousarray(uv[:, 0]),
            np.ascontiguousarray(uv[:, 1]),
            heading,
            np.cos(heading),
            np.sin(heading),
        )

    def _particle_frame(self, poses: np.ndarray, offset: float) -> tuple[np.ndarray, ...]:
        """`_grid_frame()` of the points ``offset`` metres ahead of the poses, in one numba
        pass ([`kernels.grid_frame()`][kernels.grid_frame]; equal to it up to rounding, which `cast()` keeps
        bit-exact for the simulated lidar)."""
        n = poses.shape[0]
        gu, gv, heading, cos_h, sin_h = (np.empty(n) for _ in range(5))
        ox, oy = self.map.origin[0], self.map.origin[1]
        grid_frame(
            poses, float(ox), float(oy), float(self.map.yaw), float(self.map.resolution),
            float(offset), gu, gv, heading, cos_h, sin_h,
        )  # fmt: skip
        return gu, gv, heading, cos_h, sin_h

    def _beam_directions(self, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """cos and sin of the beam angles, remembered for the last angles seen.

        A lidar or a sensor model casts the same beams every call; comparing 1080 angles is about
        ten times cheaper than their cos and sin.
        """
        memo = self._beam_memo
        if memo is not None and memo[0].shape == angles.shape and np.array_equal(memo[0], angles):
            return memo[1], memo[2]
        cos_a, sin_a = np.cos(angles), np.sin(angles)
        self._beam_memo = (angles.copy(), cos_a, sin_a)
        return cos_a, sin_a

    def cast(self, poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """Ranges (N, M) in metres, of the caster's dtype.

        Args:
            poses: (N, 3) or (3,) world [x, y, theta] (metres, radians).
            angles: (M,) beam angles relative to each pose's heading (radians).

        Raises:
            ValueError: poses not of shape (N, 3) or (3,), angles not 1-D, non-finite values.
        """
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim == 1:
            poses = poses[None, :]
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses must have shape (N, 3) or (3,), got {poses.shape}")
        angles = np.asarray(angles, dtype=np.float64)
        if angles.ndim > 1:
            raise ValueError(f"angles must be a 1-D array, got shape {angles.shape}")
        angles = np.ascontiguousarray(angles.reshape(-1))
        if not np.isfinite(poses).all():
            raise ValueError("poses must be finite (found NaN or inf)")
        if not np.isfinite(angles).all():
            raise ValueError("angles must be finite (found NaN or inf)")
        out = np.empty((poses.shape[0], angles.shape[0]), dtype=self.dtype)
        if out.size == 0:
            return out
        gu, gv, heading, cos_h, sin_h = self._grid_frame(poses)
        cos_a, sin_a = self._beam_directions(angles)
        res = self.map.resolution
        max_t = self._max_cells
        parallel = self.parallel if self.parallel is not None else out.size >= PARALLEL_MIN_RAYS
        if self.method == "exact":
            exact_rays(
                self._field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t, res, self.max_range, out,
                parallel,
            )  # fmt: skip
        elif self.method == "march":
            p = self.march_params
            march_rays(
                self._field, gu, gv, cos_h, sin_h, cos_a, sin_a, max_t,
                float(p.min_step), int(p.refine), res, self.max_range, out, parallel,
            )  # fmt: skip
        else:
            assert self._lut is not None
            p = self.lut_params
            lut_rays(
                self._lut, p.tolerance / res, p.guide / res, self._field,
                gu, gv, heading, cos_h, sin_h, angles, cos_a, sin_a,
                max_t, res, self.max_range, out, parallel, p.sort_extent / res,
            )  # fmt: skip
        return out

    def cast_score(
        self,
        poses: np.ndarray,
        angles: np.ndarray,
        rows: np.ndarray,
        per_metre: float,
        offset: float = 0.0,
        terms: np.ndarray | None = None,
    ) -> np.ndarray:
        """(N,) ``sum_b rows[b, round(clip(range_ib * per_metre, 0, W - 1))]`` over the beams.

        The same ranges as `cast()` (metres, float64) looked up in a per-beam score table
        ``rows`` (M, W) float64, e.g. a sensor model's log-likelihood row for each beam's measured
        range. The ``"lut"`` method casts and scores in one pass without storing the (N, M) ranges;
        the others cast, then score. ``offset``: metres; the rays start that far ahead of each
        pose along its heading (a lidar's mount) instead of at the pose. ``terms``: an (N, M)
        float64 array that receives each ray's term of the sum, when given.

        Raises:
            ValueError: as `cast()`; rows not (M, W) for the M angles; terms not (N, M) float64.
        """
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim == 1:
            poses = poses[None, :]
        angles = np.ascontiguousarray(np.asarray(angles, dtype=np.float64).reshape(-1))
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[0] != angles.shape[0] or rows.shape[1] < 1:
            raise ValueError(f"rows must have shape ({angles.shape[0]}, W), got {rows.shape}")
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses must have shape (N, 3) or (3,), got {poses.shape}")
        if not math.isfinite(offset):
            raise ValueError(f"offset must be a finite number of metres, got {offset!r}")
        if terms is not None and (
            terms.shape != (poses.shape[0], angles.shape[0]) or terms.dtype != np.float64
            or not terms.flags.c_contiguous
        ):
            raise ValueError(f"terms must be a C-contiguous float64 array of shape "
                             f"({poses.shape[0]}, {angles.shape[0]}), got {terms.shape}")  # fmt: skip
        if self.method != "lut" or self.dtype != np.float64:
            if offset != 0.0:
                th = poses[:, 2]
                poses = np.column_stack(
                    [poses[:, 0] + offset * np.cos(th), poses[:, 1] + offset * np.sin(th), th]
                )
            ranges = self.cast(poses, angles).astype(np.float64, copy=False)
            top = rows.shape[1] - 1
            d = np.floor(np.clip(ranges * per_metre, 0.0, top) + 0.5).astype(np.int64)
            each = rows[np.arange(rows.shape[0])[None, :], d]
            if terms is not None:
                terms[:] = each
            return each.sum(axis=1)
        if not (np.isfinite(poses).all() and np.isfinite(angles).all()):
            raise ValueError("poses and angles must be finite (found NaN or inf)")
        out = np.empty(poses.shape[0], dtype=np.float64)
        if out.size == 0:
            return out
        if angles.size == 0:
            out[:] = 0.0
            return out
        gu, gv, heading, cos_h, sin_h = self._particle_frame(poses, offset)
        cos_a, sin_a = self._beam_directions(angles)
        res = self.map.resolution
        rays = poses.shape[0] * angles.shape[0]
        parallel = self.parallel if self.parallel is not None else rays >= PARALLEL_MIN_RAYS
        assert self._lut is not None
        p = self.lut_params
        lut_score(
            self._lut, p.tolerance / res, p.guide / res, self._field,
            gu, gv, heading, cos_h, sin_h, angles, cos_a, sin_a,
            self._max_cells, res, self.max_range, rows, float(per_metre), out, parallel,
            p.sort_extent / res, terms,
        )  # fmt: skip
        return out
