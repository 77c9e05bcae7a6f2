"""Tests for racecar_sim.maps.draw: the shipped maps are reproducible, closed and drivable."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from mcl.cli.make_maps import main as make_maps_command
from racecar_sim.maps import draw

MAPS_DIR = draw.bundled_dir()
NAMES = ["basement_loop", "office", "corridor"]
MIN_FREE_AREA = {"basement_loop": 150.0, "office": 150.0, "corridor": 70.0}  # m^2
FREE, UNKNOWN, OCCUPIED = 254, 205, 0


def _load(name: str, folder: Path = MAPS_DIR) -> tuple[np.ndarray, dict]:
    meta = yaml.safe_load((folder / f"{name}.yaml").read_text(encoding="utf-8"))
    img = cv2.imread(str(folder / meta["image"]), cv2.IMREAD_UNCHANGED)
    assert img is not None
    return img, meta


def _cell(meta: dict, shape: tuple[int, int], x: float, y: float) -> tuple[int, int]:
    """(row, col) of the cell holding world point (x, y) in metres."""
    res = meta["resolution"]
    ox, oy = meta["origin"][:2]
    col = math.floor((x - ox) / res)
    row = shape[0] - 1 - math.floor((y - oy) / res)
    assert 0 <= row < shape[0] and 0 <= col < shape[1]
    return row, col


def _clearance(img: np.ndarray, res: float) -> np.ndarray:
    """Distance in metres from each free cell centre to the nearest non-free cell centre."""
    free = (img == FREE).astype(np.uint8)
    return cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res


def _has_hole(mask: np.ndarray) -> bool:
    """True if the region ``mask`` (4-connected) encloses part of its complement."""
    padded = np.pad(~mask, 1, constant_values=True).astype(np.uint8)
    n, _ = cv2.connectedComponents(padded, connectivity=8)
    return n - 1 >= 2  # the outside plus at least one enclosed island


def _component_at(mask: np.ndarray, rc: tuple[int, int]) -> np.ndarray:
    _, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=4)
    assert labels[rc] != 0, "point is not in the region"
    return labels == labels[rc]


def test_draw_maps_is_deterministic_and_matches_committed_files(tmp_path: Path) -> None:
    first = draw.draw_maps(tmp_path / "a")
    second = draw.draw_maps(tmp_path / "b")
    assert [p.name for p in first] == [f"{n}.yaml" for n in NAMES]
    for path_a, path_b in zip(first, second, strict=True):
        for suffix in (".yaml", ".png"):
            a = path_a.with_suffix(suffix).read_bytes()
            assert a == path_b.with_suffix(suffix).read_bytes()
            committed = MAPS_DIR / path_a.with_suffix(suffix).name
            assert a == committed.read_bytes(), f"{committed} is stale: rerun racecar-sim make-maps"


def test_main_writes_to_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert make_maps_command(["--out", str(tmp_path)]) == 0
    for name in NAMES:
        assert (tmp_path / f"{name}.yaml").is_file()
        assert (tmp_path / f"{name}.png").is_file()
    assert "basement_loop" in capsys.readouterr().out


@pytest.mark.parametrize("name", NAMES)
def test_yaml_is_map_server_format(name: str) -> None:
    meta = yaml.safe_load((MAPS_DIR / f"{name}.yaml").read_text(encoding="utf-8"))
    assert meta == {
        "image": f"{name}.png",
        "resolution": 0.05,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        "mode": "trinary",
    }


@pytest.mark.parametrize("name", NAMES)
def test_map_is_closed_and_connected(name: str) -> None:
    img, meta = _load(name)
    res = meta["resolution"]
    assert img.dtype == np.uint8 and img.ndim == 2
    assert set(np.unique(img).tolist()) <= {FREE, UNKNOWN, OCCUPIED}
    free = img == FREE
    assert free.any()
    # One 4-connected free region, big enough.
    n, _ = cv2.connectedComponents(free.astype(np.uint8), connectivity=4)
    assert n - 1 == 1
    assert free.sum() * res**2 > MIN_FREE_AREA[name]
    # The image border is never free, and free space is walled off from the unknown outside
    # by at least 2 occupied cells.
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    assert not (border == FREE).any()
    near_free = cv2.dilate(free.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert not (near_free & (img == UNKNOWN)).any()


@pytest.mark.parametrize("name", NAMES)
def test_start_pose_is_in_open_free_space(name: str) -> None:
    img, meta = _load(name)
    x, y, theta = draw.START_POSES[name]
    assert -math.pi <= theta < math.pi
    rc = _cell(meta, img.shape, x, y)
    assert img[rc] == FREE
    assert _clearance(img, meta["resolution"])[rc] >= 0.75


def test_basement_loop_is_a_loop_of_hallways() -> None:
    img, meta = _load("basement_loop")
    res = meta["resolution"]
    h, w = img.shape
    assert 28.0 <= w * res <= 34.0 and 18.0 <= h * res <= 24.0
    free = img == FREE
    # Not simply connected: there is an island of wall inside the loop.
    assert _has_hole(free)
    clearance = _clearance(img, res)
    start = _cell(meta, img.shape, *draw.START_POSES["basement_loop"][:2])
    # Every hallway of the loop is at least 1.6 m wide: the cells with 0.8 m clearance still
    # form a loop through the start pose ...
    assert _has_hole(_component_at(clearance >= 0.8, start))
    # ... and the hallways are not wider than 2.5 m all the way round.
    wide = clearance >= 1.25
    n, labels = cv2.connectedComponents(wide.astype(np.uint8), connectivity=4)
    assert not any(_has_hole(labels == k) for k in range(1, n))
    # Local hallway width (twice the max inscribed distance) at each hallway's centre.
    win = round(0.3 / res)
    for hall, (x, y) in draw.BASEMENT_HALL_CENTRES.items():
        r, c = _cell(meta, img.shape, x, y)
        half_width = clearance[r - win : r + win + 1, c - win : c + win + 1].max()
        assert 1.8 <= 2 * half_width <= 2.4, f"{hall} hallway is {2 * half_width:.2f} m wide"


def test_basement_loop_is_not_symmetric() -> None:
    free = _load("basement_loop")[0] == FREE
    for flipped in (free[::-1], free[:, ::-1], free[::-1, ::-1]):
        assert (flipped != free).mean() > 0.05


def test_office_has_a_wide_driving_loop() -> None:
    img, meta = _load("office")
    res = meta["resolution"]
    start = _cell(meta, img.shape, *draw.START_POSES["office"][:2])
    assert _has_hole(_component_at(_clearance(img, res) >= 0.75, start))


def test_corridor_is_a_plain_closed_rectangle() -> None:
    img, meta = _load("corridor")
    res = meta["resolution"]
    rows, cols = np.nonzero(img == FREE)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    assert (img[r0:r1, c0:c1] == FREE).all()
    assert (img == FREE).sum() == (r1 - r0) * (c1 - c0)
    assert (c1 - c0) * res == pytest.approx(40.0)
    assert (r1 - r0) * res == pytest.approx(2.0)
    # Closed at both ends and along both sides.
    assert (img[r0 - 2 : r1 + 2, c0 - 2 : c0] == OCCUPIED).all()
    assert (img[r0 - 2 : r1 + 2, c1 : c1 + 2] == OCCUPIED).all()
    assert (img[r0 - 2 : r0, c0:c1] == OCCUPIED).all()
    assert (img[r1 : r1 + 2, c0:c1] == OCCUPIED).all()
