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
[RacingRules][racecar_sim.race.racing_rules.RacingRules]; the per-step arithmetic is numba
(``racecar_sim.race.racing_kernels``). Frames: world (poses, track), track
(arc length, lateral offset), car (x forward, y left, at the rear axle).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from racecar_sim.drivers.base import as_action
from racecar_sim.race import racing_kernels as kernels
from racecar_sim.race.lanes import LaneRoom
from racecar_sim.race.racing_rules import RacingRules
from racecar_sim.race.traffic import Traffic
from racecar_sim.settings.params import nested

__all__ = ["RacingDriver"]

_STRAIGHTEN = 2.0  # 1/s: how fast backing off turns the heading back along the track


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
        self._numbers = np.array([getattr(r, name) for name in kernels.NUMBERS])
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
        t, i = self.traffic, self.index
        lat_i = float(t.lateral[i])
        if self.target is None:
            self.target = float(self.lanes[np.argmin(np.abs(self.lanes - lat_i))])
            self.offset = lat_i
        near = self._others & (np.abs(t.gaps[i]) < self.rules.horizon)
        k, speed, self._backing = kernels.decide(
            self.lanes, self.target, self._backing, lat_i, float(t.speed[i]), self.speed,
            float(t.s[i]), t.dt, t.car.length, t.car.width, t.gaps[i][near], t.lateral[near],
            t.speed[near], self._numbers, self.room.low, self.room.high, self.room.spacing,
        )  # fmt: skip
        self.target = float(self.lanes[k])
        return float(speed)

    def clear_speed(self) -> float:
        """The speed (m/s) that stops the car short of every point of another car's box in the
        corridor ahead of its own along the line it follows (the line moving from its lateral
        offset to the one followed over a lookahead; inf when the corridor is clear)."""
        t, r, i = self.traffic, self.rules, self.index
        lat_i = float(t.lateral[i])
        offset = lat_i if self.offset is None else self.offset
        return float(kernels.clear_speed(
            t.outline_s, t.outline_lateral, self._others, float(t.s[i]), lat_i, offset,
            t.track.length, r.lookahead, t.car.width / 2 + r.side_gap / 2, self._front, r.min_gap,
            r.brake,
        ))  # fmt: skip

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

