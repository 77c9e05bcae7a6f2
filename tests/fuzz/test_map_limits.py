"""Map files that would take the machine down with a careless loader: each gives one MapError line
quickly, before anything of the map's size is allocated."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from racecar_sim.maps import MapError, OccupancyMap, load_map, resolve_map
from racecar_sim.maps.limits import MAX_MAP_CELLS, check_cells, image_size
from racecar_sim.settings.validation import YAMLRefused, load_yaml, short
from tests.fuzz.hostile_maps import alias_bomb, fake_png, map_yaml, small_png

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture()
def room(tmp_path: Path) -> Path:
    """A 60 x 60 free room (3 m at 5 cm) with a wall border."""
    img = np.full((60, 60), 254, np.uint8)
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    small_png(tmp_path / "room.png", img)
    return tmp_path


def _one_line(exc: BaseException) -> str:
    text = str(exc)
    assert "\n" not in text
    return text


def test_alias_bomb_as_mode_is_refused_at_once(room: Path) -> None:
    path = room / "bomb.yaml"
    path.write_text(
        "image: room.png\nresolution: 0.05\norigin: [0, 0, 0]\n" + alias_bomb() + "mode: *a8\n"
    )
    t0 = time.perf_counter()
    with pytest.raises(MapError, match="anchors and aliases") as info:
        load_map(path)
    assert time.perf_counter() - t0 < 2.0
    assert len(_one_line(info.value)) < 300


def test_an_anchor_alone_is_refused_and_plain_yaml_reads() -> None:
    with pytest.raises(YAMLRefused):
        load_yaml("a: &x 1\nb: 2\n")
    with pytest.raises(YAMLRefused):
        load_yaml("base: &b {x: 1}\nother:\n  <<: *b\n")
    assert load_yaml("a: [1, 2]\nb: {c: x}\n") == {"a": [1, 2], "b": {"c": "x"}}


@pytest.mark.parametrize(
    ("text", "value"),
    [("1e12", 1e12), ("-2E-3", -2e-3), ("1.5e3", 1500.0), ("+3e0", 3.0), ("7", 7), ("1e", "1e")],
)
def test_exponent_without_a_dot_is_a_number(text: str, value: object) -> None:
    out = load_yaml(f"v: {text}")["v"]
    assert out == value and type(out) is type(value)


def test_deep_or_long_yaml_is_refused_in_one_line() -> None:
    with pytest.raises(YAMLRefused, match="nested too deeply"):
        load_yaml("[" * 200_000)
    with pytest.raises(YAMLRefused, match="more than"):
        load_yaml("a: " + "x" * 2_000_000)


def test_a_huge_value_is_quoted_short(room: Path) -> None:
    path = map_yaml(room, "room.png", mode="[" + ", ".join(["lol"] * 5000) + "]")
    with pytest.raises(MapError, match="'mode'") as info:
        load_map(path)
    assert len(_one_line(info.value)) < 200
    assert len(short("x" * 10_000)) <= 40


@pytest.mark.parametrize("side", [14000, 20000, 100_000])
def test_a_huge_png_is_refused_from_its_header(room: Path, side: int) -> None:
    fake_png(room / "huge.png", side, side)
    path = map_yaml(room, "huge.png")
    with pytest.raises(MapError, match="max_map_cells") as info:
        load_map(path)
    text = _one_line(info.value)
    assert f"{side} x {side}" in text and f"{MAX_MAP_CELLS:,}" in text


def test_the_limit_can_be_raised_by_the_setting(room: Path) -> None:
    path = map_yaml(room, "room.png")
    with pytest.raises(MapError, match="3,600 cells, more than the limit of 3,599"):
        load_map(path, max_cells=3599)
    assert load_map(path, max_cells=3600).shape == (60, 60)
    grid = OccupancyMap(occupied=np.zeros((10, 10), bool), resolution=0.05)
    with pytest.raises(MapError, match="max_map_cells"):
        resolve_map(grid, max_cells=99)


def test_the_limit_from_the_environment_variable(room: Path, monkeypatch) -> None:
    monkeypatch.setenv("RACECAR_SIM_MAX_MAP_CELLS", "100")
    with pytest.raises(MapError, match="limit of 100 "):
        load_map(map_yaml(room, "room.png"))
    monkeypatch.setenv("RACECAR_SIM_MAX_MAP_CELLS", "lots")
    with pytest.raises(MapError, match="RACECAR_SIM_MAX_MAP_CELLS"):
        check_cells("map", 2, 2)


def test_image_size_reads_png_and_pgm_headers(tmp_path: Path) -> None:
    img = np.zeros((30, 70), np.uint8)
    for name in ("a.png", "a.pgm", "a.bmp"):
        small_png(tmp_path / name, img)
        assert image_size(tmp_path / name) == (70, 30)
    (tmp_path / "junk.png").write_bytes(b"not an image")
    assert image_size(tmp_path / "junk.png") is None


@pytest.mark.parametrize(
    ("keys", "match"),
    [
        ({"resolution": "1e9"}, "'resolution' must be in"),
        ({"resolution": "1e-9"}, "'resolution' must be in"),
        ({"origin": "[1e300, 0, 0]"}, "'origin' x and y must be within"),
        ({"origin": "[.nan, 0, 0]"}, "'origin' must be finite"),
    ],
)
def test_resolution_and_origin_out_of_bounds(room: Path, keys: dict, match: str) -> None:
    with pytest.raises(MapError, match=match) as info:
        load_map(map_yaml(room, "room.png", **keys))
    _one_line(info.value)


def test_a_huge_real_png_stays_under_a_memory_limit(tmp_path: Path) -> None:
    """A real 14000 x 14000 PNG (small on disk) is refused in a process limited to 1 GB."""
    code = textwrap.dedent(
        f"""
        import resource, sys, zlib, struct
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
        sys.path.insert(0, {str(ROOT)!r})
        from tests.fuzz.hostile_maps import png_header
        side = 14000
        row = b"\\x00" + b"\\xfe" * side
        data = zlib.compress(row * side, 9)
        chunk = b"IDAT" + data
        png = (png_header(side, side) + struct.pack(">I", len(data)) + chunk
               + struct.pack(">I", zlib.crc32(chunk) & 0xFFFFFFFF) + b"\\0\\0\\0\\0IEND\\xaeB`\\x82")
        open({str(tmp_path / "real.png")!r}, "wb").write(png)
        open({str(tmp_path / "real.yaml")!r}, "w").write(
            "image: real.png\\nresolution: 0.05\\norigin: [0, 0, 0]\\n")
        from racecar_sim.maps import MapError, load_map
        try:
            load_map({str(tmp_path / "real.yaml")!r})
        except MapError as exc:
            print(exc)
        """
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "max_map_cells" in run.stdout and "Traceback" not in run.stderr


def test_the_vector_and_race_envs_apply_the_setting() -> None:
    from racecar_sim.race.env import RaceEnv
    from racecar_sim.vector_env import RacecarVectorEnv

    for make in (lambda: RacecarVectorEnv(2, map="corridor", max_map_cells=100),
                 lambda: RaceEnv("corridor", 2, max_map_cells=100)):  # fmt: skip
        with pytest.raises(MapError, match="more than the limit of 100 "):
            make()
