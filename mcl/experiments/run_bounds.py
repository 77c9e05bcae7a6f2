"""The bounds of a run's own settings, with the reason for each: how long a run drives and how a
live view is paced. [RunSpec][mcl.experiments.runs.RunSpec] and the commands' ``--duration`` /
``--live-speed`` check against this table; docs/settings.md shows it."""

from __future__ import annotations

from typing import Any

from racecar_sim.settings.bounds import Bound, check

__all__ = ["MAX_DURATION", "MIN_LIVE_SPEED", "RUN_BOUNDS", "check_duration", "check_live_speed"]

MAX_DURATION = 86_400.0
"""Seconds of simulated time in one run: a day."""
MIN_LIVE_SPEED = 0.01
"""Slowest live pacing, times real time (0 means unpaced)."""

RUN_BOUNDS: dict[str, Bound] = {
    "run.duration": Bound(0.0, MAX_DURATION, "s (simulated)", "a day: 3.5 million steps of "
                          "0.025 s and about 470 MB of error log; a racecar's battery lasts under "
                          "an hour, and a longer study is many runs", low_open=True),
    "live.speed": Bound(MIN_LIVE_SPEED, 1000.0, "x real time", "or 0, unpaced; at 0.01 a minute "
                        "of driving streams in 100 minutes (slower is a stalled view), and no "
                        "drive runs 1000 times faster than real time"),
}  # fmt: skip
"""Run setting -> its bound."""


def check_duration(owner: str, value: Any, name: str = "duration") -> float:
    """``value`` as seconds in ``RUN_BOUNDS["run.duration"]``.

    Raises:
        ValueError: one line naming ``owner.name``.
    """
    return float(check(owner, name, value, "run.duration", RUN_BOUNDS))


def check_live_speed(owner: str, value: Any, name: str = "live_speed") -> float:
    """``value`` as a live pacing: 0 (unpaced) or within ``RUN_BOUNDS["live.speed"]``.

    Raises:
        ValueError: one line naming ``owner.name``.
    """
    if isinstance(value, int | float) and not isinstance(value, bool) and value == 0:
        return 0.0
    try:
        return float(check(owner, name, value, "live.speed", RUN_BOUNDS))
    except ValueError as exc:
        raise ValueError(f"{exc} (or 0: unpaced)") from None
