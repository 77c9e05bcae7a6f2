"""The car's turn measured by its scans alone, and the filter's check that its estimate turned with
the car.

Where the map is out of date the scan can hold a wrong heading against the car's turn: in the
honest world of ``docs/localization_changing_world.md``, held-out clean seed 34 backs and turns
round at the east end of a corridor whose walls the rebuilt basement moved; at the estimate's
place, 0.7 m beside the car, the old map fits the scan best unturned, every scan takes back the
turn the odometry gives, and the estimate, facing the wrong way, drives off 20 m. The car's own
scans know better: two scans a quarter of a second apart, matched to each other, say how far the
car turned, whatever the map says.

[TurnCheck][mcl.filter.scan_turn.TurnCheck] keeps a keyframe scan and the odometry's motion since.
Every ``keyframe_scans`` scans the newest scan is matched to the keyframe
([match_turn][mcl.filter.scan_turn.match_turn]): the car's motion is the odometry's with its
forward travel (the learned scale applied) times one of a few shares (0 to 1.1: a pinned car's
wheels spin), its sideways
motion moved by up to ``lateral`` metres and its turn by up to ``turn_range`` radians; the turn
that best scores the keyframe's points (``beams`` of them) against the newest scan is the scans'
turn. A match counts only when its score is at least ``min_score`` and the best turn is not on the
grid's edge; a keyframe whose match does not count is left out of all three sums below. Over the last ``window_s`` seconds of counted matches, the turns of the scans, of the
odometry and of the filter's estimate are compared. When the scans and the odometry agree within
``agree`` radians (two sources that need no map), the car turned by more than ``bound`` and the
estimate by at least ``bound`` less (and differs from the odometry by more than ``bound``), the
estimate missed the car's turn, and the filter turns every particle by the scans' turn minus the
estimate's. Only a missed turn counts: an estimate that turns by itself while the car drives
straight is the scan mending a heading that was wrong (honest clean seed 36 at 18-20 s: 0.6 rad
off, mended within half a second; a check that judged any difference turned it back, and the
estimate drove off 23 m). Where the map is right, a wrong turn given to the cloud is taken back
by the next scans (three turns of 0.5-0.6 rad given on purpose to held drives cost 0-0.1 m of
mean error).

Frames and units: car frame (x forward, y left, origin at the rear axle), lidar frame (its mount
pose in the car frame); metres, radians, seconds.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numba as nb
import numpy as np

from mcl.filter.angles import wrap_angle
from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.scan_continuity import compose, even_subset
from mcl.filter.scan_scale import lidar_motion, point_score, scan_points
from racecar_sim.settings.validation import check_number

__all__ = ["TurnCheck", "TurnCheckParams", "match_turn"]

FORWARD_SHARES = np.array([0.0, 0.5, 0.9, 1.0, 1.1])
"""Shares of the odometry's forward travel (the learned scale applied) tried by a match: 0 for a
pinned car whose wheels spin, a half for one that slips, and 10 % either way for the wheels'
noise and a scale not yet learned."""


@dataclass(frozen=True)
class TurnCheckParams:
    """Settings of the turn check (module docstring).

    Attributes:
        enabled: run the check (False: the filter never turns its cloud by it).
        keyframe_scans: scans between a keyframe and the scan matched to it.
        beams: points of the keyframe matched (evenly spaced).
        turn_range: radians; the matched turn lies within this of the odometry's.
        lateral: metres; the matched sideways motion lies within this of the odometry's.
        tolerance: metres; the width of a point's score (the fine grid; the coarse one doubles
            it), plus ``tolerance_per_m`` per metre of range.
        tolerance_per_m: metres of width per metre of range.
        min_score: the least coarse score (a share of the points, 0-1) of a match that counts.
        window_s: seconds of counted matches over which the turns are compared.
        agree: radians; the scans' and the odometry's turns over the window agree within this.
        bound: radians; the car turned by more than this, the estimate by at least this less,
            and the estimate's turn differs from the odometry's by more than this: turn the
            cloud.
    """

    enabled: bool = True
    keyframe_scans: int = 10
    beams: int = 100
    turn_range: float = 0.5
    lateral: float = 0.03
    tolerance: float = 0.05
    tolerance_per_m: float = 0.01
    min_score: float = 0.55
    window_s: float = 2.0
    agree: float = 0.3
    bound: float = 0.5

    def __post_init__(self) -> None:
        owner = "TurnCheckParams"
        for name in ("turn_range", "tolerance", "window_s", "agree", "bound"):
            object.__setattr__(
                self, name, check_number(owner, name, getattr(self, name), low=0.0, low_open=True)
            )
        for name in ("lateral", "tolerance_per_m"):
            object.__setattr__(self, name, check_number(owner, name, getattr(self, name), low=0.0))
        object.__setattr__(
            self, "min_score", check_number(owner, "min_score", self.min_score, low=0.0, high=1.0)
        )
        for name, low in (("keyframe_scans", 1), ("beams", 20)):
            object.__setattr__(
                self, name, check_number(owner, name, getattr(self, name), low=low, integer=True)
            )


@nb.njit(cache=True)
def _best_turn(px, py, after, a0, step, odometry, mount, max_range, tol, tol_per_m,
               shares, turn_step, n_turn, side_step, n_side):  # fmt: skip
    best, best_j, best_k, best_i = -1.0, 0, 0, 0
    for i in range(shares.shape[0]):
        for j in range(-n_turn, n_turn + 1):
            for k in range(-n_side, n_side + 1):
                mx, my, mt = lidar_motion(odometry[0] * shares[i], odometry[1] + side_step * k,
                                          odometry[2] + turn_step * j, mount)  # fmt: skip
                value = point_score(px, py, after, a0, step, mx, my, mt, max_range, tol, tol_per_m)
                if value == value and value > best:
                    best, best_j, best_k, best_i = value, j, k, i
    return best, best_j, best_k, best_i


@nb.njit(cache=True)
def match_turn(before, before_angles, after, after_angles, odometry, mount, max_range,
               turn_range, lateral, tolerance, tolerance_per_m):  # fmt: skip
    """The car's turn (radians) that best matches two scans, and the match's coarse score (a
    share of the points, 0-1): NaNs when too few points could be compared or the best turn lies
    on the coarse grid's edge (module docstring).

    Args:
        before (np.ndarray): (K,) ranges of the earlier scan, metres (``max_range`` or more, or
            NaN: no return).
        before_angles (np.ndarray): (K,) their bearings in the lidar frame, radians.
        after (np.ndarray): (N,) ranges of the later scan, metres.
        after_angles (np.ndarray): (N,) its bearings, evenly spaced and ascending, radians.
        odometry (np.ndarray): the car's motion between the scans by its odometry, in the earlier
            car frame [x m, y m, theta rad].
        mount (np.ndarray): the lidar's pose in the car frame [x m, y m, theta rad].
        max_range (float): metres.
        turn_range (float): radians the turn may differ from the odometry's.
        lateral (float): metres the sideways motion may differ from the odometry's.
        tolerance (float): metres of score width (fine grid; the coarse grid doubles it).
        tolerance_per_m (float): extra metres of width per metre of range.
    """
    px, py, a0, step = scan_points(before, before_angles, after_angles, max_range)
    turn_step, side_step = 0.02, 0.03
    n_turn = max(1, int(math.floor(turn_range / turn_step + 1e-9)))
    n_side = int(math.floor(lateral / side_step + 1e-9))
    score, j, k, i = _best_turn(px, py, after, a0, step, odometry, mount, max_range,
                                2.0 * tolerance, tolerance_per_m, FORWARD_SHARES,
                                turn_step, n_turn, side_step, n_side)  # fmt: skip
    if score < 0.0 or abs(j) == n_turn:
        return np.nan, np.nan
    coarse = np.array([odometry[0], odometry[1] + side_step * k, odometry[2] + turn_step * j])
    shares = FORWARD_SHARES[i:i + 1]
    fine, jf, _, _ = _best_turn(px, py, after, a0, step, coarse, mount, max_range, tolerance,
                                tolerance_per_m, shares, 0.004, 5, side_step / 2, 2)  # fmt: skip
    if fine < 0.0:
        return np.nan, np.nan
    return coarse[2] + 0.004 * jf, score


class TurnCheck:
    """The turn check of one filter (module docstring): fed the odometry every step
    (``advance``) and the scans as they come (``due``, ``observe``).

    Args:
        params: the settings.

    Attributes:
        corrections: times the check turned the cloud since the start.
        matches: keyframe matches made; ``counted``: those that counted.
    """

    def __init__(self, params: TurnCheckParams | None = None) -> None:
        self.params = params or TurnCheckParams()
        self.corrections = 0
        self.matches = 0
        self.counted = 0
        self._keyframe: np.ndarray | None = None
        self._keyframe_angles: np.ndarray | None = None
        self._motion = np.zeros(3)  # odometry since the keyframe, its car frame [x, y, theta]
        self._scans = 0  # scans since the keyframe
        self._clock = 0.0  # seconds since the start
        # counted matches: (time s, the scans' turn, the odometry's turn, the estimate's turn)
        self._history: deque[tuple[float, float, float, float]] = deque()
        self._estimate_heading = math.nan  # the estimate's heading at the keyframe

    def restart(self) -> None:
        """Forget the keyframe and the window (a new belief, a cloud moved elsewhere)."""
        self._keyframe = None
        self._history.clear()

    def advance(self, twist: np.ndarray, dt: float) -> None:
        """One step of odometry ``twist`` [vx m/s, vy m/s, omega rad/s] (car frame, as the filter
        predicts with it: its learned scale applied) held ``dt`` seconds."""
        self._clock += dt
        if self._keyframe is not None:
            self._motion = compose(self._motion, twist_to_odometry(twist, dt))

    def due(self) -> bool:
        """Whether the next scan is matched (or starts the first keyframe): give it to
        `observe()` with the estimate's heading, else call `skip_scan()`."""
        return self.params.enabled and (
            self._keyframe is None or self._scans + 1 >= self.params.keyframe_scans
        )

    def skip_scan(self) -> None:
        """A scan came that is not `due()`."""
        self._scans += 1

    def observe(self, ranges: np.ndarray, angles: np.ndarray, mount: np.ndarray,
                max_range: float, heading: float) -> float:  # fmt: skip
        """A `due()` scan (``ranges`` metres at ``angles`` radians, lidar frame, ascending; the
        lidar's ``mount`` pose in the car frame) and the estimate's world ``heading`` (radians);
        returns the turn (radians) to give every particle, 0 if none."""
        p = self.params
        z = np.asarray(ranges, dtype=np.float64).reshape(-1)
        if self._keyframe is None or z.size != self._keyframe.size:
            self._new_keyframe(z, angles, heading)
            return 0.0
        idx = even_subset(z.size, p.beams)
        assert self._keyframe_angles is not None
        turn, score = match_turn(
            self._keyframe[idx], self._keyframe_angles[idx], z, np.asarray(angles, np.float64),
            self._motion.copy(), np.asarray(mount, np.float64), float(max_range),
            p.turn_range, p.lateral, p.tolerance, p.tolerance_per_m,
        )  # fmt: skip
        self.matches += 1
        estimate_turn = float(wrap_angle(heading - self._estimate_heading))
        odometry_turn = float(self._motion[2])
        if score >= p.min_score:  # NaN never counts; an uncounted keyframe leaves all three sums
            self.counted += 1
            self._history.append((self._clock, float(turn), odometry_turn, estimate_turn))
        turn = self._judge()
        self._new_keyframe(z, angles, heading + turn)  # the heading the cloud will have
        return turn

    def _judge(self) -> float:
        """The turn to give the cloud when the window says the estimate missed a turn of the car
        (module docstring), else 0."""
        p, history = self.params, self._history
        while history and history[0][0] < self._clock - p.window_s - 1e-9:
            history.popleft()
        if not history or history[0][0] > self._clock - p.window_s + 0.5:
            return 0.0  # the window is not yet full
        scans, odometry, estimate = (sum(h[i] for h in history) for i in (1, 2, 3))
        agreed = abs(scans - odometry) < p.agree
        missed = abs(estimate) <= abs(scans) - p.bound  # the car turned, the estimate less
        if agreed and missed and abs(estimate - odometry) > p.bound:
            self.corrections += 1
            history.clear()
            return scans - estimate
        return 0.0

    def _new_keyframe(self, ranges: np.ndarray, angles: np.ndarray, heading: float) -> None:
        self._keyframe = ranges.copy()
        self._keyframe_angles = np.asarray(angles, dtype=np.float64).copy()
        self._motion = np.zeros(3)
        self._scans = 0
        self._estimate_heading = float(heading)
