"""The filter may hold a map other than the world the env simulates (size, resolution, edits)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401
from mcl import LocalizationWrapper
from mcl.experiments.runs import RunSpec, run_one
from racecar_sim.drivers import WallFollower
from racecar_sim.maps import MapError, OccupancyMap, bundled, load_map
from tests.skips import need_shared


def _coarse_cropped(world: OccupancyMap, crop_cols: int = 10) -> OccupancyMap:
    """The world at twice the cell size (a cell occupied if any of its 4 is) with the left
    ``crop_cols`` fine columns cut off (so another size and another origin, same world frame)."""
    occ = world.occupied[:, crop_cols:]
    h, w = (occ.shape[0] // 2) * 2, (occ.shape[1] // 2) * 2
    # keep the bottom rows (the origin is the lower-left corner): drop a top row if odd
    occ = occ[occ.shape[0] - h :, :w]
    coarse = occ.reshape(h // 2, 2, w // 2, 2).any(axis=(1, 3))
    ox, oy, yaw = world.origin
    assert yaw == 0.0
    origin = (ox + crop_cols * world.resolution, oy, 0.0)
    return OccupancyMap(coarse, world.resolution * 2, origin, name="coarse")


def test_wrapper_tracks_on_a_coarser_smaller_filter_map():
    world = load_map(bundled("basement_loop"))
    fmap = _coarse_cropped(world)
    assert fmap.shape != world.shape and fmap.resolution != world.resolution
    env = LocalizationWrapper(
        gym.make("RacecarSim-v0", map=world), {"filter": {"n_particles": 500}}, filter_map=fmap
    )
    assert env.map is fmap and env.world_map is world
    assert env.filter is None
    obs, info = env.reset(seed=2)
    assert env.filter.map is fmap
    driver = WallFollower.for_env(env.unwrapped)
    errors = []
    for _ in range(120):  # 3 s
        obs, _, term, _, info = env.step(driver(obs))
        errors.append(info["localization"]["position_error"])
        assert not term
    assert np.median(errors) < 0.15


def test_run_spec_filter_map_reaches_the_filter(tmp_path):
    fmap_path = bundled("basement_loop")
    spec = RunSpec(map="basement_loop", filter_map=str(fmap_path), duration=0.5, n_particles=200,
                   env=(("n_beams", 60),))  # fmt: skip
    result = run_one(spec, tmp_path / "log.csv")
    assert result.status == "ok"
    with pytest.raises(MapError, match=r"not found|no bundled"):
        run_one(
            RunSpec(map="basement_loop", filter_map="nope.yaml", duration=0.1), tmp_path / "x.csv"
        )


def test_world_differs_from_the_filter_map_stata(tmp_path):
    """The issue's case: drive in basement_fixed_aligned, localize on stata_basement."""
    world, stata = need_shared("maps/basement_fixed_aligned.yaml", "maps/stata_basement.yaml")
    spec = RunSpec(map=str(world), filter_map=str(stata), duration=2.0, n_particles=500, seed=1)
    result = run_one(spec, tmp_path / "log.csv")
    assert result.stats.mean_error < 0.3
