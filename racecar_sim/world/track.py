"""A race track: a closed centerline on a map, its widths, arc length along it and the start line.

A `Track` is a closed polyline of world points (metres) in driving order, with the free width
to the right and to the left of each point. It loads from f1tenth's track format (a CSV with
``x_m, y_m, w_tr_right_m, w_tr_left_m`` per row, header lines starting with ``#``; their users'
``*_centerline.csv`` files load as they are), or is derived from a loop map
([`racecar_sim.world.centerline`][racecar_sim.world.centerline]: bundled CSVs, or the midline of any
map whose free space runs round an island). The start line crosses the track at its first point; arc length ``s`` runs from there in
the driving direction. Frames: ``world`` (the map's) for the points and poses, ``car`` (x forward,
y left, origin at the rear axle) for [`Track.ahead()`][Track.ahead].
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np

from racecar_sim.file_guard import writable
from racecar_sim.maps import OccupancyMap

__all__ = [
    "LOOP_STARTS",
    "MAX_TRACK_BYTES",
    "Track",
    "centre_loop",
    "resample_polyline",
    "with_widths",
]


def resample_polyline(points: np.ndarray, spacing: float, loop: bool = False) -> np.ndarray:
    """Points (K, 2) every ``spacing`` metres along the polyline through ``points`` (world).

    With ``loop`` the polyline closes from the last point back to the first.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.isfinite(pts).all():
        raise ValueError(f"points must be finite (K >= 2, 2), got shape {pts.shape}")
    if not spacing > 0:
        raise ValueError(f"spacing must be positive metres, got {spacing}")
    if loop:
        pts = np.vstack([pts, pts[:1]])
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        raise ValueError("points must not all coincide")
    n = max(int(round(s[-1] / spacing)), 2)
    t = np.linspace(0.0, s[-1], n, endpoint=not loop)
    return np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])])


LOOP_STARTS: dict[str, tuple[float, float, float]] = {
    "basement_loop": (9.0, 2.5, 0.0),  # south hallway, driving east (island on the left)
    "office": (11.5, 6.1, 0.0),
}
"""Where the wall follower starts recording the loop of a bundled map (world x m, y m, theta)."""

_CSV_HEADER = "# x_m, y_m, w_tr_right_m, w_tr_left_m"
MAX_TRACK_BYTES = 1_000_000
"""Largest track file read (bytes), as a map's YAML: about 25,000 rows of four numbers, a
2.5 km loop at 0.1 m spacing (f1tenth's largest centerlines have a few thousand rows)."""
_SEARCH_WINDOW = 40  # segments either side of the last nearest one searched per step
_WIDTH_REACH = 4.0  # metres searched to either side for the walls when centring a loop
_ALCOVE = 2.5  # metres: openings up to twice this long beside the track do not count as track


@nb.njit(cache=True)
def _nearest(points, seg, seg_len2, xy, hint, window, out_i, out_t):
    """Per point k of ``xy`` (N, 2): the nearest segment (index, fraction along it), searching
    ``window`` segments either side of ``hint[k]`` (every segment when ``hint[k] < 0``)."""
    m = points.shape[0]
    for k in range(xy.shape[0]):
        if hint[k] < 0 or 2 * window + 1 >= m:
            lo, count = 0, m
        else:
            lo, count = hint[k] - window, 2 * window + 1
        best = np.inf
        bi, bt = 0, 0.0
        for q in range(count):
            i = (lo + q) % m
            rx = xy[k, 0] - points[i, 0]
            ry = xy[k, 1] - points[i, 1]
            t = (rx * seg[i, 0] + ry * seg[i, 1]) / seg_len2[i]
            t = min(max(t, 0.0), 1.0)
            dx = rx - t * seg[i, 0]
            dy = ry - t * seg[i, 1]
            d2 = dx * dx + dy * dy
            if d2 < best:
                best, bi, bt = d2, i, t
        out_i[k] = bi
        out_t[k] = bt


def _track_text(path: Path) -> str:
    """The text of track file ``path``, read in bounded work: a regular file of at most
    ``MAX_TRACK_BYTES`` (a device such as /dev/zero, a pipe
    or a folder is refused before reading); bytes that are not UTF-8 are replaced.

    Raises:
        ValueError: one line naming the file.
    """
    try:
        if not path.is_file():
            what = "not a regular file" if os.path.lexists(path) else "not found"
            raise ValueError(f"track file {path}: {what}")
        with open(path, "rb") as f:
            raw = f.read(MAX_TRACK_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"track file {path}: cannot read it ({exc.strerror})") from None
    if len(raw) > MAX_TRACK_BYTES:
        raise ValueError(
            f"track file {path}: more than {MAX_TRACK_BYTES:,} bytes, longer than any track"
        )
    return raw.decode("utf-8", errors="replace")


@dataclass(frozen=True, eq=False)
class Track:
    """A closed loop of world points (metres) in driving order, with its free widths.

    Attributes:
        points: (K, 2) world x, y; the segment from the last point back to the first closes it.
        widths: (K, 2) metres of free track to the right and to the left of each point (f1tenth's
            ``w_tr_right_m, w_tr_left_m``); None when unknown.
    """

    points: np.ndarray
    widths: np.ndarray | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.isfinite(pts).all():
            raise ValueError(f"Track.points must be (K >= 3, 2) finite metres, got {pts.shape}")
        nxt = np.roll(pts, -1, axis=0)
        seg = nxt - pts
        lengths = np.hypot(seg[:, 0], seg[:, 1])
        if (lengths <= 0).any():
            raise ValueError("Track.points has repeated consecutive points")
        if self.widths is not None:
            w = np.asarray(self.widths, dtype=np.float64)
            if w.shape != pts.shape or not np.isfinite(w).all() or (w < 0).any():
                raise ValueError(
                    f"Track.widths must be (K, 2) metres >= 0 like points, got {w.shape}"
                )
            object.__setattr__(self, "widths", w)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "_seg", seg)
        object.__setattr__(self, "_seg_len2", lengths**2)
        object.__setattr__(self, "_start_s", np.concatenate(([0.0], np.cumsum(lengths)[:-1])))
        object.__setattr__(self, "length", float(lengths.sum()))

    length: float = field(init=False, default=0.0)
    """Metres round the loop (set from the points)."""

    # ------------------------------------------------------------------ files
    @classmethod
    def from_csv(cls, path: str | os.PathLike[str]) -> Track:
        """A track from f1tenth's centerline format: rows ``x_m, y_m, w_tr_right_m, w_tr_left_m``
        (two columns ``x, y`` also load, widths unknown); lines starting with ``#`` are headers.
        A last row repeating the first (a closed file) is dropped.

        Raises:
            ValueError: the file is missing, not a regular file (a device, a pipe, a folder),
                longer than ``racecar_sim.world.track.MAX_TRACK_BYTES`` (1 MB) or not
                such a table; the message names the file.
        """
        path = Path(path)
        rows = [
            line
            for line in _track_text(path).splitlines()
            if line.strip() and not line.lstrip().startswith("#")
        ]
        try:
            data = np.array([[float(v) for v in r.replace(";", ",").split(",")] for r in rows])
        except ValueError:
            raise ValueError(
                f"track file {path}: rows must be numbers 'x_m, y_m, w_tr_right_m, w_tr_left_m'"
            ) from None
        if data.ndim != 2 or data.shape[1] not in (2, 4) or len(data) < 3:
            raise ValueError(
                f"track file {path}: need >= 3 rows of 2 or 4 columns, got shape {data.shape}"
            )
        keep = np.ones(len(data), dtype=np.bool_)
        keep[1:] = np.hypot(*np.diff(data[:, :2], axis=0).T) > 0  # repeated points
        data = data[keep]
        if np.hypot(*(data[-1, :2] - data[0, :2])) == 0:
            data = data[:-1]
        try:
            return cls(data[:, :2], data[:, 2:4] if data.shape[1] == 4 else None)
        except ValueError as exc:
            raise ValueError(f"track file {path}: {exc}") from None

    def to_csv(
        self, path: str | os.PathLike[str], recognise: Callable[[Path], bool] | None = None
    ) -> Path:
        """Write the track in f1tenth's centerline format (widths 0 when unknown); returns the path.

        Args:
            path: the CSV file.
            recognise: tells whether an existing ``path`` is ours to replace (as
                [writable][racecar_sim.file_guard.writable] takes it).

        Raises:
            FileExistsError: ``path`` exists outside racecar-sim's folders
                ([writable][racecar_sim.file_guard.writable]).
        """
        path = writable(path, recognise)
        widths = self.widths if self.widths is not None else np.zeros_like(self.points)
        np.savetxt(
            path,
            np.hstack([self.points, widths]),
            fmt="%.4f",
            delimiter=",",
            header=_CSV_HEADER[2:],
        )
        return path

    # ------------------------------------------------------------------ geometry
    def project(self, xy: np.ndarray) -> tuple[float, float]:
        """Arc length ``s`` (m, in [0, length)) of the loop point nearest ``xy``, and the signed
        lateral offset (m, positive when ``xy`` lies left of the driving direction)."""
        p = np.asarray(xy, dtype=np.float64)[:2]
        rel = p - self.points
        t = np.clip((rel * self._seg).sum(axis=1) / self._seg_len2, 0.0, 1.0)
        d = rel - t[:, None] * self._seg
        dist2 = (d * d).sum(axis=1)
        i = int(np.argmin(dist2))
        seg = self._seg[i]
        cross = seg[0] * rel[i, 1] - seg[1] * rel[i, 0]
        lateral = math.copysign(math.sqrt(dist2[i]), cross) if cross != 0 else 0.0
        s = float(self._start_s[i] + t[i] * math.sqrt(self._seg_len2[i]))
        return s % self.length, lateral

    def arc_lengths(
        self, xy: np.ndarray, hint: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Arc lengths ``s`` (N,) in [0, length) of the loop points nearest world points ``xy``
        (N, 2), and the nearest segments (N,) for the next call's ``hint`` (the search then
        looks only near them, so a track passing close to itself is not confused)."""
        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        hint = (
            np.full(len(xy), -1, dtype=np.int64)
            if hint is None
            else np.asarray(hint, dtype=np.int64)
        )
        idx = np.empty(len(xy), dtype=np.int64)
        frac = np.empty(len(xy))
        _nearest(self.points, self._seg, self._seg_len2, xy, hint, _SEARCH_WINDOW, idx, frac)
        s = self._start_s[idx] + frac * np.sqrt(self._seg_len2[idx])
        return np.mod(s, self.length), idx

    def locate(
        self, xy: np.ndarray, hint: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where world points ``xy`` (N, 2) are on the loop: arc lengths ``s`` (N,) in
        [0, length), signed lateral offsets (N,) (metres, positive left of the driving direction)
        and the nearest segments (N,) for the next call's ``hint`` (as
        [arc_lengths][racecar_sim.world.track.Track.arc_lengths])."""
        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        s, idx = self.arc_lengths(xy, hint)
        seg = self._seg[idx]
        rel = xy - self.points[idx]
        lateral = (seg[:, 0] * rel[:, 1] - seg[:, 1] * rel[:, 0]) / np.sqrt(self._seg_len2[idx])
        return s, lateral, idx

    def offset_point(self, s: float, lateral: float) -> np.ndarray:
        """World point (2,) ``lateral`` metres left (negative: right) of the loop at arc length
        ``s`` (metres), across the segment there."""
        i = self._segment(s)
        seg = self._seg[i] / math.sqrt(self._seg_len2[i])
        return self.point_at(s) + lateral * np.array([-seg[1], seg[0]])

    def point_at(self, s: np.ndarray | float) -> np.ndarray:
        """World points (..., 2) at arc lengths ``s`` (metres, taken modulo the length)."""
        s = np.mod(np.asarray(s, dtype=np.float64), self.length)
        i = np.clip(np.searchsorted(self._start_s, s, side="right") - 1, 0, len(self.points) - 1)
        frac = (s - self._start_s[i]) / np.sqrt(self._seg_len2[i])
        return self.points[i] + frac[..., None] * self._seg[i]

    def heading_at(self, s: float) -> float:
        """Direction of the loop (radians, world) at arc length ``s``."""
        return math.atan2(*self._seg[self._segment(s)][::-1])

    def width_at(self, s: float) -> tuple[float, float]:
        """Free metres (right, left) of the track at arc length ``s`` (inf, inf when unknown)."""
        if self.widths is None:
            return math.inf, math.inf
        w = self.widths[self._segment(s)]
        return float(w[0]), float(w[1])

    def _segment(self, s: float) -> int:
        s = float(np.mod(s, self.length))
        return int(
            np.clip(np.searchsorted(self._start_s, s, side="right") - 1, 0, len(self.points) - 1)
        )

    def ahead(self, pose: np.ndarray, s: float, distances: np.ndarray) -> np.ndarray:
        """Car-frame points (len(distances), 2) of the loop ``distances`` metres beyond ``s``,
        seen from ``pose`` = world [x, y, theta]."""
        pts = self.point_at(s + np.asarray(distances, dtype=np.float64)) - np.asarray(pose[:2])
        c, sn = math.cos(pose[2]), math.sin(pose[2])
        return np.stack([c * pts[:, 0] + sn * pts[:, 1], -sn * pts[:, 0] + c * pts[:, 1]], axis=1)

    def advance(self, s_from: float, s_to: float) -> float:
        """Signed metres from ``s_from`` to ``s_to`` the short way round (across the seam too)."""
        d = (s_to - s_from) % self.length
        return d - self.length if d > self.length / 2 else d


def _free_extent(grid: OccupancyMap, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(K, 2) free metres from each point to the first occupied cell along -normal and +normal."""
    steps = np.arange(1, int(_WIDTH_REACH / (0.5 * grid.resolution)) + 1) * 0.5 * grid.resolution
    out = np.empty((len(points), 2))
    for col, sign in enumerate((-1.0, 1.0)):
        probe = points[:, None, :] + sign * steps[None, :, None] * normals[:, None, :]
        blocked = ~grid.is_free(probe)
        first = np.where(blocked.any(axis=1), blocked.argmax(axis=1), len(steps) - 1)
        out[:, col] = steps[first] - 0.5 * grid.resolution
    return out


def _rolling_min(values: np.ndarray, half: int) -> np.ndarray:
    """Each row's minimum over ``half`` rows either side, round the loop: a doorway or an alcove
    shorter than the window does not widen the track."""
    stacked = np.stack([np.roll(values, k, axis=0) for k in range(-half, half + 1)])
    return stacked.min(axis=0)


def _normals(points: np.ndarray) -> np.ndarray:
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)  # to the left


def centre_loop(
    grid: OccupancyMap, loop: np.ndarray, spacing: float = 0.25, passes: int = 3
) -> Track:
    """The loop ``loop`` (K, 2) moved to the middle of the free space across it, smoothed and
    resampled every ``spacing`` metres, with its free widths measured on ``grid``."""
    pts = np.asarray(loop, dtype=np.float64)
    for _ in range(passes):
        normals = _normals(pts)
        ext = _rolling_min(_free_extent(grid, pts, normals), int(_ALCOVE / spacing))
        pts = pts + 0.5 * (ext[:, 1] - ext[:, 0])[:, None] * normals
        kernel = np.ones(7) / 7.0  # circular moving average over ~1.5 m
        padded = np.vstack([pts[-3:], pts, pts[:3]])
        pts = np.stack([np.convolve(padded[:, c], kernel, mode="valid") for c in range(2)], axis=1)
        pts = resample_polyline(pts, spacing, loop=True)
    ext = _rolling_min(_free_extent(grid, pts, _normals(pts)), int(_ALCOVE / spacing))
    return Track(pts, np.stack([ext[:, 0], ext[:, 1]], axis=1))


def with_widths(track: Track, grid: OccupancyMap) -> Track:
    """``track`` itself when its widths are known, else the same points with their free widths
    measured on ``grid`` as ``centre_loop`` measures them
    (openings beside the track shorter than about 5 m do not count)."""
    if track.widths is not None:
        return track
    spacing = track.length / len(track.points)
    half = max(1, int(_ALCOVE / spacing))
    ext = _rolling_min(_free_extent(grid, track.points, _normals(track.points)), half)
    return Track(track.points, ext)
