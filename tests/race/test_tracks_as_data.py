"""Tracks as data: the bundled loop maps' centerlines are files beside the maps, ``track="auto"``
derives one on any map whose free space runs round an island, and the single env reaches all
this without importing the race package."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.world.centerline import (
    bundled_track,
    bundled_track_path,
    derive_centerline,
    loop_centerline,
)
from racecar_sim.world.track import LOOP_STARTS

ROOT = Path(__file__).resolve().parents[2]


def ring_map(name: str = "ring", resolution: float = 0.05) -> OccupancyMap:
    """A 12 m x 8 m room with a 6 m x 2.4 m island: a 1.8 m wide corridor all round."""
    occupied = np.zeros((160, 240), dtype=bool)
    occupied[:4, :] = occupied[-4:, :] = occupied[:, :4] = occupied[:, -4:] = True
    occupied[40:120, 40:200] = True
    return OccupancyMap(occupied=occupied, resolution=resolution, origin=(0.0, 0.0, 0.0), name=name)


def nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.min(np.hypot(*(a[:, None, :] - b[None, :, :]).transpose(2, 0, 1)), axis=1)


@pytest.mark.parametrize("name", sorted(LOOP_STARTS))
def test_every_bundled_loop_map_ships_both_tracks(name: str) -> None:
    for kind in ("centerline", "loop"):
        assert bundled_track_path(name, kind).is_file(), f"{name}: no {kind} CSV beside the map"
    centre = bundled_track(name)
    assert centre is not None and centre.widths is not None
    grid = resolve_map(name)
    assert grid.is_free(centre.points).all()
    # the centerline starts at the map's loop start and runs the way it points
    x, y, theta = LOOP_STARTS[name]
    assert np.hypot(*(centre.points[0] - (x, y))) < 1.0
    ahead = centre.points[1] - centre.points[0]
    assert ahead @ (np.cos(theta), np.sin(theta)) > 0


def test_the_derived_centerline_of_basement_loop_follows_the_bundled_one() -> None:
    grid = resolve_map("basement_loop")
    derived = derive_centerline(grid, LOOP_STARTS["basement_loop"])
    bundled = bundled_track("basement_loop")
    gap = nearest(derived.points, bundled.points)
    assert gap.max() < 0.5 and gap.mean() < 0.15
    assert abs(derived.length - bundled.length) < 0.02 * bundled.length
    assert np.hypot(*(derived.points[0] - bundled.points[0])) < 0.5


def test_auto_on_a_map_that_was_never_bundled() -> None:
    grid = ring_map()
    track = loop_centerline(grid)
    # the midline of the 1.8 m corridor round the island: 0.9 m from both walls all round
    island_x, island_y = (2.0, 10.0), (2.0, 6.0)  # metres (rows 40-120 of 160 at 0.05 m)
    x, y = track.points.T
    outside = np.maximum(np.maximum(island_x[0] - x, x - island_x[1]), np.maximum(island_y[0] - y, y - island_y[1]))
    clearance = np.minimum(outside, grid.distance_at(track.points))
    assert clearance.min() > 0.4  # the corners are cut (centre_loop smooths over ~1.5 m)
    assert abs(np.median(clearance) - 0.9) < 0.1  # the straights run down the middle
    assert track.widths is not None and (track.widths.sum(axis=1) > 1.4).all()
    # counter-clockwise: the island on the left
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert area > 0
    assert 2 * (8.0 + 4.2) * 0.9 < track.length < 2 * (12.0 + 8.0)


def test_auto_on_a_map_with_no_island_says_so() -> None:
    with pytest.raises(ValueError, match="not a loop map"):
        loop_centerline(resolve_map("corridor"))


def test_the_single_env_drives_laps_on_a_derived_track_without_the_race_package() -> None:
    code = (
        "import sys, numpy as np\n"
        "from tests.race.test_tracks_as_data import ring_map\n"
        "from racecar_sim.env import RacecarEnv\n"
        "from racecar_sim.drivers import PurePursuit\n"
        "env = RacecarEnv(ring_map(), track='auto')\n"
        "pts = env.track.points\n"
        "heading = np.arctan2(*(pts[1] - pts[0])[::-1])\n"
        "obs, info = env.reset(seed=0, options={'pose': [pts[0][0], pts[0][1], heading]})\n"
        "driver = PurePursuit(pts, speed=3.0)\n"
        "for _ in range(1200):\n"
        "    obs, r, term, trunc, info = env.step(driver(None, info['pose']))\n"
        "    if term: break\n"
        "print(info['lap'], round(env.track.length, 2), any(m.startswith('racecar_sim.race') for m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    laps, _length, imported_race = out.stdout.split()
    assert int(laps) >= 1, out.stdout
    assert imported_race == "False"


def test_make_maps_writes_the_bundled_tracks_as_they_are(tmp_path) -> None:
    from mcl.cli.make_maps import main

    assert main(["--out", str(tmp_path / "maps")]) == 0
    for name in sorted(LOOP_STARTS):
        for kind in ("centerline", "loop"):
            written = (tmp_path / "maps" / f"{name}_{kind}.csv").read_text()
            assert written == bundled_track_path(name, kind).read_text(), f"{name}_{kind}.csv is stale"
