"""racecar_sim.file_guard and the writers that use it: racecar-sim writes only into new, empty or
its own folders, replaces only files it wrote, removes only empty folders it created, and takes
only paths the system can. Everything happens in temporary folders."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.experiments.video import FrameWriter
from mcl.wrappers.error_log import HEADER, ErrorLogWriter
from racecar_sim.file_guard import (
    MARKER,
    MAX_DEPTH,
    NAME_MAX,
    PATH_MAX,
    NotOurs,
    claim_folder,
    folder_problem,
    in_our_folder,
    overlaps,
    path_problem,
    writable,
)
from racecar_sim.world.track import Track


def test_a_new_folder_is_claimed_marked_and_released_when_nothing_was_written(tmp_path) -> None:
    claim = claim_folder(tmp_path / "a" / "b" / "c")
    assert (tmp_path / "a" / "b" / "c" / MARKER).is_file()
    (tmp_path / "a" / "b" / "c" / "logs" / "empty").mkdir(parents=True)
    assert claim.release()
    assert list(tmp_path.iterdir()) == []  # the folders it created, and only those, are gone


def test_a_path_through_dot_dot_is_claimed_and_released(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    claim = claim_folder(Path("a/./b/../c"))
    assert (tmp_path / "a" / "c" / MARKER).is_file() and (tmp_path / "a" / "b").is_dir()
    assert claim.release()
    assert list(tmp_path.iterdir()) == []


def test_a_folder_deeper_than_python_creates_is_refused_by_its_text() -> None:
    assert "300 folders deep" in path_problem("/".join(["x"] * 300))
    assert path_problem("/".join(["x"] * MAX_DEPTH)) is None


def test_release_keeps_everything_once_a_file_was_written(tmp_path) -> None:
    claim = claim_folder(tmp_path / "run")
    (tmp_path / "run" / "logs").mkdir()
    (tmp_path / "run" / "logs" / "half.csv").write_text("step\n1\n")
    assert not claim.release()
    assert (tmp_path / "run" / "logs" / "half.csv").read_text() == "step\n1\n"
    assert (tmp_path / "run" / MARKER).is_file()


def test_release_of_an_existing_empty_folder_removes_only_its_marker(tmp_path) -> None:
    claim = claim_folder(tmp_path)
    assert claim.created == [] and claim.marker_written
    assert claim.release()
    assert tmp_path.is_dir() and list(tmp_path.iterdir()) == []


def test_release_does_not_follow_a_link_into_another_folder(tmp_path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    claim = claim_folder(tmp_path / "run")
    (tmp_path / "run" / "link").symlink_to(other, target_is_directory=True)
    assert not claim.release()
    assert other.is_dir() and (tmp_path / "run" / "link").is_symlink()


def test_a_folder_of_other_files_is_refused_and_kept(tmp_path) -> None:
    (tmp_path / "data.txt").write_text("keep")
    problem = folder_problem(tmp_path)
    assert problem is not None and "data.txt" in problem
    with pytest.raises(NotOurs, match="did not write"):
        claim_folder(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.txt"]


def test_a_subfolder_of_ours_is_ours_unless_reached_through_a_link(tmp_path) -> None:
    claim_folder(tmp_path / "run")
    (tmp_path / "run" / "sub").mkdir()
    (tmp_path / "run" / "sub" / "old.csv").write_text("x")
    assert folder_problem(tmp_path / "run" / "sub") is None
    assert in_our_folder(tmp_path / "run" / "sub" / "old.csv")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "theirs.csv").write_text("theirs")
    (tmp_path / "run" / "link").symlink_to(elsewhere, target_is_directory=True)
    assert not in_our_folder(tmp_path / "run" / "link" / "theirs.csv")
    with pytest.raises(NotOurs):
        writable(tmp_path / "run" / "link" / "theirs.csv")
    (elsewhere / "sub").mkdir()
    (tmp_path / "run" / "deep").symlink_to(elsewhere / "sub", target_is_directory=True)
    # lexically run/theirs.csv, really elsewhere/theirs.csv: not ours
    with pytest.raises(NotOurs):
        writable(tmp_path / "run" / "deep" / ".." / "theirs.csv")
    assert (elsewhere / "theirs.csv").read_text() == "theirs"


def test_writable_refuses_links_folders_and_files_that_are_not_ours(tmp_path) -> None:
    target = tmp_path / "target.txt"
    target.write_text("theirs")
    (tmp_path / "link.txt").symlink_to(target)
    claim_folder(tmp_path / "ours")
    (tmp_path / "ours" / "link.txt").symlink_to(target)
    for path in (target, tmp_path / "link.txt", tmp_path / "ours" / "link.txt", tmp_path / "ours"):
        with pytest.raises(NotOurs):
            writable(path)
    assert target.read_text() == "theirs"
    assert writable(tmp_path / "new.txt") == tmp_path / "new.txt"  # a new file is fine
    assert writable(target, lambda p: p.read_text() == "theirs") == target  # recognised


def test_the_error_log_replaces_an_error_log_and_nothing_else(tmp_path) -> None:
    log = tmp_path / "log.csv"
    with ErrorLogWriter(log) as w:
        w.write(1, 0.025, np.zeros(3), np.zeros(3), 0.0, 0.0, 10.0, 0.001)
    with ErrorLogWriter(log) as w:  # an earlier log: replaced
        pass
    assert log.read_text() == ",".join(HEADER) + "\n"
    mine = tmp_path / "results.csv"
    mine.write_text("step,time\n1,2\n")  # starts like a log, is not one
    with pytest.raises(NotOurs):
        ErrorLogWriter(mine)
    assert mine.read_text() == "step,time\n1,2\n"


def test_frame_writer_and_track_csv_do_not_overwrite_a_users_file(tmp_path) -> None:
    clip = tmp_path / "holiday.mp4"
    clip.write_bytes(b"my video")
    writer = FrameWriter(clip, fps=5)
    with pytest.raises(NotOurs):
        writer.write(np.zeros((4, 4, 3), dtype=np.uint8))
    assert clip.read_bytes() == b"my video"
    track = Track(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    csv = tmp_path / "track.csv"
    csv.write_text("# x_m, y_m, w_tr_right_m, w_tr_left_m\n1, 2, 3, 4\n")  # someone's track
    with pytest.raises(NotOurs):
        track.to_csv(csv)
    claim_folder(tmp_path / "ours")
    written = track.to_csv(tmp_path / "ours" / "track.csv")
    assert track.to_csv(written) == written  # its own file in its own folder: replaced
    np.testing.assert_allclose(Track.from_csv(written).points, track.points)


def test_run_pending_refuses_a_folder_of_other_files(tmp_path) -> None:
    from mcl.experiments.runner import run_pending

    (tmp_path / "thesis.tex").write_text("\\section{}")
    with pytest.raises(NotOurs):
        run_pending(object(), [], tmp_path, workers=1, resume=False, reuse=lambda s, p: None,
                    progress=False, stream=None)  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis.tex"]


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [("x", "x", True), ("x", "x/y", True), ("x/y", "x", True), ("x/./y/..", "x", True),
     ("x", "xy", False), ("x/y", "x/z", False)],
)  # fmt: skip
def test_overlaps(a, b, expected, tmp_path) -> None:
    assert overlaps(tmp_path / a, tmp_path / b) is expected


def test_a_link_to_a_folder_overlaps_it(tmp_path) -> None:
    (tmp_path / "real").mkdir()
    (tmp_path / "alias").symlink_to(tmp_path / "real", target_is_directory=True)
    assert overlaps(tmp_path / "alias" / "inner", tmp_path / "real")


_NAMES = st.lists(st.text(min_size=1, max_size=300).filter(lambda t: "/" not in t), max_size=20)
_DEEP = st.lists(st.sampled_from(["x", "é", ".", ""]), min_size=240, max_size=280)


@given(_NAMES | _DEEP)
def test_path_problem_is_none_exactly_for_names_the_system_takes(parts) -> None:
    text = "/".join(parts)
    raw = [p.encode("utf-8", "surrogateescape") for p in parts]
    fine = (
        text != ""
        and "\0" not in text
        and len(text.encode("utf-8", "surrogateescape")) < PATH_MAX
        and all(len(r) <= NAME_MAX for r in raw)
        and sum(1 for p in parts if p not in ("", ".")) <= MAX_DEPTH
    )
    assert (path_problem(text) is None) is fine


def test_path_problem_says_what_is_wrong_in_a_short_line() -> None:
    assert "empty" in path_problem("")
    assert "256 bytes" in path_problem("a/" + "n" * 256)
    assert path_problem("a/" + "n" * 255) is None
    assert "256 bytes" in path_problem("é" * 128)  # 2 bytes per character
    long = path_problem("/".join(["d" * 99] * 50))
    assert "4999 bytes" in long and len(long) < 200
