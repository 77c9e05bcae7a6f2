"""A bag whose LaserScan header cannot be replayed (0 beams, NaN or infinite angles or ranges, a fan
wider than a turn, more beams than any lidar) is one clear BagError, from MCAP and from ROS 2
sqlite3 bags alike, and ``racecar-sim replay`` says it in one line with exit code 2."""

from __future__ import annotations

import math

import pytest

from mcl.io import BagError, read_bag
from mcl.io.scan_checks import MAX_SCAN_BEAMS
from tests.cli.test_mistakes import assert_one_line_error, run
from tests.io.scan_bags import write_scan_bag

NAN, INF = math.nan, math.inf
# (header fields, a fragment of the message)
HOSTILE = {
    "0 beams": ({"beams": 0}, "has 0 beams"),
    "NaN angle_increment": ({"angle_increment": NAN}, "angle_increment = nan"),
    "inf angle_increment": ({"angle_increment": INF}, "angle_increment = inf"),
    "NaN angle_min": ({"angle_min": NAN}, "angle_min = nan"),
    "-inf angle_min": ({"angle_min": -INF}, "angle_min = -inf"),
    "NaN range_max": ({"range_max": NAN}, "range_max = nan"),
    "inf range_max": ({"range_max": INF}, "range_max = inf"),
    "negative range_max": ({"range_max": -1.0}, "range_max = -1.0"),
    "NaN range_min": ({"range_min": NAN}, "range_min = nan"),
    "range_min above range_max": ({"range_min": 40.0}, "range_min = 40.0"),
    "zero angle_increment": ({"angle_increment": 0.0}, "every beam in one direction"),
    "fan of 1e30 rad": ({"angle_increment": 1e30}, "more than a full turn"),
    "too many beams": ({"beams": MAX_SCAN_BEAMS + 1, "angle_increment": 1e-4,
                        "scans": 2}, "more than the 10,000"),
}  # fmt: skip
STORAGES = ("mcap", "sqlite3")


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_a_hostile_scan_header_is_one_clear_error(case, storage, tmp_path) -> None:
    fields, fragment = HOSTILE[case]
    bag = write_scan_bag(tmp_path / "bag", storage, **fields)
    with pytest.raises(BagError) as info:
        read_bag(bag)
    message = str(info.value)
    assert "\n" not in message and len(message) < 300
    assert "the first scan on /scan" in message and fragment in message, message


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("case", ["0 beams", "NaN angle_increment", "-inf angle_min",
                                  "NaN range_max", "inf range_max"])  # fmt: skip
def test_replay_of_a_hostile_scan_is_one_line_and_exit_2(case, storage, tmp_path, capsys) -> None:
    fields, fragment = HOSTILE[case]
    bag = write_scan_bag(tmp_path / "bag", storage, **fields)
    out = tmp_path / "out"
    code, _, err = run(["replay", str(bag), "--map", "corridor", "--out", str(out)], capsys)
    assert_one_line_error(code, err, "bag", fragment)
    assert not out.exists()


@pytest.mark.parametrize("storage", STORAGES)
def test_ranges_that_disagree_with_the_angles_are_read_with_a_warning(storage, tmp_path) -> None:
    bag = write_scan_bag(tmp_path / "bag", storage, beams=10, n_ranges=6)
    data = read_bag(bag)
    assert data.n_beams == 6
    assert data.angles[1] - data.angles[0] == pytest.approx(0.2)  # placed at angle_increment
    assert any("6 ranges but" in w and "make 10 beams" in w for w in data.warnings)
    assert not read_bag(write_scan_bag(tmp_path / "ok", storage, beams=10)).warnings


@pytest.mark.parametrize("storage", STORAGES)
def test_a_single_beam_and_a_full_turn_are_fine(storage, tmp_path) -> None:
    one = read_bag(write_scan_bag(tmp_path / "one", storage, beams=1, angle_increment=0.0))
    assert one.n_beams == 1
    turn = 2 * math.pi / 359
    full = read_bag(write_scan_bag(tmp_path / "full", storage, beams=360, angle_min=-math.pi,
                                   angle_increment=turn))  # fmt: skip
    assert full.n_beams == 360 and full.angles[-1] == pytest.approx(math.pi)
