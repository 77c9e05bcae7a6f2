"""Wheels that turn while the car stands: the filter's check that the odometry moves a car its scans
say has not moved.

Wheel odometry reports what the wheels do. A car pinned against a wall or a chair with the motor
still pushing, a car lifted onto a stand, wheels spinning on a slick floor: the odometry says the
car drives on, and a filter that follows its odometry drives its estimate away from the car,
through walls, while every scan says the car is where it was (in the honest world of
`docs/localization_changing_world.md`, cluttered seed 9 pins itself at 53 s and the estimate
followed the spinning wheels 4 m away in 7 s).

[Standstill][mcl.filter.standstill.Standstill] keeps a reference scan and the odometry's motion
since. Once the odometry has moved the car ``min_distance`` metres or turned it ``min_turn``
radians from there, it compares the newest scan with the reference, with the two scans'
[continuity][mcl.filter.scan_continuity.both_ways] (no map involved): as the odometry says the
car moved (and that turned by ``turn_slack`` either way, the odometry's noisier part), and as if
it had not moved at all. When the car standing still explains the scans (``still_above`` of the
points seen again) better by ``margin`` than the odometry's motion in ``in_a_row`` comparisons
in a row, the car stands: the filter then predicts with no motion (its motion noise still
applies) until a later comparison says the car moves. In a corridor whose walls look the same all along, both explain the
side walls and the far ones decide: the odometry's motion wins whenever the car did move.

A car that slips moves, but less than its wheels say: pinned at one corner, it pivots slowly while
the wheels spin backwards and steer hard (cluttered seed 18 at 18-22 s: the VESC reported 0.6 m/s
and 0.8 rad/s, the car turned at 0.12 rad/s and did not move). Neither standing nor the odometry
explains its scans, so when the odometry's motion explains them poorly the check also tries
shares of it (``shares``: of the odometry's translation and, apart, of its turn), and the best
share that passes the same test is what the filter then predicts with
([motion_shares][mcl.filter.standstill.Standstill.motion_shares]); standing is the share 0, 0.

Three comparisons of 0.2 m find a pinned car after its wheels have said it drove about 0.6 m,
and the filter followed them; where the scan cannot pull the estimate back (the old map wrong
round the car), that stayed. So when the check first finds the car standing or slipping, the
filter moves its cloud back to where its estimate was at the first of those comparisons, moved
on by the share found ([take_back][mcl.filter.standstill.Standstill.take_back]). And while the car
stands, the filter does not move its particles at all, not even by its motion noise: a car that
stands has no motion to be unsure of, and noise with nothing to hold the cloud lets the scan
slide it to any place nearby that fits the old map better (held-out cluttered seed 24 of the
honest world pins itself at 17.5 s for 42 s while its wheels report 0.5-1.8 m/s: the estimate
slid 1.4 m along the corridor). A cloud that *searches* (its last correction scored with the wide
search hit: spread wider than the sensor model's ``search_start_spread``, as after a kidnap, until
it shrinks under ``search_spread``) is not held (``hold_searching``): it has no estimate to
protect, and its poses, not moving, could never come closer to a standing car. nav2 amcl does
not update its filter at all until its odometry has moved 0.25 m or turned 0.2 rad
(`update_min_d`, `update_min_a`: nav2's defaults); a car whose wheels spin would pass that gate,
which is why the check looks at the scans.

Frames and units: car frame and lidar frame (as in [mcl.filter.scan_continuity][]); metres,
radians, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mcl.filter.motion_model import twist_to_odometry
from mcl.filter.scan_continuity import both_ways, compose, invert
from racecar_sim.settings.validation import short

__all__ = ["NEAR_TIE", "Standstill", "StandstillParams"]

NEAR_TIE = 0.02
"""A share must explain this much more of the points than a smaller one to be preferred to it."""


@dataclass(frozen=True)
class StandstillParams:
    """Settings of the standstill check (module docstring).

    Attributes:
        enabled: check, and predict with no motion while the car stands (False: always follow the
            odometry).
        min_distance: metres the odometry must have moved the car since the reference scan before
            the two are compared.
        min_turn: radians the odometry must have turned the car, the same way.
        still_above: the continuity with no motion must be at least this for the car to stand.
        margin: ... and exceed the continuity with the odometry's motion by this much.
        in_a_row: comparisons in a row that must find the car standing before the filter stops
            following the odometry (the first that finds it moving ends the standstill).
        take_back: when the check first finds the car standing or slipping, the cloud is moved
            rigidly so that its estimate is where it was at the first of the ``in_a_row``
            comparisons that found it, moved on by the share found of the odometry since
            ([take_back][mcl.filter.standstill.Standstill.take_back]); not when the cloud was
            moved elsewhere since (a burst's outcome kept, the search's cloud taken, a jump).
        hold_still: while the car stands (shares 0 and 0) the particles are not moved at all,
            not even by the motion model's noise (False: its noise still spreads them).
        hold_searching: ``hold_still`` also for a cloud that searches
            ([ParticleFilter.searching][mcl.filter.particle_filter.ParticleFilter]: spread wider
            than the sensor model's ``search_start_spread``, as after a kidnap, until it shrinks
            under ``search_spread``); False: a searching cloud keeps its motion noise while the
            car stands, so that its poses still refine.
        beams: points of each scan compared.
        tolerance: metres within which a point counts as seen again.
        tolerance_per_m: extra metres of tolerance per metre of range.
        shares: the shares of the odometry's translation, and apart of its turn, tried as the
            car's motion (each pair of them); 0 (standing) must be one. Empty: only standing.
        turn_slack: radians; before a share is tried, the odometry's motion is also tried turned
            this much more and less (its turn rate is the noisier part), and the best of the
            three is what a share must beat.
    """

    enabled: bool = True
    min_distance: float = 0.2
    min_turn: float = 0.2
    still_above: float = 0.6
    margin: float = 0.3
    in_a_row: int = 3
    take_back: bool = True
    hold_still: bool = True
    hold_searching: bool = False
    beams: int = 100
    tolerance: float = 0.05
    tolerance_per_m: float = 0.01
    shares: tuple[float, ...] = (0.0, 0.25, 0.5)
    turn_slack: float = 0.03

    def __post_init__(self) -> None:
        for name in ("enabled", "take_back", "hold_still", "hold_searching"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"StandstillParams.{name} = {short(getattr(self, name))} must be a bool"
                )
        for name in ("beams", "in_a_row"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(
                    f"StandstillParams.{name} = {short(value)} must be a positive integer"
                )
        if isinstance(self.beams, bool) or not isinstance(self.beams, int) or self.beams < 10:
            raise ValueError(
                f"StandstillParams.beams = {short(self.beams)} must be an integer >= 10"
            )
        for name in ("min_distance", "min_turn", "still_above", "margin", "tolerance",
                     "tolerance_per_m", "turn_slack"):  # fmt: skip
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value) and value >= 0)
            ):
                raise ValueError(f"StandstillParams.{name} = {short(value)} must be a number >= 0")
            object.__setattr__(self, name, float(value))
        if self.min_distance <= 0 or self.min_turn <= 0:
            raise ValueError("StandstillParams: min_distance and min_turn must be > 0")
        shares = self.shares
        if isinstance(shares, list):
            shares = tuple(shares)
        if not isinstance(shares, tuple) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and 0 <= v < 1 for v in shares
        ):
            raise ValueError(
                f"StandstillParams.shares = {short(self.shares)} must be numbers in [0, 1)"
            )
        object.__setattr__(self, "shares", tuple(float(v) for v in shares) or (0.0,))
        if 0.0 not in self.shares:
            raise ValueError("StandstillParams.shares must hold 0 (the car standing)")
        if self.still_above > 1 or self.margin > 1:
            raise ValueError("StandstillParams: still_above and margin are fractions in [0, 1]")


def _made(run: list[tuple[np.ndarray | None, np.ndarray]], shares: np.ndarray) -> np.ndarray | None:
    """The world pose the first window of ``run`` (estimate at its reference, odometry's motion
    [dx m, dy m, dtheta rad]) ends at when each window's motion is made at ``shares`` (of
    translation, of turn); None when the first window has no estimate."""
    start = run[0][0]
    if start is None:
        return None
    a, b = shares
    pose = start
    for _, m in run:
        pose = compose(pose, np.array([a * m[0], a * m[1], b * m[2]]))
    return pose


class Standstill:
    """Whether one car stands while its wheels turn (module docstring); one per filter.

    Args:
        params: [StandstillParams][mcl.filter.standstill.StandstillParams].

    Attributes:
        n_standing: comparisons that found it standing or slipping since the start.
    """

    def __init__(self, params: StandstillParams | None = None) -> None:
        self.params = params if params is not None else StandstillParams()
        self._shares = np.ones(2)
        self._slipping = False  # asked at every prediction: kept, not worked out each time
        self.n_standing = 0
        self._in_a_row = 0
        self._motion = np.zeros(3)  # the car's motion by the odometry since the reference scan
        self._reference: tuple[np.ndarray, np.ndarray] | None = None
        self._reference_pose: np.ndarray | None = None  # the filter's estimate at it
        # (estimate at the reference, odometry's motion) of the comparisons in a row so far
        self._run: list[tuple[np.ndarray | None, np.ndarray]] = []
        self._take_back: np.ndarray | None = None

    @property
    def motion_shares(self) -> np.ndarray:
        """(2,) the shares of the odometry's translation and of its turn that the car makes, by
        the last comparisons ([1, 1]: the odometry holds; [0, 0]: the car stands)."""
        return self._shares.copy()

    @property
    def standing(self) -> bool:
        """The last comparisons found the car standing: no motion at all."""
        return not self._shares.any()

    @property
    def slipping(self) -> bool:
        """The last comparisons found the car moving less than the odometry says (or standing)."""
        return self._slipping

    def scaled(self, twist: np.ndarray) -> np.ndarray:
        """The car-frame ``twist`` [vx, vy, omega] as the car makes it: times
        [motion_shares][mcl.filter.standstill.Standstill.motion_shares]."""
        a, b = self._shares
        return np.asarray(twist, dtype=np.float64) * np.array([a, a, b])

    def restart(self) -> None:
        """Forget the reference scan and the motion since (a new belief)."""
        self._shares = np.ones(2)
        self._slipping = False
        self._in_a_row = 0
        self._motion = np.zeros(3)
        self._reference = None
        self._reference_pose = None
        self._run = []
        self._take_back = None

    def cloud_replaced(self) -> None:
        """The filter's cloud was moved to another place other than by its odometry and scans
        (a burst's outcome kept, the search's cloud taken, a jump of the scans): the estimates
        recorded so far are not ones to take back to."""
        self._reference_pose = None
        self._run = []

    def take_back(self) -> np.ndarray | None:
        """Where the estimate belongs (world pose [x m, y m, theta rad]) once the comparisons
        first found the car standing or slipping: the estimate at the first of their reference
        scans moved by the odometry's motion since at the share found. Once (then None); None
        when there is none to take back."""
        back, self._take_back = self._take_back, None
        return back

    def advance(self, twist: np.ndarray, dt: float) -> None:
        """The odometry says the car drove the car-frame ``twist`` [vx m/s, vy m/s, omega rad/s]
        for ``dt`` seconds."""
        if self.params.enabled:
            self._motion = compose(self._motion, twist_to_odometry(twist, dt))

    def due(self) -> bool:
        """Whether the next scan is taken (the first one, or the odometry has moved the car far
        enough since the reference): the caller need not work out the scan's bearings otherwise."""
        if not self.params.enabled:
            return False
        m = self._motion
        return self._reference is None or (
            math.hypot(m[0], m[1]) >= self.params.min_distance or abs(m[2]) >= self.params.min_turn
        )

    def observe(
        self,
        scan: np.ndarray,
        angles: np.ndarray,
        mount: np.ndarray,
        max_range: float,
        estimate: np.ndarray | None = None,
    ) -> bool:
        """Compare ``scan`` (metres, at bearings ``angles`` in radians, ascending, evenly spaced)
        with the reference once the odometry has moved far enough; returns
        [slipping][mcl.filter.standstill.Standstill.slipping].

        Args:
            scan: the ranges.
            angles: their bearings in the lidar frame.
            mount: the lidar's pose in the car frame [x m, y m, theta rad].
            max_range: metres; ranges at or beyond it are no return.
            estimate: the filter's world pose [x m, y m, theta rad] at this scan, for
                [take_back][mcl.filter.standstill.Standstill.take_back] (None: nothing to take
                back from this scan on).
        """
        p = self.params
        if not self.due():
            return self.slipping
        z = np.asarray(scan, dtype=np.float64).reshape(-1)
        if self._reference is None:
            self._new_reference(z, angles, estimate)
            return self.slipping
        m = self._motion
        before, before_angles = self._reference
        mount = np.asarray(mount, dtype=np.float64)
        inverse_mount = invert(mount)
        args = (p.beams, float(max_range), p.tolerance, p.tolerance_per_m)

        def explains(motion: np.ndarray) -> float:
            lidar_motion = compose(compose(inverse_mount, motion), mount)
            return both_ways(before, before_angles, z, angles, lidar_motion, *args)

        as_odometry = explains(m)
        best, best_shares = explains(np.zeros(3)), (0.0, 0.0)
        if as_odometry <= 1.0 - p.margin and p.turn_slack > 0:  # the odometry's turn, give or take
            for slack in (-p.turn_slack, p.turn_slack):
                as_odometry = max(as_odometry, explains(m + np.array([0.0, 0.0, slack])))
        if as_odometry <= 1.0 - p.margin:  # else no share can beat the odometry by the margin
            for a in p.shares:
                for b in p.shares:
                    if a or b:
                        share = explains(np.array([a * m[0], a * m[1], b * m[2]]))
                        if share > best + NEAR_TIE:
                            best, best_shares = share, (a, b)
        looks_slipping = best >= p.still_above and best - as_odometry >= p.margin
        self._in_a_row = self._in_a_row + 1 if looks_slipping else 0  # NaN compares False
        keep = max(0, len(self._run) + 1 - p.in_a_row)  # the last in_a_row windows, this one too
        window = (self._reference_pose, m.copy())
        self._run = [*self._run[keep:], window] if looks_slipping else []
        was_slipping = self._slipping
        self._shares = np.array(best_shares if self._in_a_row >= p.in_a_row else (1.0, 1.0))
        self._slipping = bool((self._shares < 1).any())
        if self._slipping and not was_slipping and p.take_back:
            self._take_back = _made(self._run, self._shares)
        self.n_standing += self.slipping
        self._new_reference(z, angles, estimate)
        self._motion = np.zeros(3)
        return self.slipping

    def _new_reference(
        self, scan: np.ndarray, angles: np.ndarray, estimate: np.ndarray | None
    ) -> None:
        """``scan`` becomes the reference the next comparison starts from, with the filter's
        ``estimate`` there."""
        self._reference = (scan.copy(), np.asarray(angles, dtype=np.float64).copy())
        self._reference_pose = None if estimate is None else np.array(estimate, dtype=float)
