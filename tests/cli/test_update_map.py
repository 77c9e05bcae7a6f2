"""``racecar-sim update-map``: an out-of-date map updated from simulated drives, written as new
map files only; a user's mistake is one line naming the flag, before any drive."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from racecar_sim.maps import load_map, resolve_map
from racecar_sim.maps.changes import with_cells
from racecar_sim.maps.writer import save_map
from tests.cli.test_mistakes import assert_one_line_error, run


def _old_loop(folder: Path) -> tuple[Path, np.ndarray]:
    """The bundled loop with the free band within 0.4 m of its walls drawn as wall for
    x = 5..9 m (a recess the world has and the old map lacks), saved as a map_server map;
    returns (its YAML, the recess's cells)."""
    world = resolve_map("basement_loop")
    band = cv2.dilate(world.occupied.astype(np.uint8), np.ones((17, 17), np.uint8)).astype(bool)
    rows, cols = np.indices(world.shape)
    x = world.grid_to_world(np.stack([rows, cols], axis=-1))[..., 0]
    recess = band & ~world.occupied & (x >= 5.0) & (x <= 9.0)
    return save_map(with_cells(world, recess, free=False), folder / "old.yaml"), recess


def test_update_map_writes_the_old_map_with_the_recess_opened(tmp_path, capsys) -> None:
    old_yaml, recess = _old_loop(tmp_path)
    out = tmp_path / "maps" / "updated.yaml"  # the folder is made
    code, stdout, err = run(
        ["update-map", "--map", "basement_loop", "--filter-map", str(old_yaml), "--scene", "none",
         "--drives", "3", "--duration", "8", "--param", "drives_needed=2", "--out", str(out),
         "--quiet"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert sorted(p.name for p in out.parent.iterdir()) == ["updated.pgm", "updated.yaml"]
    old, new = load_map(old_yaml), load_map(out)
    assert new.shape == old.shape and np.allclose(new.origin, old.origin)
    assert not (new.occupied & ~old.occupied).any()  # cells are only opened
    opened = old.occupied & ~new.occupied
    assert opened.sum() > 500
    near = cv2.dilate(recess.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
    assert (opened & near).sum() > 0.8 * opened.sum()  # within 0.25 m of the recess
    assert f"{int(opened.sum())} cells opened" in stdout and "of 3 drives" in stdout


@pytest.mark.parametrize(
    ("case", "flag", "fragment"),
    [
        ("yaml-there", "--out", "already there"),
        ("pgm-there", "--out", "already there"),
        ("not-yaml", "--out", "must end in .yaml"),
        ("bad-param", "--param", "drives_needed"),
        ("unknown-param", "--param", "drives"),
        ("missing-filter-map", "--filter-map", "missing.yaml"),
        ("bad-scene", "--scene", "invalid choice"),
        ("no-filter-map", "--filter-map", "is required"),
    ],
)
def test_a_mistake_is_one_line_before_any_drive_and_touches_nothing(
    case, flag, fragment, tmp_path, capsys, monkeypatch
) -> None:
    import mcl.cli.update_map as command

    def no_drive(*args, **kwargs):
        raise AssertionError("a drive was started")

    monkeypatch.setattr(command, "record_drive", no_drive)
    mine = tmp_path / "mine.yaml"
    args = {"--map": "corridor", "--filter-map": "corridor", "--out": str(mine)}
    extra: list[str] = []
    if case == "yaml-there":
        mine.write_text("the user's own file\n")
    elif case == "pgm-there":
        (tmp_path / "mine.pgm").write_bytes(b"the user's own image")
    elif case == "not-yaml":
        args["--out"] = str(tmp_path / "mine.pgm")
    elif case == "bad-param":
        extra = ["--param", "drives_needed=0"]
    elif case == "unknown-param":
        extra = ["--param", "drives=2"]
    elif case == "missing-filter-map":
        args["--filter-map"] = str(tmp_path / "missing.yaml")
    elif case == "bad-scene":
        extra = ["--scene", "jungle"]
    elif case == "no-filter-map":
        del args["--filter-map"]
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    argv = ["update-map", *[w for kv in args.items() for w in kv], *extra, "--quiet"]
    code, _, err = run(argv, capsys)
    assert_one_line_error(code, err, flag, fragment)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
