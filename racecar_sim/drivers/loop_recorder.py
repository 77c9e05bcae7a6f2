"""A waypoint loop recorded by driving: run a driver until its path repeats (world frame, metres)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from racecar_sim.world.track import resample_polyline

__all__ = ["waypoints_from_drive"]


def waypoints_from_drive(
    env: Any,
    driver: Callable[..., np.ndarray],
    *,
    seed: int | None = None,
    start_pose: np.ndarray | None = None,
    spacing: float = 0.25,
    max_steps: int = 100_000,
    close_radius: float = 1.0,
    min_length: float = 10.0,
    close_heading: float = math.pi / 4,
    check_every: int = 10,
) -> np.ndarray:
    """Drive ``driver`` in ``env`` until its path repeats; that cycle as a waypoint loop.

    ``env`` is a RacecarSim env (``reset(seed=, options={"pose": ...})``, ``step(action)`` with the
    true pose in ``info["pose"]``). The loop closes when the car, after covering ``min_length``
    more metres, comes back within ``close_radius`` metres of a point of its path *heading the same
    way* (within ``close_heading`` radians); the loop is the path since that point. Passing a point
    the other way (an out-and-back round a pillar) is not a loop, and a driver that settles into a
    cycle which never passes its start again (the wall follower started in a side room) still closes
    one. The path is checked every ``check_every`` steps.

    Returns:
        (K, 2) world metres, one point every ``spacing`` metres, for ``PurePursuit(loop=True)``,
        ordered so that a car at the start pose drives along it forwards (the cycle may run the
        other way, e.g. when the wall follower turned round a pillar before settling).

    Raises:
        RuntimeError: the car collided or did not close a loop within ``max_steps``.
    """
    options = {"pose": list(map(float, start_pose))} if start_pose is not None else None
    reset = getattr(driver, "reset", None)
    if callable(reset):
        reset()  # a driver with state (the wall follower backing out) starts afresh
    obs, info = env.reset(seed=seed, options=options)
    poses = np.empty((max_steps + 1, 3))
    covered = np.zeros(max_steps + 1)  # metres driven up to each pose
    poses[0] = info["pose"]
    for k in range(1, max_steps + 1):
        obs, _, terminated, truncated, info = env.step(driver(obs, info["pose"]))
        poses[k] = info["pose"]
        covered[k] = covered[k - 1] + float(np.hypot(*(poses[k, :2] - poses[k - 1, :2])))
        if info.get("collision", False):
            raise RuntimeError(
                f"the car collided at {poses[k, :2].round(2).tolist()} after {covered[k]:.1f} m"
            )
        if k % check_every == 0 or terminated or truncated:
            j = _earlier_pass(
                poses[: k + 1], covered[: k + 1], close_radius, min_length, close_heading
            )
            if j is not None:
                loop = resample_polyline(poses[j:k, :2], spacing, loop=True)
                return _oriented_along(loop, poses[0])
        if terminated or truncated:
            break
    raise RuntimeError(f"the drive did not return to its start (covered {covered[k]:.1f} m)")


def _oriented_along(loop: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``loop`` (K, 2), reversed if needed so that it runs forwards for a car at ``pose`` [x, y, theta].

    The direction is judged at the waypoint nearest the pose: a car started against it would need
    a U-turn in a hallway, which pure pursuit does not plan.
    """
    i = int(np.argmin(np.hypot(*(loop - pose[:2]).T)))
    tangent = loop[(i + 1) % len(loop)] - loop[i - 1]
    if tangent @ np.array([math.cos(pose[2]), math.sin(pose[2])]) < 0:
        return loop[::-1].copy()
    return loop


def _earlier_pass(
    poses: np.ndarray,
    covered: np.ndarray,
    radius: float,
    min_length: float,
    max_turn: float,
) -> int | None:
    """Index of the earlier pose the last pose closes a loop on, or None (see waypoints_from_drive).

    Candidates lie at least ``min_length`` metres of driving back, within ``radius`` metres and
    ``max_turn`` radians of heading; of the most recent pass through them, the nearest is chosen.
    """
    last = poses[-1]
    old = covered <= covered[-1] - min_length
    gap = np.hypot(poses[:, 0] - last[0], poses[:, 1] - last[1])
    turn = np.abs(np.remainder(poses[:, 2] - last[2] + np.pi, 2 * np.pi) - np.pi)
    hits = np.flatnonzero(old & (gap < radius) & (turn < max_turn))
    if hits.size == 0:
        return None
    recent = hits[covered[hits] >= covered[hits[-1]] - 2 * radius]
    return int(recent[np.argmin(gap[recent])])
