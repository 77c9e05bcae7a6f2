"""What a replay needs of a bag's LaserScan header, checked on the first scan before any is kept.

The reader places beam ``i`` at ``angle_min + i * angle_increment`` (car-frame radians) and turns
ranges outside ``[range_min, range_max]`` into no-returns, and the filter's beam model is built for
``range_max``. A scan that cannot be placed or measured that way is refused with one line: no
beams, more beams than any planar lidar has, a non-finite ``angle_min`` or ``angle_increment``, a
zero step between several beams, a fan wider than a full turn, or a ``range_min`` / ``range_max``
that is not finite, negative, or beyond the filter's range bound. A ``ranges`` array whose length
differs from the one ``angle_min``, ``angle_max`` and ``angle_increment`` imply is read as it is
(beams from ``angle_min`` at ``angle_increment``), with a warning.
"""

from __future__ import annotations

import math
from typing import Any

from mcl.filter.bounds import FILTER_BOUNDS
from racecar_sim.settings.bounds import BOUNDS

__all__ = ["MAX_SCAN_BEAMS", "scan_problem", "scan_warning"]

MAX_SCAN_BEAMS = int(BOUNDS["n_beams"].high)
"""Most beams in one scan: the simulated lidar's bound (10,000; real planar lidars have
360-3600)."""
_MAX_RANGE = FILTER_BOUNDS["sensor.max_range"].high
_TURN = 2.0 * math.pi * (1.0 + 1e-6)


def _number(msg: Any, name: str) -> float:
    try:
        return float(getattr(msg, name))
    except (TypeError, ValueError):
        return math.nan


def scan_problem(msg: Any, n_beams: int) -> str | None:
    """Why the first scan ``msg`` (a LaserScan with ``n_beams`` ranges) cannot be replayed, or None.

    The text follows "the first scan ..." in a message naming the bag and the topic.
    """
    if n_beams < 1:
        return "has 0 beams"
    if n_beams > MAX_SCAN_BEAMS:
        return f"has {n_beams:,} beams, more than the {MAX_SCAN_BEAMS:,} of any planar lidar"
    a0, step = _number(msg, "angle_min"), _number(msg, "angle_increment")
    r0, r1 = _number(msg, "range_min"), _number(msg, "range_max")
    if not math.isfinite(a0) or abs(a0) > 2.0 * math.pi:
        return f"has angle_min = {a0!r} rad (must be finite, within a turn either way)"
    if not math.isfinite(step):
        return f"has angle_increment = {step!r} rad (must be finite)"
    if n_beams > 1 and step == 0.0:
        return f"has angle_increment 0 for {n_beams} beams: every beam in one direction"
    if abs(step) * (n_beams - 1) > _TURN:
        return (
            f"spans {abs(step) * (n_beams - 1):.4g} rad ({n_beams} beams at angle_increment "
            f"{step:.4g}), more than a full turn"
        )
    if not (math.isfinite(r1) and 0.0 < r1 <= _MAX_RANGE):
        return f"has range_max = {r1!r} m (must be in (0, {_MAX_RANGE:g}], the filter's bound)"
    if not (math.isfinite(r0) and 0.0 <= r0 < r1):
        return f"has range_min = {r0!r} m (must be >= 0 and below range_max {r1:g} m)"
    return None


def scan_warning(msg: Any, n_beams: int) -> str | None:
    """A warning when ``n_beams`` ranges differ from the count ``angle_min``, ``angle_max`` and
    ``angle_increment`` imply by more than one (None otherwise)."""
    a0, a1, step = (_number(msg, k) for k in ("angle_min", "angle_max", "angle_increment"))
    if not (math.isfinite(a1) and step != 0.0 and math.isfinite(step)):
        return None
    implied = (a1 - a0) / step + 1.0
    if not math.isfinite(implied) or abs(implied - n_beams) <= 1.0:
        return None
    return (
        f"scans have {n_beams} ranges but angle_min..angle_max at angle_increment make "
        f"{implied:.0f} beams; the beams are placed from angle_min at angle_increment"
    )
