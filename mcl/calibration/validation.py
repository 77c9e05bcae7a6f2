"""The simulated lidar against the real one, by one judge ([`mcl.calibration.judge`][mcl.calibration.judge]): the real
scans of a bag at their reference poses, and simulated scans from the same poses with a noise
profile in a scene, both refined by the same robust scan match and compared with exact casts.

Leave-one-bag-out: fit the sensor on one bag (``racecar-sim calibrate-noise BAG``), then predict
the other bag's five fractions with the scene of the other bag's corridor
(``scripts/validate_noise.py``; the docs page "Honest noise" has the tables).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from mcl.calibration.judge import judged_recording, judged_simulation
from mcl.calibration.reference_poses import ReferencePoses, track_recording
from mcl.calibration.room_split import RoomStats, room_stats
from mcl.calibration.scan_match import ScanMatcher
from mcl.calibration.scan_stats import ResidualFractions, residual_fractions
from mcl.io.bag_reader import BagData, read_bag
from racecar_sim.maps import OccupancyMap, load_map

__all__ = [
    "JudgedBag",
    "judge_bag",
    "simulated_fractions",
    "simulated_room",
    "simulated_scans",
    "wall_follower_route",
]

MAX_RANGE = 30.0
"""Metres: the Hokuyo's range_max in the shared bags, also the simulated lidar's here."""


@dataclass(frozen=True)
class JudgedBag:
    """A recording judged on a map.

    Attributes:
        rec: the recording.
        poses: its reference poses (scan matching).
        z, z_star: (S, B) de-skewed scans and exact casts from the refined poses, metres.
        fractions: the five fractions (`residual_fractions()`).
    """

    rec: BagData
    poses: ReferencePoses
    z: np.ndarray
    z_star: np.ndarray
    fractions: ResidualFractions


def judge_bag(
    bag: str | os.PathLike[str],
    occupancy_map: OccupancyMap,
    start_guess: np.ndarray | None = None,
    mount: float = 0.275,
) -> JudgedBag:
    """Track ``bag`` on the map (from ``start_guess``, a lidar pose of the scan a third into it,
    or a global search) and judge its scans."""
    rec = read_bag(bag)
    matcher = ScanMatcher(occupancy_map, rec.angles, MAX_RANGE)
    guess = None if start_guess is None else np.asarray(start_guess, dtype=np.float64)
    poses = track_recording(rec, matcher, mount, start_guess=guess)
    z, zs = judged_recording(rec, poses, matcher, mount)
    return JudgedBag(rec, poses, z, zs, residual_fractions(z, zs, MAX_RANGE))


def simulated_scans(
    occupancy_map: OccupancyMap | str | os.PathLike[str],
    base_poses: np.ndarray,
    every: int = 3,
    seed: int = 0,
    **settings,
) -> tuple[np.ndarray, np.ndarray]:
    """(z, z_star) (S, B) metres: simulated scans from every ``every``-th of ``base_poses`` (S, 3)
    (rear-axle, world) and the exact casts from their refined poses, judged like real ones
    ([`mcl.calibration.judge.judged_simulation()`][mcl.calibration.judge.judged_simulation]). ``settings`` go to ``RacecarSim-v0``
    (e.g. ``noise_profile``, ``scene``); the lidar is the Hokuyo's (1081 beams over 270 degrees,
    30 m). Pose i is reset with seed ``seed + i`` (a scene is placed anew at each). Poses where
    the car's box touches a wall of the map are skipped."""
    import gymnasium as gym

    import racecar_sim  # noqa: F401  (registers RacecarSim-v0)

    grid = occupancy_map if isinstance(occupancy_map, OccupancyMap) else load_map(occupancy_map)
    kw = {"n_beams": 1081, "fov": 1.5 * np.pi, "max_range": MAX_RANGE, **settings}
    env = gym.make("RacecarSim-v0", map=grid, **kw).unwrapped
    matcher = ScanMatcher(grid, env.lidar.angles, MAX_RANGE)
    picks = np.asarray(base_poses, dtype=np.float64)[::every]

    def scan_at(i: int):
        try:
            obs, _ = env.reset(seed=seed + i, options={"pose": picks[i]})
        except ValueError:
            return None
        z = obs["scan"].astype(np.float64)
        z[z >= env.lidar_params.max_range] = np.nan
        return z, env.lidar.mount_pose(env.pose)

    out = judged_simulation(scan_at, len(picks), matcher)
    env.close()
    return out


def simulated_fractions(
    occupancy_map: OccupancyMap | str | os.PathLike[str],
    base_poses: np.ndarray,
    every: int = 3,
    seed: int = 0,
    **settings,
) -> ResidualFractions:
    """The five fractions of `simulated_scans()` (same arguments)."""
    z, zs = simulated_scans(occupancy_map, base_poses, every, seed, **settings)
    return residual_fractions(z, zs, MAX_RANGE)


def simulated_room(
    occupancy_map: OccupancyMap | str | os.PathLike[str],
    base_poses: np.ndarray,
    every: int = 3,
    seed: int = 0,
    body: float = 0.0,
    **settings,
) -> RoomStats:
    """What the room adds to `simulated_scans()` (same arguments): the shares of mapped
    beams in wide runs ([`mcl.calibration.room_split.room_stats()`][mcl.calibration.room_split.room_stats]), the first ``body``
    share of the scan's beams (the car's own body) left out as the calibration leaves it out."""
    z, zs = simulated_scans(occupancy_map, base_poses, every, seed, **settings)
    zs = zs.copy()
    zs[:, : round(body * zs.shape[1])] = np.inf
    spacing = float(settings.get("fov", 1.5 * np.pi)) / (zs.shape[1] - 1)
    return room_stats(z, zs, spacing, MAX_RANGE)


def wall_follower_route(
    world: OccupancyMap | str | os.PathLike[str],
    seeds: tuple[int, ...] = (0, 1, 2),
    duration: float = 60.0,
    every: float = 1.5,
) -> np.ndarray:
    """(N, 3) rear-axle world poses, one every ``every`` seconds, of the wall follower's drives in
    ``world`` from the resets of ``seeds`` (the noise experiment's route: its start poses and
    driver, ``noise_profile="mit_racecar"``, no scene). A drive ends at ``duration`` seconds or
    at its first wall contact."""
    import gymnasium as gym

    import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
    from racecar_sim.drivers import WallFollower

    grid = world if isinstance(world, OccupancyMap) else load_map(world)
    env = gym.make("RacecarSim-v0", map=grid, noise_profile="mit_racecar").unwrapped
    poses = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        driver = WallFollower.for_env(env)
        keep = max(1, round(every / env.dt))
        for k in range(round(duration / env.dt)):
            obs, _, terminated, _, _ = env.step(driver(obs))
            if terminated:
                break
            if k % keep == 0:
                poses.append(env.pose.copy())
    env.close()
    return np.array(poses).reshape(-1, 3)
