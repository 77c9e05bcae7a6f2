"""Map loading (ROS map_server YAML), frames, distance field, errors and bundled maps."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.maps import (
    DEFAULT_MAP,
    MapError,
    OccupancyMap,
    bundled,
    bundled_names,
    load_map,
    resolve_map,
)


def write_map(
    folder: Path,
    pixels: np.ndarray,
    *,
    name: str = "m",
    ext: str = "png",
    **overrides: object,
) -> Path:
    """Write an image and its YAML; keys in ``overrides`` replace (or, when None, drop) YAML keys."""
    cv2.imwrite(str(folder / f"{name}.{ext}"), pixels)
    data: dict[str, object] = {
        "image": f"{name}.{ext}",
        "resolution": 0.1,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    for key, value in overrides.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def room_pixels(h: int = 6, w: int = 8) -> np.ndarray:
    """A free room (254) inside a one-cell black wall, with an unknown (205) cell and a wall block."""
    img = np.full((h, w), 254, np.uint8)
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    img[1, 1] = 205  # unknown: counts as occupied
    img[2, 5] = 0
    return img


# ---------------------------------------------------------------- loading
def test_load_png_classifies_free_occupied_unknown(tmp_path: Path) -> None:
    grid = load_map(write_map(tmp_path, room_pixels()))
    assert grid.shape == (6, 8)
    assert grid.occupied[0].all() and grid.occupied[:, 0].all()
    assert grid.occupied[1, 1], "unknown cells must count as occupied"
    assert grid.occupied[2, 5]
    assert not grid.occupied[3, 3]
    assert np.count_nonzero(~grid.occupied) == 4 * 6 - 2
    assert grid.resolution == pytest.approx(0.1)


def test_load_pgm_and_rgb_images(tmp_path: Path) -> None:
    pgm = load_map(write_map(tmp_path, room_pixels(), name="gray", ext="pgm"))
    rgb = load_map(write_map(tmp_path, cv2.cvtColor(room_pixels(), cv2.COLOR_GRAY2BGR), name="rgb"))
    png = load_map(write_map(tmp_path, room_pixels(), name="png"))
    np.testing.assert_array_equal(pgm.occupied, png.occupied)
    np.testing.assert_array_equal(rgb.occupied, png.occupied)


def test_negate_inverts_the_meaning_of_pixels(tmp_path: Path) -> None:
    plain = load_map(write_map(tmp_path, room_pixels(), name="plain"))
    # With negate 1, white is occupied and black is free: the inverted image gives the same map.
    inverted = 255 - room_pixels()
    negated = load_map(write_map(tmp_path, inverted, name="neg", negate=1))
    np.testing.assert_array_equal(negated.occupied, plain.occupied)


def test_image_path_is_relative_to_the_yaml(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sub = tmp_path / "deep" / "folder"
    sub.mkdir(parents=True)
    path = write_map(sub, room_pixels())
    monkeypatch.chdir(tmp_path)
    assert load_map(path).shape == (6, 8)


def test_raw_mode_reads_percentages(tmp_path: Path) -> None:
    img = np.full((4, 5), 0, np.uint8)  # 0 % occupied: free
    img[0, :] = 100  # occupied
    img[1, 1] = 255  # unknown
    grid = load_map(write_map(tmp_path, img, mode="raw"))
    assert grid.occupied[0].all() and grid.occupied[1, 1]
    assert not grid.occupied[2:].any()


# ---------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        ({"resolution": None}, "resolution"),
        ({"resolution": 0}, "resolution"),
        ({"resolution": -0.05}, "resolution"),
        ({"resolution": "fine"}, "resolution"),
        ({"image": None}, "image"),
        ({"image": "nothere.png"}, "nothere.png"),
        ({"origin": [0, 0]}, "origin"),
        ({"occupied_thresh": 1.5}, "occupied_thresh"),
        ({"free_thresh": -0.1}, "free_thresh"),
        ({"free_thresh": 0.7, "occupied_thresh": 0.6}, "free_thresh"),
        ({"negate": 3}, "negate"),
        ({"mode": "fuzzy"}, "mode"),
    ],
)
def test_bad_yaml_raises_map_error_naming_file_and_problem(
    tmp_path: Path, overrides: dict, fragment: str
) -> None:
    path = write_map(tmp_path, room_pixels(), **overrides)
    with pytest.raises(MapError) as err:
        load_map(path)
    assert str(path) in str(err.value)
    assert fragment in str(err.value)
    assert isinstance(err.value, ValueError)


def test_missing_yaml_file(tmp_path: Path) -> None:
    with pytest.raises(MapError, match="file not found"):
        load_map(tmp_path / "absent.yaml")


def test_unreadable_image(tmp_path: Path) -> None:
    path = write_map(tmp_path, room_pixels())
    (tmp_path / "m.png").write_bytes(b"this is not a png")
    with pytest.raises(MapError, match="could not be read"):
        load_map(path)


def test_map_with_no_free_cell(tmp_path: Path) -> None:
    with pytest.raises(MapError, match="no free cell"):
        load_map(write_map(tmp_path, np.zeros((5, 5), np.uint8)))


def test_yaml_that_is_not_a_mapping(tmp_path: Path) -> None:
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(MapError, match="mapping"):
        load_map(path)


# ---------------------------------------------------------------- frames
def test_origin_without_yaw_puts_cell_corners_where_map_server_does(tmp_path: Path) -> None:
    grid = load_map(write_map(tmp_path, room_pixels(), origin=[-1.0, 2.0, 0.0]))
    h = grid.height
    # The bottom-left cell (row H-1, col 0) has its centre half a cell from the origin.
    np.testing.assert_allclose(grid.grid_to_world([h - 1, 0]), [-1.0 + 0.05, 2.0 + 0.05])
    # The top-left cell is H-1 cells above.
    np.testing.assert_allclose(grid.grid_to_world([0, 0]), [-0.95, 2.0 + (h - 0.5) * 0.1])
    np.testing.assert_array_equal(grid.world_to_grid([-0.99, 2.01]), [h - 1, 0])


def test_origin_yaw_rotates_the_grid_about_the_origin(tmp_path: Path) -> None:
    yaw = 3.14
    grid = load_map(write_map(tmp_path, room_pixels(), origin=[25.9, 48.5, yaw]))
    h = grid.height
    # Cell (row, col) corner in the unrotated frame is (col*res, (H-1-row)*res); rotate by yaw.
    row, col = 2, 5
    u, v = (col + 0.5) * 0.1, (h - 1 - row + 0.5) * 0.1
    expected = [
        25.9 + math.cos(yaw) * u - math.sin(yaw) * v,
        48.5 + math.sin(yaw) * u + math.cos(yaw) * v,
    ]
    np.testing.assert_allclose(grid.grid_to_world([row, col]), expected, atol=1e-12)
    # With yaw ~ pi, cells with larger columns lie at smaller world x.
    assert grid.grid_to_world([2, 6])[0] < grid.grid_to_world([2, 1])[0]


@settings(max_examples=60, deadline=None)
@given(
    yaw=st.floats(-math.pi, math.pi),
    ox=st.floats(-50, 50),
    oy=st.floats(-50, 50),
    row=st.integers(0, 5),
    col=st.integers(0, 7),
)
def test_world_grid_round_trip(yaw: float, ox: float, oy: float, row: int, col: int) -> None:
    grid = OccupancyMap(occupied=room_pixels() == 0, resolution=0.1, origin=(ox, oy, yaw))
    centre = grid.grid_to_world(np.array([[row, col]]))
    np.testing.assert_array_equal(grid.world_to_grid(centre), [[row, col]])
    np.testing.assert_allclose(grid.map_to_world(grid.world_to_map(centre)), centre, atol=1e-9)


def test_vectorised_conversions_keep_shapes() -> None:
    grid = OccupancyMap(occupied=room_pixels() == 0, resolution=0.1)
    pts = np.zeros((3, 4, 2))
    assert grid.world_to_grid(pts).shape == (3, 4, 2)
    assert grid.grid_to_world(np.zeros((5, 2), int)).shape == (5, 2)
    assert grid.is_free(pts).shape == (3, 4)


def test_is_free_outside_the_map_is_false() -> None:
    grid = OccupancyMap(occupied=room_pixels() == 0, resolution=0.1)
    assert not grid.is_free(np.array([-1.0, -1.0]))
    assert grid.is_free(grid.grid_to_world(np.array([3, 3])))


# ---------------------------------------------------------------- distance field
def test_distance_field_matches_brute_force() -> None:
    rng = np.random.default_rng(3)
    occ = rng.random((20, 30)) < 0.08
    occ[5, 5] = False
    grid = OccupancyMap(occupied=occ, resolution=0.05)
    # Brute force: nearest occupied cell centre, where the ring of cells around the image is occupied.
    padded = np.pad(occ, 1, constant_values=True)
    walls = np.argwhere(padded) - 1
    cells = np.argwhere(np.ones_like(occ))
    d = np.sqrt(((cells[:, None, :] - walls[None, :, :]) ** 2).sum(-1)).min(axis=1)
    np.testing.assert_allclose(grid.distance.reshape(-1), d * 0.05, atol=1e-3)
    assert (grid.distance[occ] == 0).all()


# ---------------------------------------------------------------- sampling
def test_sample_free_poses_lands_in_free_space_with_wrapped_heading() -> None:
    grid = OccupancyMap(occupied=room_pixels() == 0, resolution=0.1, origin=(1.0, 2.0, 1.0))
    poses = grid.sample_free_poses(np.random.default_rng(0), 500)
    assert poses.shape == (500, 3)
    assert grid.is_free(poses[:, :2]).all()
    assert (poses[:, 2] >= -math.pi).all() and (poses[:, 2] < math.pi).all()


def test_sample_free_poses_respects_clearance() -> None:
    occ = np.zeros((40, 40), bool)
    grid = OccupancyMap(occupied=occ, resolution=0.1)
    poses = grid.sample_free_poses(np.random.default_rng(1), 300, clearance=1.0)
    assert (grid.distance_at(poses[:, :2]) >= 1.0).all()
    with pytest.raises(MapError, match="clearance"):
        grid.sample_free_poses(np.random.default_rng(1), 1, clearance=100.0)


def test_sampling_keeps_each_clearance_apart_on_one_map() -> None:
    # the free cells are found once per clearance: a draw with another clearance in between
    # must neither narrow nor widen the next
    grid = OccupancyMap(occupied=np.zeros((40, 40), bool), resolution=0.1)
    rng = np.random.default_rng(2)
    for clearance in (1.0, 0.0, 1.0, 0.0):
        d = grid.distance_at(grid.sample_free_poses(rng, 300, clearance=clearance)[:, :2])
        assert (d >= clearance).all()
        if clearance == 0.0:  # 70 % of this room's cells lie under 1 m from its edge
            assert (d < 1.0).mean() > 0.6


# ---------------------------------------------------------------- real and bundled maps
def test_stata_basement_loads_with_its_yaw(stata_map: OccupancyMap) -> None:
    assert stata_map.shape == (1300, 1730)
    assert stata_map.resolution == pytest.approx(0.0504)
    assert stata_map.origin[2] == pytest.approx(3.14)
    # The README of ../shared/maps measures about 780 m² of free floor.
    assert 700 < stata_map.free_area < 860


def test_bundled_maps_exist_and_load() -> None:
    names = bundled_names()
    assert DEFAULT_MAP in names
    for name in names:
        path = bundled(name)
        assert path.suffix == ".yaml"
        grid = load_map(path)
        assert grid.free_area > 10.0


def test_unknown_bundled_name_lists_the_known_ones() -> None:
    with pytest.raises(MapError) as err:
        bundled("atlantis")
    assert "atlantis" in str(err.value)
    assert DEFAULT_MAP in str(err.value)


def test_resolve_map_accepts_names_paths_and_maps(tmp_path: Path) -> None:
    grid = resolve_map(None)
    assert grid.name == DEFAULT_MAP
    assert resolve_map(grid) is grid
    path = write_map(tmp_path, room_pixels())
    assert resolve_map(str(path)).shape == (6, 8)
