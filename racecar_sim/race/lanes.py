"""Where a car fits across a track: the lateral offsets from the centerline its box keeps clear of
the track's edges, and how far ahead a given offset stays clear.

A car driving ``o`` metres left of the centerline (its rear axle's lateral offset, a car ``width``
wide, facing along the track) fits at arc length ``s`` when ``-right(s) + width / 2 + margin <= o <=
left(s) - width / 2 - margin`` (the track's free widths,
[Track.width_at][racecar_sim.world.track.Track.width_at]).
[LaneRoom][racecar_sim.race.lanes.LaneRoom] samples those bounds along the track once, so that a
driver asks "how far ahead does each of these offsets fit" with one numpy expression per step.
"""

from __future__ import annotations

import math

import numpy as np

from racecar_sim.world.track import Track

__all__ = ["LaneRoom"]


class LaneRoom:
    """The lateral room of ``track`` for a car ``width`` metres wide keeping ``margin`` metres
    from the edges, sampled every ``spacing`` metres along the track.

    A track without widths (``Track.widths`` None) has room everywhere; give it its widths first
    ([with_widths][racecar_sim.world.track.with_widths]).

    Attributes:
        low, high: (K,) metres, the smallest and largest lateral offset (left positive) at which
            the car fits at sample ``k`` (arc length ``k * spacing``); ``low > high`` where it
            does not fit beside the centerline at all.
    """

    def __init__(self, track: Track, width: float, margin: float, spacing: float = 0.25) -> None:
        if not (width > 0 and margin >= 0 and spacing > 0):
            raise ValueError(
                f"LaneRoom: width {width!r} and spacing {spacing!r} must be positive metres, "
                f"margin {margin!r} non-negative"
            )
        self.track = track
        n = max(int(math.ceil(track.length / spacing)), 1)
        self.spacing = track.length / n
        s = np.arange(n) * self.spacing
        widths = np.array([track.width_at(v) for v in s])  # inf where the track has no widths
        inset = width / 2 + margin
        self.low = -widths[:, 0] + inset
        self.high = widths[:, 1] - inset

    def reach(self, s: float, offsets: np.ndarray, horizon: float) -> np.ndarray:
        """Metres ahead of arc length ``s`` over which each lateral offset of ``offsets`` (M,)
        fits, up to ``horizon`` metres (``horizon`` where it fits all the way, 0 where it does
        not fit at ``s``)."""
        offsets = np.asarray(offsets, dtype=np.float64)
        steps = max(int(math.ceil(horizon / self.spacing)), 1)
        k = (int(s / self.spacing) + np.arange(steps + 1)) % len(self.low)
        fits = (offsets[:, None] >= self.low[k]) & (offsets[:, None] <= self.high[k])
        first_out = np.where(fits.all(axis=1), steps + 1, np.argmin(fits, axis=1))
        return np.minimum(first_out * self.spacing, horizon)
