"""Damaged ROS 1 bags: cut inside the first chunk, a chunk written twice, chunks out of time order,
every message written twice. Each keeps what the file holds, reads every message once and says what
happened in one line."""

from __future__ import annotations

import numpy as np
import pytest

from mcl.io import BagError, read_bag
from tests.io.bag_fixtures import (
    BAG1,
    chunk_spans,
    duplicate_chunk,
    move_chunk,
    shared_bag,
    write_ros1_drive,
)


@pytest.fixture(scope="module")
def ros1(tmp_path_factory, room):
    """A 4 s synthetic drive as a ROS 1 bag of 6 uncompressed chunks, and what it reads as."""
    path = write_ros1_drive(tmp_path_factory.mktemp("ros1") / "drive.bag", room)
    return path, read_bag(path)


def _same_messages(data, full, n_scans=None) -> None:
    n = full.n_scans if n_scans is None else n_scans
    np.testing.assert_array_equal(data.scans, full.scans[:n])
    np.testing.assert_array_equal(data.scan_times, full.scan_times[:n])
    m = data.odom_times.size
    np.testing.assert_array_equal(data.odom_twist, full.odom_twist[:m])


def _one_line_each(warnings) -> None:
    assert all("\n" not in w and len(w) < 300 for w in warnings), warnings


def test_the_fixture_has_several_chunks_and_reads_clean(ros1) -> None:
    path, full = ros1
    assert len(chunk_spans(path.read_bytes())) >= 4
    assert full.warnings == [] and full.n_scans == 160
    assert np.all(np.diff(full.scan_times) > 0)


@pytest.mark.parametrize("compression", [None, "lz4"])
def test_a_bag_cut_inside_its_first_chunk_is_called_truncated_and_keeps_the_chunk(
    tmp_path, room, ros1, compression
) -> None:
    _, full = ros1
    src = ros1[0]
    if compression is not None:
        src = write_ros1_drive(tmp_path / f"{compression}.bag", room, compression=compression)
    blob = src.read_bytes()
    _, data_at, end = chunk_spans(blob)[0]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(blob[: data_at + (end - data_at) * 3 // 4])
    data = read_bag(cut)
    assert len(data.warnings) == 1
    (warning,) = data.warnings
    assert "ROS 1 bag is truncated" in warning and "inside its first chunk" in warning, warning
    assert "index looks damaged" not in warning
    assert 0 < data.n_scans < full.n_scans
    _same_messages(data, full, data.n_scans)


def test_a_bz2_bag_cut_inside_its_first_chunk_says_it_cannot_be_read(tmp_path, room) -> None:
    """bz2 decompresses whole blocks (up to 900 kB) only: nothing of a cut first chunk is readable."""
    blob = write_ros1_drive(tmp_path / "bz2.bag", room, compression="bz2").read_bytes()
    _, data_at, end = chunk_spans(blob)[0]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(blob[: data_at + (end - data_at) * 3 // 4])
    with pytest.raises(BagError, match=r"truncated: .* first chunk .*bz2.* before its first"):
        read_bag(cut)


def test_a_bag_cut_before_its_first_message_says_so(tmp_path, ros1) -> None:
    blob = ros1[0].read_bytes()
    _, data_at, _ = chunk_spans(blob)[0]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(blob[: data_at + 10])
    with pytest.raises(BagError, match=r"truncated: it ends after .* inside its first chunk, before"):
        read_bag(cut)


def test_the_shared_bag_cut_inside_its_first_chunk(tmp_path) -> None:
    src = shared_bag(BAG1)
    blob = src.read_bytes()
    _, data_at, end = chunk_spans(blob)[0]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(blob[: (data_at + end) // 2])
    data, full = read_bag(cut), read_bag(src)
    assert "truncated" in data.warnings[0] and "first chunk" in data.warnings[0]
    assert 10 < data.n_scans < full.n_scans
    _same_messages(data, full, data.n_scans)


def test_a_chunk_written_twice_is_read_once(tmp_path, ros1) -> None:
    path, full = ros1
    dup = tmp_path / "dup.bag"
    n_copied = duplicate_chunk(path, dup, 1)
    assert n_copied > 20
    data = read_bag(dup)
    _same_messages(data, full)
    assert data.odom_times.size == full.odom_times.size
    assert np.all(np.diff(data.scan_times) > 0)  # no jump back where the copy starts
    copies = [w for w in data.warnings if "exact copies" in w]
    assert len(copies) == 1 and copies[0].startswith(f"{n_copied} messages")
    assert not any("backwards" in w for w in data.warnings)
    _one_line_each(data.warnings)


def test_the_shared_bag_with_a_chunk_written_twice(tmp_path) -> None:
    """Issue 24's case: 815 messages were read instead of 631, and time jumped back 2 s."""
    src = shared_bag(BAG1)
    dup = tmp_path / "dup.bag"
    n_copied = duplicate_chunk(src, dup, 1)
    data, full = read_bag(dup), read_bag(src)
    assert n_copied == 184  # 631 + 184 = 815
    _same_messages(data, full)
    assert data.odom_times.size == full.odom_times.size
    assert np.all(np.diff(data.scan_times) >= 0)
    assert any(w.startswith("184 messages are exact copies") for w in data.warnings)


def test_every_message_indexed_twice_is_read_once(tmp_path, room, ros1) -> None:
    """The bag's own index lists each message twice (rosbags reads it without the salvage)."""
    _, full = ros1
    data = read_bag(write_ros1_drive(tmp_path / "twice.bag", room, twice=True))
    _same_messages(data, full)
    n = full.n_scans + full.odom_times.size + len(full.truth_times)
    assert data.warnings == [
        f"{n} messages are exact copies of earlier ones (same topic, log time and bytes, e.g. a "
        "chunk written twice); each was read once"
    ]


def test_time_that_runs_backwards_is_one_warning_and_read_in_time_order(tmp_path, ros1) -> None:
    path, full = ros1
    moved = tmp_path / "moved.bag"
    move_chunk(path, moved, 1)
    data = read_bag(moved)
    back = [w for w in data.warnings if "backwards" in w]
    assert len(back) == 1 and "runs backwards once" in back[0], data.warnings
    _one_line_each(data.warnings)
    step = float(back[0].split("by up to ")[1].split(" s")[0])
    assert 0.3 < step < 2.0  # about one chunk's span of the 4 s drive (6 chunks)
    _same_messages(data, full)
    assert not any("exact copies" in w for w in data.warnings)


def test_replay_of_a_bag_with_a_chunk_written_twice(tmp_path, ros1, room, capsys) -> None:
    """Through the command: the warnings are lines of their own, time in trajectory.csv never
    runs back, one row per scan of the original."""
    from mcl.cli.main import main
    from tests.io.test_replay import room_yaml

    path, full = ros1
    dup = tmp_path / "dup.bag"
    duplicate_chunk(path, dup, 2)
    out = tmp_path / "r"
    code = main(
        ["replay", str(dup), "--map", room_yaml(room, tmp_path), "--out", str(out),
         "--init", "5,2,0", "--video-fps", "0"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert any("exact copies" in w for w in warnings)
    rows = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1, usecols=0)
    assert rows.size == full.n_scans and np.all(np.diff(rows) > 0)


def test_bytes_changed_anywhere_give_a_bag_or_one_line_never_a_traceback(tmp_path, ros1) -> None:
    """Seeded byte flips over the whole file, the index at its end included (a flip there made the
    salvage's record walk raise UnicodeDecodeError)."""
    path, full = ros1
    blob = path.read_bytes()
    rng = np.random.default_rng(7)
    spots = [len(blob) - 200, len(blob) - 60, *rng.integers(0, len(blob), 10).tolist()]
    for i, at in enumerate(spots):
        bad = bytearray(blob)
        bad[at : at + 16] = bytes(rng.integers(0, 256, 16, dtype=np.uint8))
        damaged = tmp_path / f"flip{i}.bag"
        damaged.write_bytes(bytes(bad))
        try:
            data = read_bag(damaged)
        except BagError as exc:
            assert "\n" not in str(exc)
            continue
        assert 0 < data.n_scans <= full.n_scans
        _one_line_each(data.warnings)
