"""A scripted racing driver that knows the other cars: it follows, passes and gives way.

[RacingDriver][racecar_sim.race.racing_driver.RacingDriver] drives pure pursuit on a line parallel
to the track's centerline, a *lane* (a lateral offset, metres, left positive), at its own top speed.
Every step it weighs the lanes ``-max_offset, ..., 0, ..., max_offset`` (``lane_step`` apart) with
what it knows of the race ([Traffic][racecar_sim.race.traffic.Traffic]: every car's place and speed
along the track, as an opponent sees them) and of the track
([LaneRoom][racecar_sim.race.lanes.LaneRoom]: where a lane fits between the track's edges):

1. **Following.** In each lane, the car ahead whose side comes closer than ``side_gap`` to the
   car's sides sets the speed by a time-headway rule: with bumper gap ``g`` and its speed
   ``v_lead``, ``v = (response v_lead + g - standstill_gap) / (response + headway)``, so at a
   steady speed ``v`` the gap is ``standstill_gap + headway v``; below ``min_gap`` it stops.
2. **Passing.** A lane free of slower cars is worth more speed; the car moves to it when the
   gain beats ``switch_cost`` per metre of lane change and ``line_cost`` per metre off the line
   it wants. It moves only into a lane that fits the track over the whole pass (the distance it
   needs to get two car lengths and a merge gap ahead of the cars it passes, at least three
   seconds of driving, at most ``horizon``), and only when no car is beside or just behind in
   the lanes it sweeps (a lane change in front of a car leaves
   ``standstill_gap + merge_headway v`` to it). On the way across, the cars ahead in the lanes
   it sweeps cap its speed so that it is out of their way (at ``lateral_speed``) before it is
   within ``min_gap`` of them.
3. **Giving way.** A car with another close behind (bumper gap within ``yield_range``), and no
   slower car within twice that ahead in its own lane, wants a line ``yield_offset`` to the side
   away from it (to the right when it is straight behind;
   where it is when there are cars close behind on both sides), so that the follower passes on
   the other side; otherwise it wants the centerline. Where the track is too narrow for two
   cars it holds its lane, and the follower stays behind. A car with a faster one beside it eases
   off by ``pass_ease``, so that the pass is over sooner.
4. **Room.** A lane that ends before the pass is done merges towards the centerline like a
   zip: the cars ahead between it and the centerline count as cars in the lane. In a lane that
   runs out the car brakes at ``brake`` to stop before the end (the centerline never runs out).
5. **Backing off.** Behind a standing car a car stops where it can still pull out round it (two
   arcs of 1.5 lookaheads' radius); one that stands closer backs off at ``reverse_speed``,
   turning its heading back along the track, to 0.3 m beyond that gap, while nothing is within
   ``standstill_gap`` behind it.
6. **Last check.** Whatever the lanes say, the car slows to stop short of any point of another
   car's box in the corridor ahead of its own box along the line it follows (half a ``side_gap``
   wider each side).

The lane chosen moves the line followed sideways at ``lateral_speed``. Rules and numbers:
[RacingRules][racecar_sim.race.racing_rules.RacingRules]. Frames: world (poses, track), track
(arc length, lateral offset), car (x forward, y left, at the rear axle).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from racecar_sim.drivers.base import as_action
from racecar_sim.params import nested
from racecar_sim.race.lanes import LaneRoom
from racecar_sim.race.racing_rules import RacingRules
from racecar_sim.race.traffic import Traffic

__all__ = ["RacingDriver"]

_TIE_BREAK = 1e-3  # m/s per metre left: of two equal lanes the left one (pass on the left)
_STRAIGHT_BEHIND = 0.05  # metres: a follower this close to the car's lateral is straight behind
_MIN_PASS_TIME = 3.0  # seconds of driving a lane must fit when it passes nobody
_CREEP = 0.05  # m/s: slower than this is standing
_PULL_OUT_RADIUS = 1.5  # lookaheads: the radius of the arcs of a pull-out from standing
_BACK_OFF = 0.3  # metres backed off beyond the gap a pull-out needs
_FASTER = 0.1  # m/s faster than a car ahead is closing on it
_SETTLE = 0.05  # metres of side gap a car still settling into its lane may lack
_STRAIGHTEN = 2.0  # 1/s: how fast backing off turns the heading back along the track


@dataclass(frozen=True)
class _Near:
    """The other cars within the horizon at one step (arrays over them; lanes x cars for the
    masks ``in_dest`` and ``in_swept``)."""

    lat: np.ndarray  # metres left of the centerline
    v: np.ndarray  # m/s along the track (not below 0)
    ahead: np.ndarray  # rear axle ahead of this car's
    gap: np.ndarray  # metres bumper to bumper to a car ahead
    rear_gap: np.ndarray  # metres bumper to bumper to a car behind
    sep: float  # metres between lateral offsets that keep two cars side_gap apart
    in_dest: np.ndarray  # in the lane
    in_swept: np.ndarray  # in the lanes swept from the car's lateral offset to the lane
    in_mine: np.ndarray  # in the car's own lane
    lat_i: float  # the car's own lateral offset


class RacingDriver:
    """Car ``index`` of the race ``traffic`` describes, driven at up to ``speed`` m/s (see the
    module doc).

    Args:
        traffic: the race's traffic picture, updated by the race before each call.
        index: which car this driver drives.
        speed: top speed, metres per second.
        rules: the rules' numbers (a [RacingRules][racecar_sim.race.racing_rules.RacingRules]
            or a mapping of its fields).

    Attributes:
        target: the lane (metres left of the centerline) chosen at the last call, or None.
        offset: the lateral offset of the line followed (moving towards ``target``), or None.
    """

    def __init__(
        self,
        traffic: Traffic,
        index: int,
        speed: float = 2.0,
        rules: RacingRules | Mapping[str, Any] | None = None,
    ) -> None:
        if not isinstance(index, int) or not 0 <= index < traffic.n_cars:
            raise ValueError(
                f"RacingDriver.index = {index!r} must be a car of the race "
                f"(0 ... {traffic.n_cars - 1})"
            )
        if not (isinstance(speed, int | float) and math.isfinite(speed) and speed >= 0):
            raise ValueError(f"RacingDriver.speed = {speed!r} must be non-negative m/s")
        self.traffic = traffic
        self.index = index
        self.speed = float(speed)
        self.rules = nested(RacingRules() if rules is None else rules, RacingRules,
                            "RacingDriver.rules")  # fmt: skip
        r, car = self.rules, traffic.car
        half = int(round(r.max_offset / r.lane_step))
        self.lanes = np.arange(-half, half + 1) * r.lane_step
        """(M,) the lateral offsets weighed, metres (left positive)."""
        self.room = LaneRoom(traffic.track, car.width, r.wall_margin)
        self._others = np.arange(traffic.n_cars) != index
        self._front = car.length - car.rear_overhang
        self._wheelbase = car.wheelbase
        self._max_steer = car.max_steer
        self.target: float | None = None
        self.offset: float | None = None
        self._backing = False

    def reset(self) -> None:
        """Forget the lane (the next call starts from the car's place)."""
        self.target = None
        self.offset = None
        self._backing = False

    # ------------------------------------------------------------------ the decision
    def decide(self) -> float:
        """Choose the lane (``target``) from the traffic picture; returns the speed, m/s (negative
        while backing off)."""
        t, r, lanes = self.traffic, self.rules, self.lanes
        lat_i = float(t.lateral[self.index])
        if self.target is None:
            self.target = float(lanes[np.argmin(np.abs(lanes - lat_i))])
            self.offset = lat_i
        near = self._near(lat_i)
        reach, ending = self._room(near)
        # a lane that ends merges towards the centerline: the cars ahead on the way are followed
        to_centre = _within(near.lat, np.minimum(lanes, 0.0), np.maximum(lanes, 0.0), near.sep)
        in_dest = near.in_dest | (ending[:, None] & to_centre)
        v_dest = self._lane_speeds(near, in_dest, reach)
        v_across, stuck = self._crossing_speeds(near, in_dest)
        # a lane change must not cut in front of a car beside or just behind: towards one not
        # straight behind it (half a lane over or more)
        merge = near.rear_gap < r.standstill_gap + r.merge_headway * near.v
        off_line = np.abs(near.lat - lat_i) > near.sep / 2
        toward = np.abs(near.lat[None, :] - lanes[:, None]) < np.abs(near.lat - lat_i)[None, :]
        close_by = ~near.ahead & merge & off_line
        cut_in = near.in_swept & toward & close_by[None, :]
        # gives way to a car close behind, unless it is closing on a slower car itself
        behind = ~near.ahead & (near.rear_gap < r.yield_range)
        slower = near.ahead & near.in_mine & (near.gap < 2 * r.yield_range)
        busy = (slower & (near.v < self.speed - _FASTER)).any()
        line = 0.0 if busy else self._line(lat_i, near.lat[behind])
        score = (
            v_dest
            - r.line_cost * np.abs(lanes - line)
            - r.switch_cost * np.abs(lanes - self.target)
            + _TIE_BREAK * lanes
        )
        current = np.abs(lanes - self.target) < 1e-9
        score = np.where(cut_in.any(axis=1) | (ending & ~current), -np.inf, score)
        if np.isfinite(score).any():
            k = int(np.argmax(score))
        else:  # boxed in: stay in the lane the car is in
            k = int(np.argmin(np.abs(lanes - lat_i)))
        self.target = float(lanes[k])
        # pulled up too close behind a standing car to pull out round it: back off if nothing
        # is close behind
        close_behind = ~near.ahead & near.in_swept[k] & (near.rear_gap < r.standstill_gap)
        self._backing = bool(stuck[k].any()) and not close_behind.any() and r.reverse_speed > 0
        if self._backing:
            return -r.reverse_speed
        speed = min(float(v_dest[k]), float(v_across[k]))
        # a faster car beside it, passing: ease off so that the pass is over sooner
        beside = (np.abs(near.rear_gap + t.car.length) < t.car.length) & ~near.in_mine
        if (beside & (near.v > float(t.speed[self.index]) + _FASTER)).any():
            speed = min(speed, self.speed - r.pass_ease)
        return max(speed, 0.0)

    def _near(self, lat_i: float) -> _Near:
        """The other cars within ``horizon`` along the track, against every lane."""
        t, r, lanes = self.traffic, self.rules, self.lanes
        i = self.index
        near = self._others & (np.abs(t.gaps[i]) < r.horizon)
        d, lat = t.gaps[i][near], t.lateral[near]
        sep = t.car.width + r.side_gap
        return _Near(
            lat=lat,
            v=np.maximum(t.speed[near], 0.0),
            ahead=d >= 0,
            gap=d - t.car.length,
            rear_gap=-d - t.car.length,
            sep=sep,
            in_dest=_within(lat, lanes, lanes, sep),
            in_swept=_within(lat, np.minimum(lanes, lat_i), np.maximum(lanes, lat_i), sep),
            in_mine=np.abs(lat - lat_i) < sep,
            lat_i=lat_i,
        )

    def _room(self, near: _Near) -> tuple[np.ndarray, np.ndarray]:
        """Per lane, metres ahead it fits (up to ``horizon``), and whether it ends before the
        pass it makes is done (or within a few seconds of driving)."""
        r, v_free = self.rules, self.speed
        closing = np.maximum(v_free - near.v, 0.1)
        to_gain = (
            near.gap + 2 * self.traffic.car.length + r.standstill_gap + r.merge_headway * near.v
        )
        passed = near.ahead & near.in_mine & ~near.in_dest & (near.v < v_free - _FASTER)
        need = np.where(passed, v_free * to_gain / closing, 0.0).max(axis=1, initial=0.0)
        need = np.minimum(np.maximum(need, v_free * _MIN_PASS_TIME), r.horizon)
        reach = self.room.reach(float(self.traffic.s[self.index]), self.lanes, r.horizon)
        return reach, (reach < need) & (np.abs(self.lanes) > 1e-9)

    def _lane_speeds(self, near: _Near, in_dest: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """Per lane, the speed the cars ahead in it (headway) and its room ahead allow."""
        r = self.rules
        # behind a standing car, stop where the car can still pull out round it
        aside = np.maximum(near.sep - np.abs(near.lat - near.lat_i), 0.0)
        stop_gap = np.where(near.v < _CREEP, np.maximum(r.standstill_gap, self._pull_out(aside)),
                            r.standstill_gap)  # fmt: skip
        follow = (r.response * near.v + near.gap - stop_gap) / (r.response + r.headway)
        follow = np.where(near.gap < r.min_gap, 0.0, follow)
        v_dest = np.where(near.ahead & in_dest, follow, np.inf).min(axis=1, initial=np.inf)
        v_room = np.sqrt(2.0 * r.brake * np.maximum(reach - r.standstill_gap, 0.0))
        open_ahead = (np.abs(self.lanes) < 1e-9) | (reach >= r.horizon)
        v_dest = np.minimum(v_dest, np.where(open_ahead, np.inf, v_room))
        return np.clip(v_dest, 0.0, self.speed)

    def _crossing_speeds(self, near: _Near, in_dest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per lane, the speed that keeps the car out of the way of the cars ahead in the lanes
        it sweeps on the way across, and (lanes x cars) the standing cars it is too close to
        pull out round."""
        r = self.rules
        way = np.sign(self.lanes - near.lat_i)[:, None]
        beside = near.sep - _SETTLE  # lateral offsets apart that count as out of the way
        clear = np.maximum(way * (near.lat + way * beside - near.lat_i), 0.0)  # sideways, m
        across = near.ahead & near.in_swept & ~in_dest & (clear > 0)
        t_move = np.maximum(clear / r.lateral_speed, max(self.traffic.dt, 1e-3))
        squeeze = near.v + (near.gap - r.min_gap) / t_move
        pull_out = self._pull_out(clear)
        if self._backing:  # backs off beyond the gap needed, then pulls out
            pull_out = pull_out + _BACK_OFF
        standing = float(self.traffic.speed[self.index]) < _CREEP
        stuck = across & (near.gap < pull_out) & (near.v < _CREEP) & standing
        squeeze = np.where(stuck, 0.0, squeeze)
        return np.where(across, squeeze, np.inf).min(axis=1, initial=np.inf), stuck

    def _pull_out(self, sideways: np.ndarray) -> np.ndarray:
        """Metres of gap a standing car needs to move ``sideways`` metres before reaching the
        car ahead: two arcs of 1.5 lookaheads' radius, plus ``min_gap``."""
        radius = _PULL_OUT_RADIUS * self.rules.lookahead
        return self.rules.min_gap + 2.0 * np.sqrt(sideways * radius)

    def _line(self, lat_i: float, followers: np.ndarray) -> float:
        """The lateral offset wanted (metres) with cars close behind at lateral ``followers``:
        away from them (to the right of one straight behind), held where they are on both
        sides, the centerline when there are none."""
        if followers.size == 0:
            return 0.0
        left = bool((followers > lat_i + _STRAIGHT_BEHIND).any())
        right = bool((followers < lat_i - _STRAIGHT_BEHIND).any())
        if left and right:
            return lat_i
        return self.rules.yield_offset if right else -self.rules.yield_offset

    def clear_speed(self) -> float:
        """The speed (m/s) that stops the car short of every point of another car's box in the
        corridor ahead of its own along the line it follows (the line moving from its lateral
        offset to the one followed over a lookahead; inf when the corridor is clear)."""
        t, r, i = self.traffic, self.rules, self.index
        length = t.track.length
        ahead = np.mod(t.outline_s[self._others] - t.s[i] + length / 2, length) - length / 2
        lat_i = float(t.lateral[i])
        offset = lat_i if self.offset is None else self.offset
        line = lat_i + (offset - lat_i) * np.clip(ahead / r.lookahead, 0.0, 1.0)
        inside = (ahead > 0.0) & (
            np.abs(t.outline_lateral[self._others] - line) < t.car.width / 2 + r.side_gap / 2
        )
        if not inside.any():
            return math.inf
        room = float(ahead[inside].min()) - self._front - r.min_gap
        return math.sqrt(2.0 * r.brake * max(room, 0.0))

    # ------------------------------------------------------------------ the driver protocol
    def __call__(self, obs: Mapping[str, Any] | None, pose: np.ndarray | None = None) -> np.ndarray:
        """Action float32 [steer rad, speed m/s] for the car at rear-axle world ``pose`` (else
        ``obs["pose_estimate"]``); its place on the track and the other cars' come from the
        traffic picture.

        Raises:
            ValueError: no pose is given, or it is not three finite numbers.
        """
        if pose is None:
            if isinstance(obs, Mapping) and "pose_estimate" in obs:
                pose = obs["pose_estimate"]
            else:
                raise ValueError("RacingDriver needs the car's pose: pass pose=[x, y, theta]")
        p = np.asarray(pose, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"pose must be three finite numbers [x, y, theta], got {pose!r}")
        speed = self.decide()
        speed = min(speed, self.clear_speed()) if speed > 0 else speed
        assert self.offset is not None and self.target is not None
        step = self.rules.lateral_speed * self.traffic.dt
        self.offset += min(max(self.target - self.offset, -step), step)
        s = float(self.traffic.s[self.index]) + self.rules.lookahead
        goal = self.traffic.track.offset_point(s, self.offset)
        dx, dy = goal[0] - p[0], goal[1] - p[1]
        c, sn = math.cos(p[2]), math.sin(p[2])
        lx, ly = c * dx + sn * dy, -sn * dx + c * dy  # the goal in the car frame
        if speed >= 0:
            steer = math.atan(2.0 * self._wheelbase * ly / max(lx * lx + ly * ly, 1e-9))
        else:  # backing off: turn the heading back along the track
            error = (p[2] - self.traffic.track.heading_at(s) + math.pi) % (2 * math.pi) - math.pi
            steer = math.atan(_STRAIGHTEN * error * self._wheelbase / -speed)
        steer = min(max(steer, -self._max_steer), self._max_steer)
        return as_action(steer, speed)


def _within(lat: np.ndarray, low: np.ndarray, high: np.ndarray, sep: float) -> np.ndarray:
    """(M, N): whether lateral offsets ``lat`` (N,) come closer than ``sep`` to the bands
    ``[low, high]`` (M,) (metres)."""
    outside = np.maximum(lat[None, :] - high[:, None], low[:, None] - lat[None, :])
    return outside < sep
