"""A command never deletes or overwrites what racecar-sim did not make: ``--bag`` replaces only a
recording of ours, ``--out`` writes only into a new, empty or racecar-sim folder, path flags refuse
names the system cannot take, and every refusal comes before anything is created or run (one line
naming the flag, exit code 2). Every case runs in a temporary folder."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import mcl.cli.drive
from mcl.cli.main import main
from racecar_sim.file_guard import MARKER, claim_folder
from tests.cli.test_mistakes import assert_one_line_error, run

SHORT = ["--map", "corridor", "--duration", "0.3", "--particles", "50", "--video-fps", "0",
         "--quiet"]  # fmt: skip


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative name -> content)."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def _user_folder(folder: Path) -> dict[str, bytes]:
    """A folder of someone's files (nested, hidden, a recording-like name), returned as a tree."""
    (folder / "nested" / "deeper").mkdir(parents=True)
    (folder / "data.txt").write_text("keep\n")
    (folder / ".hidden").write_bytes(b"\x00\x01secret")
    (folder / "nested" / "notes.md").write_text("# notes\n")
    (folder / "nested" / "deeper" / "metadata.yaml").write_text("mine: true\n")
    return _tree(folder)


@pytest.fixture
def no_runs(monkeypatch):
    def started(*args, **kwargs):
        raise AssertionError("a run started although the command line had a mistake")

    monkeypatch.setattr(mcl.cli.drive, "run_one", started)


# ---------------------------------------------------------------------- --bag
def test_bag_on_a_folder_that_is_not_a_recording_keeps_every_file(
    tmp_path, capsys, no_runs
) -> None:
    important = tmp_path / "important"
    before = _user_folder(important)
    out = tmp_path / "o"
    code, _, err = run(["drive", *SHORT, "--bag", str(important), "--out", str(out)], capsys)
    assert_one_line_error(code, err, "--bag", "give a new folder")
    assert _tree(important) == before  # every file, with its content
    assert not out.exists()  # refused before anything was created


def test_bag_on_a_folder_with_a_single_mcap_is_refused(tmp_path, capsys, no_runs) -> None:
    folder = tmp_path / "half"
    folder.mkdir()
    (folder / "half.mcap").write_bytes(b"\x89MCAP0\r\n")  # a drive killed before metadata.yaml
    args = ["--bag", str(folder), "--out", str(tmp_path / "o")]
    code, _, err = run(["drive", *SHORT, *args], capsys)
    assert_one_line_error(code, err, "--bag", "other files than a recording's")
    assert (folder / "half.mcap").read_bytes() == b"\x89MCAP0\r\n"


@pytest.mark.parametrize(
    ("what", "fragment"),
    [("empty", "empty folder"), ("file", "not a folder"), ("link", "link")],
)
def test_bag_on_an_empty_folder_a_file_or_a_link_is_refused(
    what, fragment, tmp_path, capsys, no_runs
) -> None:
    target = tmp_path / "target"
    target.mkdir()
    (target / "kept.txt").write_text("kept")
    bag = tmp_path / "bag"
    if what == "empty":
        bag.mkdir()
    elif what == "file":
        bag.write_text("a file")
    else:
        bag.symlink_to(target, target_is_directory=True)
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "--bag", fragment)
    assert os.path.lexists(bag)
    assert (target / "kept.txt").read_text() == "kept"
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("bag", "out"),
    [("x", "x/inner"), ("x/inner", "x"), ("x", "x"), ("x/./y", "x/y/../y")],
    ids=["out-inside-bag", "bag-inside-out", "same", "same-spelled-otherwise"],
)
@pytest.mark.parametrize("exists", [False, True], ids=["new", "existing"])
def test_overlapping_bag_and_out_are_refused_before_anything_is_made(
    bag, out, exists, tmp_path, capsys, no_runs
) -> None:
    x = tmp_path / "x"
    before: dict[str, bytes] = {}
    if exists:  # an earlier run's folder (ours, so that --out alone would be accepted)
        claim_folder(x)
        (x / "y").mkdir()
        (x / "y" / "log.txt").write_text("mine")
        before = _tree(x)
    args = ["--bag", str(tmp_path / bag), "--out", str(tmp_path / out)]
    code, _, err = run(["drive", *SHORT, *args], capsys)
    assert_one_line_error(code, err, "--bag", "overlap")
    if exists:
        assert _tree(x) == before and sorted(p.name for p in x.iterdir()) == [MARKER, "y"]
    else:
        assert not x.exists()


def test_a_previous_recording_of_ours_is_replaced(tmp_path, capsys) -> None:
    from mcl.io import read_bag

    bag = tmp_path / "rec"
    code, _, err = run(["drive", *SHORT, "--seed", "1", "--bag", str(bag),
                        "--out", str(tmp_path / "o1")], capsys)  # fmt: skip
    assert code == 0, err
    first = _tree(bag)
    assert sorted(first) == ["metadata.yaml", "rec.mcap"]
    code, _, err = run(["drive", *SHORT, "--seed", "2", "--duration", "0.5", "--bag", str(bag),
                        "--out", str(tmp_path / "o2")], capsys)  # fmt: skip
    assert code == 0, err
    second = _tree(bag)
    assert sorted(second) == ["metadata.yaml", "rec.mcap"]
    assert second["rec.mcap"] != first["rec.mcap"]  # the new drive, not the old one
    data = read_bag(bag)
    assert data.scan_times[-1] > 0.4  # the 0.5 s drive (the first lasted 0.3 s)


def test_a_recording_with_one_more_file_is_not_replaced(tmp_path, capsys) -> None:
    bag = tmp_path / "rec"
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o1")], capsys)
    assert code == 0, err
    (bag / "README.txt").write_text("my notes on this drive")
    before = _tree(bag)
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o2")], capsys)
    assert_one_line_error(code, err, "--bag", "other files")
    assert _tree(bag) == before
    assert not (tmp_path / "o2").exists()


def test_a_bag_of_other_topics_is_not_replaced(tmp_path, capsys, no_runs) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "theirs"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        con = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        msg = store.types["std_msgs/msg/String"](data="hello")
        writer.write(con, 1, store.serialize_cdr(msg, "std_msgs/msg/String"))
    before = _tree(bag)
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "--bag", "not a racecar-sim recording")
    assert _tree(bag) == before


# ---------------------------------------------------------------------- --out
def test_out_into_a_folder_of_someone_elses_files_is_refused(tmp_path, capsys, no_runs) -> None:
    folder = tmp_path / "mine"
    before = _user_folder(folder)
    code, _, err = run(["drive", *SHORT, "--out", str(folder)], capsys)
    line = assert_one_line_error(code, err, "--out", "racecar-sim did not write")
    assert ".hidden" in line and "data.txt" in line  # names what is there
    assert _tree(folder) == before


def test_out_into_an_empty_folder_is_marked_and_reused(tmp_path, capsys) -> None:
    out = tmp_path / "empty"
    out.mkdir()
    code, _, err = run(["drive", *SHORT, "--out", str(out)], capsys)
    assert code == 0, err
    assert (out / MARKER).is_file() and (out / "error_log.csv").is_file()
    (out / "my_notes.txt").write_text("kept")  # a user's file in our folder is not touched
    code, _, err = run(["drive", *SHORT, "--seed", "3", "--out", str(out)], capsys)
    assert code == 0, err
    assert (out / "my_notes.txt").read_text() == "kept"


def test_a_failed_command_leaves_an_empty_folder_as_it_was(tmp_path, capsys, monkeypatch) -> None:
    out = tmp_path / "empty"
    out.mkdir()

    def fails(*args, **kwargs):
        raise RuntimeError("stop")

    monkeypatch.setattr(mcl.cli.drive, "run_one", fails)
    with pytest.raises(RuntimeError):
        main(["drive", *SHORT, "--out", str(out)])
    assert out.is_dir() and list(out.iterdir()) == []  # the marker written for it is gone


def test_make_maps_replaces_its_own_maps_and_no_one_elses(tmp_path, capsys) -> None:
    folder = tmp_path / "maps"
    code, _, err = run(["make-maps", "--out", str(folder)], capsys)
    assert code == 0, err
    (folder / "my_map.yaml").write_text("image: my_map.png\n")
    drawn = _tree(folder)
    code, _, err = run(["make-maps", "--out", str(folder)], capsys)
    assert code == 0, err  # its own maps are redrawn, the user's map is left alone
    assert _tree(folder) == drawn
    (folder / "office.yaml").write_text("image: office.png\nresolution: 0.1\n")  # edited by hand
    edited = _tree(folder)
    code, _, err = run(["make-maps", "--out", str(folder)], capsys)
    assert_one_line_error(code, err, "--out", "office.yaml exists and was not written")
    assert _tree(folder) == edited  # not one map redrawn


def test_make_maps_refuses_a_png_without_its_yaml(tmp_path, capsys) -> None:
    folder = tmp_path / "maps"
    folder.mkdir()
    (folder / "corridor.png").write_bytes(b"someone's picture")
    code, _, err = run(["make-maps", "--out", str(folder)], capsys)
    assert_one_line_error(code, err, "--out", "corridor.png")
    assert sorted(p.name for p in folder.iterdir()) == ["corridor.png"]


def test_calibrate_noise_refuses_to_overwrite_a_file_it_did_not_write(tmp_path, capsys) -> None:
    bag, map_yaml, out = tmp_path / "a.bag", tmp_path / "map.yaml", tmp_path / "profile.yaml"
    bag.write_bytes(b"")
    map_yaml.write_text("image: x.png\n")
    out.write_text("name: my hand-made profile\n")
    code, _, err = run(["calibrate-noise", str(bag), "--map", str(map_yaml), "--out", str(out)],
                       capsys)  # fmt: skip
    assert_one_line_error(code, err, "--out", "not written by racecar-sim")
    assert out.read_text() == "name: my hand-made profile\n"
    code, _, err = run(["calibrate-noise", str(bag), "--map", str(map_yaml), "--out",
                        str(tmp_path)], capsys)  # fmt: skip
    assert_one_line_error(code, err, "--out", "is a folder")


# ---------------------------------------------------------------------- path texts
_OUT_COMMANDS = {
    "drive": [],
    "replay": ["{bag}", "--map", "corridor"],
    "experiment": [],
    "ablation": [],
    "fast-laps": [],
    "opponents": [],
    "train-agent": [],
    "make-maps": [],
    "calibrate-noise": ["{bag}", "--map", "{map}"],
    "update-map": ["--filter-map", "corridor"],
}
_LONG_NAME = "n" * 256
_PATHS = {
    "empty": ("", "is empty"),
    "long-name": (f"out/{_LONG_NAME}/x", "name of 256 bytes"),
    "long-path": ("/".join(["d" * 99] * 50), "bytes long"),
    "nul": ("out\0x", "NUL"),
    "deep": ("/".join(["x"] * 300), "300 folders deep"),
}


def _flag_cases() -> list:
    cases = [
        pytest.param(sub, "--out", key, id=f"{sub} --out {key}")
        for sub in _OUT_COMMANDS
        for key in _PATHS
    ]
    cases += [pytest.param("drive", "--bag", key, id=f"drive --bag {key}") for key in _PATHS]
    return cases


@pytest.mark.parametrize(("sub", "flag", "key"), _flag_cases())
def test_a_path_the_system_cannot_take_is_one_line(
    sub, flag, key, tmp_path, capsys, monkeypatch, no_runs
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.bag").write_bytes(b"")
    (tmp_path / "map.yaml").write_text("image: x.png\n")
    names = {"{bag}": "a.bag", "{map}": "map.yaml"}
    text, fragment = _PATHS[key]
    args = [names.get(a, a) for a in _OUT_COMMANDS[sub]] + [flag, text]
    code, _, err = run([sub, *args], capsys)
    assert_one_line_error(code, err, flag, fragment)
    assert len(err) < 500  # the path is cut short in the message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bag", "map.yaml"]  # nothing made


@pytest.mark.parametrize("sub", [s for s in _OUT_COMMANDS if s not in ("calibrate-noise", "update-map")])
def test_a_folder_path_leaves_room_for_the_files_in_it(sub, tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    args = [a.replace("{bag}", "a.bag").replace("{map}", "map.yaml") for a in _OUT_COMMANDS[sub]]
    long = "/".join(["d" * 99] * 39)  # 3899 bytes: the folder fits, a file name in it may not
    code, _, err = run([sub, *args, "--out", long], capsys)
    assert_one_line_error(code, err, "--out", "at most 3839")
    assert list(tmp_path.iterdir()) == []


def test_a_bag_name_leaves_room_for_its_mcap_file(tmp_path, capsys, no_runs) -> None:
    bag = tmp_path / ("n" * 251)  # n...n.mcap would be 256 bytes
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o")], capsys)
    assert_one_line_error(code, err, "--bag", "at most 250")
    assert list(tmp_path.iterdir()) == []


def test_a_bag_name_of_250_bytes_is_recorded(tmp_path, capsys) -> None:
    bag = tmp_path / ("n" * 250)
    code, _, err = run(["drive", *SHORT, "--bag", str(bag), "--out", str(tmp_path / "o")], capsys)
    assert code == 0, err
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "n" * 250 + ".mcap"]
