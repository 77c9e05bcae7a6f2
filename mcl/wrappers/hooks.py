"""Step hooks: how a recorder, a live view or a probe follows a localized drive without the wrapper
knowing it.

A step hook is any callable ``hook(record)``; [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper]
calls each of its hooks, in the order they were added, once after ``reset()`` (step 0) and once
after every ``step()``, after the filter's update and the error log's row, with the
[`StepRecord`][mcl.wrappers.hooks.StepRecord] of that step. The wrappers never import ``mcl.io``:
the bag recorder and the Foxglove live view ([`DriveRecorder`][mcl.io.bag_writer.DriveRecorder],
optionally streaming to a [`LiveServer`][mcl.io.live.LiveServer]) are hooks their users attach.

A hook only reads: it must not change the record's arrays (they are read-only views of the step's
own arrays, the filter's among them: copy what you keep) nor the env or the filter, so the drive is
the same with and without it. A hook that raises stops the step
(the exception reaches the caller of ``reset()`` / ``step()``).

Frames and units: world frame of the map; poses [x, y, theta] of the rear axle in metres and
radians (theta in [-pi, pi)); times in seconds.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

__all__ = ["StepHook", "StepHooks", "StepRecord", "read_only", "step_record"]


def read_only(a: Any) -> np.ndarray:
    """A read-only float64 view of ``a`` (a read-only copy when ``a`` is not float64 already)."""
    v = np.asarray(a, dtype=np.float64).view()
    v.flags.writeable = False
    return v


@dataclass(frozen=True)
class StepRecord:
    """What one reset or step of a localized drive produced, as a step hook sees it (read-only).

    Attributes:
        step: 0 for the reset, k for the k-th step since it.
        time: seconds since the reset (the env's ``info["time"]``).
        truth: (3,) true pose [x m, y m, theta rad], world frame (``info["pose"]``).
        estimate: (3,) the filter's estimate after this step's update, world frame (the same
            values as ``obs["pose_estimate"]`` and ``info["localization"]["estimate"]``).
        covariance: (3, 3) covariance of the particles about the estimate over [x, y, theta]
            (m², m rad, rad²; ``info["localization"]["covariance"]``).
        particles: (N, 3) the filter's particles [x m, y m, theta rad], world frame, after
            resampling.
        weights: (N,) their normalised weights (sum 1).
        scan: (B,) this step's ranges in metres, beams in the lidar's order (car frame angles);
            the lidar's max range where a beam has no return (``obs["scan"]``). A step without a
            fresh scan (``new_scan`` False) repeats the last one.
        odom: (3,) the odometry twist of this step, [vx m/s, vy m/s, omega rad/s] in the car's
            frame (``obs["odom"]``; the motion from ``time - dt`` to ``time``; meaningless at
            step 0).
        new_scan: whether the filter was corrected by a fresh scan this step (always True at
            step 0; ``info["localization"]["corrected"]``).
        info: the info dict the step returns (the env's plus ``localization``), as a read-only
            mapping.
    """

    step: int
    time: float
    truth: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray
    particles: np.ndarray
    weights: np.ndarray
    scan: np.ndarray
    odom: np.ndarray
    new_scan: bool
    info: Mapping[str, Any]


StepHook = Callable[[StepRecord], None]
"""A step hook: called as ``hook(record)`` with a [`StepRecord`][mcl.wrappers.hooks.StepRecord]."""


class StepHooks:
    """The hooks of one wrapper, in the order they were added (the same hook may be added twice,
    and is then called twice).

    Args:
        hooks: the first hooks: one callable, an iterable of them, or None for none.

    Raises:
        TypeError: a hook is not callable.
    """

    def __init__(self, hooks: StepHook | Iterable[StepHook] | None = None) -> None:
        self._hooks: list[StepHook] = []
        if hooks is None:
            return
        for hook in [hooks] if callable(hooks) else list(hooks):
            self.add(hook)

    def add(self, hook: StepHook) -> None:
        """Call ``hook(record)`` after every reset and step from now on."""
        if not callable(hook):
            raise TypeError(f"a step hook must be callable as hook(record), got {hook!r}")
        self._hooks.append(hook)

    def remove(self, hook: StepHook) -> None:
        """Stop calling ``hook`` (its first occurrence).

        Raises:
            ValueError: ``hook`` was not added.
        """
        try:
            self._hooks.remove(hook)
        except ValueError:
            raise ValueError(f"{hook!r} is not a step hook of this wrapper") from None

    def __len__(self) -> int:
        return len(self._hooks)

    def __iter__(self):
        return iter(tuple(self._hooks))

    def __bool__(self) -> bool:
        return bool(self._hooks)

    def call(self, record: StepRecord) -> None:
        """Call every hook with ``record``, in order (a hook added or removed by a hook takes
        effect from the next record)."""
        for hook in tuple(self._hooks):
            hook(record)


def step_record(
    step: int,
    time: float,
    obs: Mapping[str, Any],
    info: dict[str, Any],
    particles: np.ndarray,
    weights: np.ndarray,
) -> StepRecord:
    """The record of a step from the wrapper's ``obs`` and ``info`` (``info["localization"]`` as
    ``mcl.wrappers.localization.localization_report`` makes it) and the filter's particles and
    weights."""
    loc = info["localization"]
    return StepRecord(
        step=int(step),
        time=float(time),
        truth=read_only(info["pose"]),
        estimate=read_only(loc["estimate"]),
        covariance=read_only(loc["covariance"]),
        particles=read_only(particles),
        weights=read_only(weights),
        scan=read_only(obs["scan"]),
        odom=read_only(obs["odom"]),
        new_scan=bool(loc["corrected"]),
        info=MappingProxyType(info),
    )
