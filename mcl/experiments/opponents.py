"""Stand-in opponents for the localization experiment: car-sized boxes driving ahead of the car.

`OpponentsScenario` keeps ``n`` unmapped boxes of a car's footprint (``length x width``
metres) on the loop a few metres ahead of the car (``gaps``, metres of arc length from the car's
rear axle to each box's centre), facing along the loop, in the car's own lane: they move with the
car, so the sectors they shadow stay in front of it for the whole drive, as opponents driving
close ahead at the car's speed do. They are the env's obstacle boxes (``obstacles={"boxes": n}``,
[`racecar_sim.world.obstacles`][racecar_sim.world.obstacles]), placed before every step, so the lidar sees them exactly (their
edges cut the beams before the lidar's noise is drawn) and the filter's map does not.

The loop is [`mcl.agents.track.track_for_map()`][mcl.agents.track.track_for_map] of the env's map; the direction along it is the
car's (the sign of the cosine between the car's heading and the loop's).

Frames: world (metres, radians).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mcl.agents.track import Track, track_for_map
from mcl.wrappers.localization import TRACKING_INIT_SPREAD

__all__ = ["OpponentsScenario", "box_corners"]

CAR_LENGTH = 0.55
"""Metres, the opponents' footprint length (the default car's)."""
CAR_WIDTH = 0.30
"""Metres, the opponents' footprint width."""


def box_corners(centre: np.ndarray, heading: float, length: float, width: float) -> np.ndarray:
    """(4, 2) world corners of a ``length x width`` box centred at ``centre`` facing ``heading``."""
    c, s = math.cos(heading), math.sin(heading)
    local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64) * [
        length / 2,
        width / 2,
    ]
    rot = np.array([[c, -s], [s, c]])
    return np.asarray(centre, dtype=np.float64) + local @ rot.T


class OpponentsScenario:
    """Tracking (start around the truth) with ``n`` car-sized boxes held ``gaps`` metres ahead.

    Args:
        n: opponents (0 = tracking alone; the env must have ``obstacles={"boxes": n}`` boxes).
        gaps: metres of loop arc length from the car's rear axle to each opponent's centre (the
            first ``n`` are used).
        length, width: metres, the opponents' footprint.
        init_spread: standard deviations (x m, y m, theta rad) of the initial cloud.
        track: the loop (default: ``track_for_map`` of the env's map, found at the first step).

    ``outcome()``: ``opponents`` (n) and ``gaps`` (the gaps used, metres).
    """

    name = "opponents"

    def __init__(
        self,
        n: int = 1,
        gaps: tuple[float, ...] = (2.0, 3.2, 4.4),
        length: float = CAR_LENGTH,
        width: float = CAR_WIDTH,
        init_spread: tuple[float, float, float] = TRACKING_INIT_SPREAD,
        track: Track | None = None,
    ) -> None:
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"OpponentsScenario.n = {n!r} must be a non-negative integer")
        gaps = tuple(float(g) for g in gaps)
        if len(gaps) < n or not all(math.isfinite(g) and g > 0 for g in gaps):
            raise ValueError(f"OpponentsScenario.gaps = {gaps!r}: need {n} positive metres")
        for label, value in (("length", length), ("width", width)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"OpponentsScenario.{label} = {value!r} must be positive metres")
        self.n = n
        self.gaps = gaps[:n]
        self.length, self.width = float(length), float(width)
        self.init_spread = tuple(float(v) for v in init_spread)
        self.track = track

    def reset_options(self) -> dict[str, Any]:
        """Start around the truth with ``init_spread``."""
        return {"init": "pose", "init_spread": self.init_spread}

    def poses(self, car_pose: np.ndarray) -> np.ndarray:
        """(n, 3) world poses [x, y, heading] of the opponents' centres for the car at ``car_pose``."""
        assert self.track is not None
        s, _ = self.track.project(car_pose[:2])
        forward = math.cos(car_pose[2] - self.track.heading_at(s)) >= 0.0
        sign = 1.0 if forward else -1.0
        out = np.empty((self.n, 3))
        for k, gap in enumerate(self.gaps):
            sk = s + sign * gap
            out[k, :2] = self.track.point_at(sk)
            out[k, 2] = self.track.heading_at(sk) + (0.0 if forward else math.pi)
        return out

    def before_step(self, env: Any, step: int, time: float, rng: np.random.Generator) -> None:
        """Put the boxes ``gaps`` ahead of the car along the loop."""
        if self.n == 0:
            return
        inner = env.unwrapped
        obstacles = inner.obstacles
        if obstacles is None or len(obstacles.boxes) < self.n:
            raise ValueError(
                f"OpponentsScenario needs the env setting obstacles={{'boxes': {self.n}}}"
            )
        if self.track is None:
            self.track = track_for_map(inner.map.name)
        for k, pose in enumerate(self.poses(np.asarray(inner.pose, dtype=np.float64))):
            obstacles.move_box(k, box_corners(pose[:2], pose[2], self.length, self.width))

    def outcome(self) -> dict[str, Any]:
        """See the class docstring."""
        return {"opponents": self.n, "gaps": list(self.gaps)}
