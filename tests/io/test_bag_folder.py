"""BagRecorder replaces a folder only when it holds exactly a recording of ours (mcl.io.bag_folder);
anything else at the path is refused and left as it was. Everything happens in temporary folders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.io import BagRecorder, read_bag
from mcl.io.bag_folder import recording_problem
from mcl.io.bag_writer import TOPICS
from racecar_sim.file_guard import NotOurs
from tests.io.bag_fixtures import record_drive

ANGLES = np.linspace(-math.pi / 2, math.pi / 2, 11)


def _tree(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _recorder(path, room, **kwargs) -> BagRecorder:
    return BagRecorder(path, room, ANGLES, 10.0, 0.2, **kwargs)


def test_a_folder_of_other_files_is_refused_and_kept(tmp_path, room) -> None:
    folder = tmp_path / "important"
    (folder / "sub").mkdir(parents=True)
    (folder / "data.txt").write_text("keep")
    (folder / "sub" / "metadata.yaml").write_text("not: ours")
    before = _tree(folder)
    with pytest.raises(NotOurs, match="other files than a recording"):
        _recorder(folder, room)
    assert _tree(folder) == before


def test_an_earlier_recording_of_ours_is_replaced(tmp_path, room) -> None:
    path = tmp_path / "drive"
    record_drive(path, room, duration=0.5)
    assert recording_problem(path, TOPICS) is None
    old = read_bag(path)
    with _recorder(path, room) as rec:  # a new, different recording at the same place
        rec.write_static(0.0)
        rec.write_odom(0.0, np.zeros(3), np.zeros(3))
        rec.write_scan(0.0, np.full(ANGLES.size, 3.0))
    new = read_bag(path)
    assert old.n_beams != new.n_beams == ANGLES.size and new.n_scans == 1
    assert sorted(p.name for p in path.iterdir()) == ["drive.mcap", "metadata.yaml"]


def test_overwrite_false_refuses_even_a_recording_of_ours(tmp_path, room) -> None:
    path = tmp_path / "drive"
    record_drive(path, room, duration=0.3)
    before = _tree(path)
    with pytest.raises(FileExistsError):
        _recorder(path, room, overwrite=False)
    assert _tree(path) == before


def test_a_recording_whose_metadata_was_edited_is_refused(tmp_path, room) -> None:
    path = tmp_path / "drive"
    record_drive(path, room, duration=0.3)
    meta = path / "metadata.yaml"
    meta.write_text(meta.read_text().replace("/pf/particles", "/camera/image"))
    before = _tree(path)
    with pytest.raises(NotOurs, match="not a racecar-sim recording"):
        _recorder(path, room)
    assert _tree(path) == before
    meta.write_text("{{{{ not yaml")
    with pytest.raises(NotOurs):
        _recorder(path, room)
    assert (path / "drive.mcap").is_file()
