"""The lidar apart from the room: which beams of a real scan show the sensor's own noise, and what
the rest says about the room.

A beam shows the *sensor* when it meets a mapped, unoccluded wall near the expected range: its
exact cast is mapped and continuous with both neighbours' (no depth edge, where a few
centimetres of pose error change the cast a lot), and it is not part of a *wide* run of short or
long returns. A run is wide when it covers ``ROOM_WIDTH`` metres or more of the surface (beams x
expected range x beam spacing): a leg, a box, a door or a pane of glass. Narrower failures (one
to a few beams) are the sensor's own (mixed pixels, speckle), and are kept in its fit.

The wide runs are the *room*: long ones are openings in the mapped walls (glass, open doors,
things moved since the map was drawn), short ones are furniture and people. Their shares and
sizes describe a scene (`racecar_sim.world.scenes`), not the sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ROOM_WIDTH",
    "BodyBlock",
    "RoomStats",
    "body_block",
    "hit_correlation",
    "room_beams",
    "room_stats",
    "sensor_beams",
    "wide_runs",
]

ROOM_WIDTH = 0.1
"""Metres of surface: a run of failures at least this wide is a thing in the room."""

_TOL = 0.15


def wide_runs(mask: np.ndarray, z_star: np.ndarray, spacing: float, width: float) -> np.ndarray:
    """bool (S, B): the beams of ``mask`` (S, B) in runs (along each row) that span ``width``
    metres or more of surface, a beam spanning ``z_star`` x ``spacing`` (expected range, metres,
    times the beam spacing, radians)."""
    s, b = mask.shape
    padded = np.zeros((s, b + 1), dtype=bool)
    padded[:, :b] = mask
    flat = padded.ravel()
    span = np.zeros((s, b + 1))
    span[:, :b] = np.nan_to_num(np.minimum(z_star, 1e3), nan=0.0, posinf=0.0) * spacing
    starts = flat & ~np.r_[False, flat[:-1]]
    ids = np.cumsum(starts) * flat  # 0 outside runs, run number (from 1) inside
    widths = np.bincount(ids, weights=span.ravel() * flat)
    wide = (widths >= width) & (np.arange(widths.size) > 0)
    return wide[ids].reshape(s, b + 1)[:, :b]


def _continuous(z_star: np.ndarray) -> np.ndarray:
    """bool (S, B): the cast is within 5 % + 2 cm of both neighbours' (no depth edge)."""
    out = np.zeros(z_star.shape, dtype=bool)
    mid = z_star[:, 1:-1]
    tol = 0.05 * mid + 0.02
    with np.errstate(invalid="ignore"):
        out[:, 1:-1] = (np.abs(mid - z_star[:, :-2]) < tol) & (np.abs(mid - z_star[:, 2:]) < tol)
    return out


def _kinds(z: np.ndarray, z_star: np.ndarray, max_range: float):
    mapped = np.isfinite(z_star) & (z_star < max_range - 1e-6)
    valid = mapped & np.isfinite(z) & (z < max_range - 1e-6)
    with np.errstate(invalid="ignore"):
        res = np.where(valid, z - z_star, np.nan)
    return mapped, valid, res


@dataclass(frozen=True)
class BodyBlock:
    """The beams the car's own body blocks (a wheel, the chassis): read closer than ``near``.

    Attributes:
        first, last: the block as fractions of the scan from its first beam, ``[first, last)``.
        probability: mean share of the scans in which a beam of the block reads the body.
        range: metres, median reading of the body.
    """

    first: float = 0.0
    last: float = 0.0
    probability: float = 0.0
    range: float = 0.06

    def mask(self, n_beams: int) -> np.ndarray:
        """bool (B,): the block's beams."""
        out = np.zeros(n_beams, dtype=bool)
        out[round(self.first * n_beams) : round(self.last * n_beams)] = True
        return out


def body_block(z: np.ndarray, near: float = 0.2, share: float = 0.3) -> BodyBlock:
    """The beams of scans ``z`` (S, B) that read closer than ``near`` metres in ``share`` of the
    scans or more, from the first such beam to the last (none: an empty block)."""
    with np.errstate(invalid="ignore"):
        close = np.isfinite(z) & (z < near)
    per_beam = close.mean(axis=0)
    idx = np.flatnonzero(per_beam >= share)
    if idx.size == 0:
        return BodyBlock()
    lo, hi = int(idx.min()), int(idx.max()) + 1
    b = z.shape[1]
    return BodyBlock(
        first=lo / b,
        last=hi / b,
        probability=float(per_beam[lo:hi].mean()),
        range=float(np.median(z[:, lo:hi][close[:, lo:hi]])),
    )


def room_beams(z: np.ndarray, z_star: np.ndarray, spacing: float, max_range: float) -> np.ndarray:
    """bool (S, B): the beams in wide runs of short or long returns (the room's)."""
    _mapped, valid, res = _kinds(z, z_star, max_range)
    with np.errstate(invalid="ignore"):
        short = valid & (res < -_TOL)
        long = valid & (res > _TOL)
    return wide_runs(short, z_star, spacing, ROOM_WIDTH) | wide_runs(
        long, z_star, spacing, ROOM_WIDTH
    )


def sensor_beams(z: np.ndarray, z_star: np.ndarray, spacing: float, max_range: float) -> np.ndarray:
    """bool (S, B): the beams that show the sensor's own noise (see the module doc)."""
    mapped = np.isfinite(z_star) & (z_star < max_range - 1e-6)
    return mapped & _continuous(z_star) & ~room_beams(z, z_star, spacing, max_range)


@dataclass(frozen=True)
class RoomStats:
    """What the room adds, as shares of the mapped beams of some scans.

    Attributes:
        openings: share in wide runs of long returns (glass, open doors).
        opening_excess: metres, mean range beyond the expected one plus 0.15 m of those returns.
        clutter: share in wide runs of short returns (furniture, people).
        clutter_ratio: median measured / expected range of those returns.
        sensor: share of the mapped beams that show the sensor (`sensor_beams()`).
    """

    openings: float
    opening_excess: float
    clutter: float
    clutter_ratio: float
    sensor: float

    def as_dict(self) -> dict[str, float]:
        """The fields by name."""
        return {k: float(getattr(self, k)) for k in self.__dataclass_fields__}


def room_stats(z: np.ndarray, z_star: np.ndarray, spacing: float, max_range: float) -> RoomStats:
    """`RoomStats` of scans ``z`` (S, B) against expected ``z_star`` (S, B), metres."""
    mapped, valid, res = _kinds(z, z_star, max_range)
    with np.errstate(invalid="ignore"):
        wl = wide_runs(valid & (res > _TOL), z_star, spacing, ROOM_WIDTH)
        ws = wide_runs(valid & (res < -_TOL), z_star, spacing, ROOM_WIDTH)
    n = max(int(mapped.sum()), 1)
    return RoomStats(
        openings=float(wl.sum() / n),
        opening_excess=float(np.mean(res[wl] - _TOL)) if wl.any() else 0.0,
        clutter=float(ws.sum() / n),
        clutter_ratio=float(np.median(z[ws] / z_star[ws])) if ws.any() else 1.0,
        sensor=float(sensor_beams(z, z_star, spacing, max_range).sum() / n),
    )


def hit_correlation(z: np.ndarray, z_star: np.ndarray, keep: np.ndarray) -> float:
    """Correlation of neighbouring beams' hit errors (both in ``keep`` and within 0.15 m), from
    robust spreads: 1 - var(e_i - e_i+1) / (2 var(e)), each variance from the median absolute
    deviation. Errors that vary smoothly along the scan (the map's walls a little off the real
    ones, what pose error remains) give values near 1; independent noise gives 0."""
    with np.errstate(invalid="ignore"):
        res = np.where(keep, z - z_star, np.nan)
        hit = keep & (np.abs(res) <= _TOL)
    pair = hit[:, :-1] & hit[:, 1:]
    e = res[hit]
    d = (res[:, 1:] - res[:, :-1])[pair]
    if e.size < 100 or d.size < 100:
        return 0.0
    sd_e = 1.4826 * np.median(np.abs(e - np.median(e)))
    sd_d = 1.4826 * np.median(np.abs(d - np.median(d)))
    return float(np.clip(1.0 - sd_d**2 / (2.0 * sd_e**2), 0.0, 0.99))
