"""The racing driver's per-step arithmetic as numba kernels (the rules are in
[RacingDriver][racecar_sim.race.racing_driver.RacingDriver]).

A driver weighs a dozen lanes against a handful of cars every step; as numpy that is some sixty
small array operations a step, a third of a millisecond each driver. These loops do the same
arithmetic, in the same order, in a few microseconds. Metres, seconds, m/s; lateral offsets are
left of the centerline; ``gaps`` run from the driver's rear axle forwards to each car's.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["NUMBERS", "clear_speed", "decide"]

NUMBERS = (
    "headway", "standstill_gap", "min_gap", "response", "side_gap", "lateral_speed",
    "merge_headway", "yield_range", "yield_offset", "reverse_speed", "pass_ease", "brake",
    "lookahead", "line_cost", "switch_cost", "horizon",
)  # fmt: skip
"""The ``RacingRules`` fields ``decide`` takes, in its ``rules`` array's order."""

TIE_BREAK = 1e-3  # m/s per metre left: of two equal lanes the left one (pass on the left)
STRAIGHT_BEHIND = 0.05  # metres: a follower this close to the car's lateral is straight behind
MIN_PASS_TIME = 3.0  # seconds of driving a lane must fit when it passes nobody
CREEP = 0.05  # m/s: slower than this is standing
PULL_OUT_RADIUS = 1.5  # lookaheads: the radius of the arcs of a pull-out from standing
BACK_OFF = 0.3  # metres backed off beyond the gap a pull-out needs
FASTER = 0.1  # m/s faster than a car ahead is closing on it
SETTLE = 0.05  # metres of side gap a car still settling into its lane may lack


@nb.njit(cache=True)
def _reach(s, lane, horizon, low, high, spacing):
    """Metres ahead of arc length ``s`` over which lateral offset ``lane`` fits (as
    ``LaneRoom.reach``)."""
    steps = max(int(math.ceil(horizon / spacing)), 1)
    k0 = int(s / spacing)
    n = low.shape[0]
    first_out = steps + 1
    for j in range(steps + 1):
        k = (k0 + j) % n
        if not (lane >= low[k] and lane <= high[k]):
            first_out = j
            break
    return min(first_out * spacing, horizon)


@nb.njit(cache=True)
def _pull_out(sideways, min_gap, radius):
    return min_gap + 2.0 * math.sqrt(sideways * radius)


@nb.njit(cache=True)
def _line(lat_i, lat, follower, yield_offset):
    """The lateral offset wanted with the cars ``follower`` close behind (see the driver)."""
    left = False
    right = False
    seen = False
    for j in range(lat.shape[0]):
        if follower[j]:
            seen = True
            if lat[j] > lat_i + STRAIGHT_BEHIND:
                left = True
            if lat[j] < lat_i - STRAIGHT_BEHIND:
                right = True
    if not seen:
        return 0.0
    if left and right:
        return lat_i
    return yield_offset if right else -yield_offset


@nb.njit(cache=True)
def decide(
    lanes, target, backing, lat_i, own_speed, v_free, s_i, dt, car_length, car_width,
    d, lat, speed, rules, low, high, spacing,
):  # fmt: skip
    """The lane and the speed of one driver for one step.

    Args:
        lanes: (M,) lateral offsets weighed.
        target: the lane chosen last step (metres). backing: whether it was backing off.
        lat_i, own_speed, s_i: the car's lateral offset, speed along the track, arc length.
        v_free: its top speed. dt: seconds since the last step.
        car_length, car_width: metres (every car's).
        d, lat, speed: (N,) the other cars within the horizon: gap from the rear axle forwards
            to theirs, lateral offset, speed along the track.
        rules: the numbers of ``NUMBERS``, in order.
        low, high, spacing: the track's room (``LaneRoom``).

    Returns:
        (index of the lane chosen, speed in m/s, negative while backing off; whether backing).
    """
    headway, standstill, min_gap, response = rules[0], rules[1], rules[2], rules[3]
    side_gap, lateral_speed, merge_headway = rules[4], rules[5], rules[6]
    yield_range, yield_offset, reverse_speed = rules[7], rules[8], rules[9]
    pass_ease, brake, lookahead = rules[10], rules[11], rules[12]
    line_cost, switch_cost, horizon = rules[13], rules[14], rules[15]
    m, n = lanes.shape[0], d.shape[0]
    sep = car_width + side_gap
    radius = PULL_OUT_RADIUS * lookahead
    v = np.maximum(speed, 0.0)
    gap = d - car_length
    rear_gap = -d - car_length
    ahead = d >= 0
    in_mine = np.abs(lat - lat_i) < sep
    # per car: follow speed, merge gap, whether a slower car ahead makes the driver busy
    follow = np.empty(n)
    busy = False
    for j in range(n):
        stop_gap = standstill
        if v[j] < CREEP:
            stop_gap = max(
                standstill, _pull_out(max(sep - abs(lat[j] - lat_i), 0.0), min_gap, radius)
            )
        follow[j] = (response * v[j] + gap[j] - stop_gap) / (response + headway)
        if gap[j] < min_gap:
            follow[j] = 0.0
        if ahead[j] and in_mine[j] and gap[j] < 2 * yield_range and v[j] < v_free - FASTER:
            busy = True
    if busy:
        line = 0.0
    else:
        line = _line(lat_i, lat, ~ahead & (rear_gap < yield_range), yield_offset)
    standing = own_speed < CREEP
    v_dest = np.empty(m)
    v_across = np.empty(m)
    score = np.empty(m)
    stuck_any = np.zeros(m, dtype=np.bool_)
    for lane_k in range(m):
        lane = lanes[lane_k]
        lo, hi = min(lane, lat_i), max(lane, lat_i)
        lo_c, hi_c = min(lane, 0.0), max(lane, 0.0)
        centre = abs(lane) < 1e-9
        # the room: a lane must fit over the pass it makes (or a few seconds of driving)
        need = 0.0
        for j in range(n):
            dest = abs(lat[j] - lane) < sep
            if ahead[j] and in_mine[j] and not dest and v[j] < v_free - FASTER:
                to_gain = gap[j] + 2 * car_length + standstill + merge_headway * v[j]
                need = max(need, v_free * to_gain / max(v_free - v[j], 0.1))
        need = min(max(need, v_free * MIN_PASS_TIME), horizon)
        reach = _reach(s_i, lane, horizon, low, high, spacing)
        ending = reach < need and not centre
        way = 1.0 if lane > lat_i else (-1.0 if lane < lat_i else 0.0)
        best = np.inf
        squeeze_min = np.inf
        cut_in = False
        for j in range(n):
            dest = abs(lat[j] - lane) < sep
            swept = max(lat[j] - hi, lo - lat[j]) < sep
            if ending and max(lat[j] - hi_c, lo_c - lat[j]) < sep:
                dest = True  # a lane that ends merges towards the centerline like a zip
            if ahead[j] and dest:
                best = min(best, follow[j])
            clear = max(way * (lat[j] + way * (sep - SETTLE) - lat_i), 0.0)
            if ahead[j] and swept and not dest and clear > 0:
                t_move = max(clear / lateral_speed, max(dt, 1e-3))
                squeeze = v[j] + (gap[j] - min_gap) / t_move
                pull = _pull_out(clear, min_gap, radius) + (BACK_OFF if backing else 0.0)
                if gap[j] < pull and v[j] < CREEP and standing:
                    squeeze = 0.0
                    stuck_any[lane_k] = True
                squeeze_min = min(squeeze_min, squeeze)
            merge = rear_gap[j] < standstill + merge_headway * v[j]
            off_line = abs(lat[j] - lat_i) > sep / 2
            toward = abs(lat[j] - lane) < abs(lat[j] - lat_i)
            if swept and toward and not ahead[j] and merge and off_line:
                cut_in = True
        if not (centre or reach >= horizon):
            best = min(best, math.sqrt(2.0 * brake * max(reach - standstill, 0.0)))
        v_dest[lane_k] = min(max(best, 0.0), v_free)
        v_across[lane_k] = squeeze_min
        current = abs(lane - target) < 1e-9
        score[lane_k] = (
            v_dest[lane_k] - line_cost * abs(lane - line) - switch_cost * abs(lane - target)
            + TIE_BREAK * lane
        )  # fmt: skip
        if cut_in or (ending and not current):
            score[lane_k] = -np.inf
    k = -1
    for lane_k in range(m):
        if score[lane_k] > -np.inf and (k < 0 or score[lane_k] > score[k]):
            k = lane_k
    if k < 0:  # boxed in: stay in the lane the car is in
        k = int(np.argmin(np.abs(lanes - lat_i)))
    # pulled up too close behind a standing car to pull out round it: back off if nothing is
    # close behind
    lane = lanes[k]
    lo, hi = min(lane, lat_i), max(lane, lat_i)
    close_behind = False
    for j in range(n):
        if not ahead[j] and max(lat[j] - hi, lo - lat[j]) < sep and rear_gap[j] < standstill:
            close_behind = True
    if stuck_any[k] and not close_behind and reverse_speed > 0:
        return k, -reverse_speed, True
    out = min(v_dest[k], v_across[k])
    # a faster car beside it, passing: ease off so that the pass is over sooner
    for j in range(n):
        if abs(d[j]) < car_length and not in_mine[j] and v[j] > own_speed + FASTER:
            out = min(out, v_free - pass_ease)
    return k, max(out, 0.0), False


@nb.njit(cache=True)
def clear_speed(outline_s, outline_lat, others, s_i, lat_i, offset, length, lookahead,
                half_width, front, min_gap, brake):  # fmt: skip
    """The speed that stops the car short of every point of another car's box in the corridor
    ahead along its line (``half_width`` each side of it; inf when clear): see
    ``RacingDriver.clear_speed``."""
    nearest = np.inf
    for c in range(outline_s.shape[0]):
        if not others[c]:
            continue
        for p in range(outline_s.shape[1]):
            ahead = np.mod(outline_s[c, p] - s_i + length / 2, length) - length / 2
            if ahead <= 0.0:
                continue
            line = lat_i + (offset - lat_i) * min(max(ahead / lookahead, 0.0), 1.0)
            if abs(outline_lat[c, p] - line) < half_width:
                nearest = min(nearest, ahead)
    if nearest == np.inf:
        return np.inf
    return math.sqrt(2.0 * brake * max(nearest - front - min_gap, 0.0))
