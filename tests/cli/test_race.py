"""``racecar-sim race``: a short race end to end (table, CSV, video), laps counted on a small ring
track, positions in race order, racing drivers that pass without contact (overtakes counted), and a
user's mistakes as one line with exit code 2."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from mcl.cli.main import main

pytest.importorskip("pettingzoo", reason="RaceEnv needs the [race] extra (pettingzoo)")

RING_R = 1.6  # metres: the ring track's centerline radius (10.05 m round)


def ring(folder: Path) -> tuple[Path, Path]:
    """A round ring 1.2 m wide (radius 1.0-2.2 m, the track's centerline at 1.6 m, driven
    counter-clockwise) as a map_server YAML + PNG, and its centerline CSV."""
    res, half = 0.05, 2.6
    n = round(2 * half / res)
    centres = (np.arange(n) + 0.5) * res - half
    x, y = np.meshgrid(centres, centres[::-1])  # image row 0 at the top
    r = np.hypot(x, y)
    free = (r > 1.0) & (r < 2.2)
    cv2.imwrite(str(folder / "ring.png"), np.where(free, 254, 0).astype(np.uint8))
    (folder / "ring.yaml").write_text(
        f"image: ring.png\nresolution: {res}\norigin: [{-half}, {-half}, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    a = np.linspace(0.0, 2 * math.pi, 120, endpoint=False)
    rows = np.column_stack([RING_R * np.cos(a), RING_R * np.sin(a), np.full(a.size, 0.55),
                            np.full(a.size, 0.55)])  # fmt: skip
    np.savetxt(folder / "ring.csv", rows, fmt="%.4f", delimiter=",",
               header="x_m, y_m, w_tr_right_m, w_tr_left_m")  # fmt: skip
    return folder / "ring.yaml", folder / "ring.csv"


def read_results(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open() as fh:
        return list(csv.DictReader(fh))


def test_the_default_race_runs_end_to_end_with_table_and_video(tmp_path, capsys) -> None:
    out = tmp_path / "race"
    assert main(["race", "--duration", "2.5", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    rows = read_results(out)
    assert [r["position"] for r in rows] == ["1", "2", "3", "4"]
    assert sorted(r["car"] for r in rows) == ["car_0", "car_1", "car_2", "car_3"]
    assert {r["driver"] for r in rows} == {"racing"}
    by_grid = sorted(rows, key=lambda r: int(r["grid"]))
    speeds = [float(r["speed"]) for r in by_grid]
    assert len(set(speeds)) == 4 and speeds == sorted(speeds)  # each its own; slowest on pole
    assert all(float(r["distance"]) > 2.0 for r in rows)  # all drove
    assert all(r["wall_contacts"] == r["car_contacts"] == "0" for r in rows)
    assert all(r["mean_error"] == "" for r in rows)  # no filter without --localize
    table = (out / "results.md").read_text()
    assert table.strip() in printed and "| pos | car | driver |" in table
    video = cv2.VideoCapture(str(out / "race.mp4"))
    frames = int(video.get(cv2.CAP_PROP_FRAME_COUNT))
    ok, frame = video.read()
    assert ok and frames == 26  # 10 per simulated second and the start
    assert frame.shape[1] > 1000  # the map and the panel beside it


def test_laps_are_counted_and_positions_follow_the_race_order(tmp_path, capsys) -> None:
    """On a 10 m ring two pursuit cars at 3 and 2 m/s: the faster completes laps of about
    10 m / 3 m/s, leads, and the table's order is the race order."""
    yaml, centerline = ring(tmp_path)
    out = tmp_path / "ring_race"
    argv = ["race", "--map", str(yaml), "--track", str(centerline), "--cars", "2",
            "--drivers", "pursuit", "--speeds", "2,3", "--duration", "8", "--video-fps", "0", "--out", str(out),
            "--quiet"]  # fmt: skip
    assert main(argv) == 0
    first, second = read_results(out)
    assert (first["car"], first["position"], second["position"]) == ("car_1", "1", "2")
    assert first["grid"] == "1"  # blind drivers: the faster car on pole (fastest-first)
    assert int(first["laps"]) == 2 and int(second["laps"]) == 1
    laps = [float(t) for t in first["lap_times"].split(";")]
    assert len(laps) == 2 and float(first["best_lap"]) == pytest.approx(min(laps), abs=1e-3)
    flying = 2 * math.pi * RING_R / 3.0  # s: the centerline at 3 m/s (pursuit cuts in a little)
    assert 0.9 * flying < laps[1] < 1.1 * flying < laps[0]  # the first from a standing start
    assert float(first["distance"]) > float(second["distance"])
    assert "2 cars on ring" in capsys.readouterr().out


def test_laps_end_the_race_when_the_first_car_completes_them(tmp_path, capsys) -> None:
    yaml, centerline = ring(tmp_path)
    out = tmp_path / "to_one_lap"
    argv = ["race", "--map", str(yaml), "--track", str(centerline), "--cars", "2",
            "--speeds", "3", "--laps", "1", "--duration", "30", "--video-fps", "0",
            "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    rows = read_results(out)
    assert max(int(r["laps"]) for r in rows) == 1
    assert "(to 1 laps)" in capsys.readouterr().out
    assert float(rows[0]["lap_times"]) < 6.0  # stopped at that lap, far short of 30 s


@pytest.mark.parametrize(("seed", "speeds"), [(0, "2.0,2.4,2.8"), (5, "2.2,2.6,3.1")])
def test_racing_drivers_pass_the_slower_cars_without_contact(tmp_path, seed, speeds) -> None:
    """Racing drivers (the default) from the slowest-first grid on basement_loop: within 8 s the
    faster cars have passed slower ones, no car touched another or a wall, and each car's
    overtakes minus times overtaken is the places it gained from its grid slot."""
    out = tmp_path / "racing"
    argv = ["race", "--map", "basement_loop", "--cars", "3", "--speeds", speeds, "--seed",
            str(seed), "--duration", "8", "--video-fps", "0", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    rows = read_results(out)
    assert all(r["car_contacts"] == r["wall_contacts"] == "0" for r in rows)
    overtakes = [int(r["overtakes"]) for r in rows]
    assert sum(overtakes) > 0 and sum(overtakes) == sum(int(r["overtaken"]) for r in rows)
    for r in rows:
        assert int(r["overtakes"]) - int(r["overtaken"]) == int(r["grid"]) - int(r["position"])
    fastest = max(rows, key=lambda r: float(r["speed"]))
    assert fastest["grid"] == "3" and int(fastest["overtakes"]) >= 1  # from last, it passed


@pytest.mark.slow
@pytest.mark.parametrize("map_name", ["basement_loop", "office"])
def test_the_default_race_is_a_race_on_both_loop_maps(tmp_path, map_name) -> None:
    """The default race (4 racing cars, 60 s, the slowest on pole): every faster car passes
    every slower one once and is not passed back, so they finish in order of speed; no contact."""
    out = tmp_path / map_name
    argv = ["race", "--map", map_name, "--video-fps", "0", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    rows = read_results(out)
    speeds = [float(r["speed"]) for r in rows]
    assert len(rows) == 4 and speeds == sorted(speeds, reverse=True)
    assert [r["grid"] for r in rows] == ["4", "3", "2", "1"]  # the leader started last
    assert [int(r["overtakes"]) for r in rows] == [3, 2, 1, 0]
    assert [int(r["overtaken"]) for r in rows] == [0, 1, 2, 3]
    assert all(r["car_contacts"] == r["wall_contacts"] == "0" for r in rows)


@pytest.mark.slow
def test_localized_racing_drivers_pass_on_their_estimates(tmp_path) -> None:
    """With --localize the racing drivers steer on their filters' estimates: they still pass
    without contact, and every filter tracks its car."""
    out = tmp_path / "mcl_racing"
    argv = ["race", "--cars", "3", "--localize", "--particles", "300", "--duration", "10",
            "--video-fps", "0", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    rows = read_results(out)
    assert sum(int(r["overtakes"]) for r in rows) > 0
    assert all(r["car_contacts"] == r["wall_contacts"] == "0" for r in rows)
    assert all(float(r["max_error"]) < 0.3 for r in rows)


@pytest.mark.parametrize(
    ("argv", "flag", "fragment"),
    [
        (["--drivers", "walls"], "--drivers", "unknown driver 'walls'"),
        (["--drivers", "wall,pursuit"], "--drivers", "2 drivers for 4 cars"),
        (
            ["--drivers", "policy:nowhere/model.zip"],
            "--drivers",
            "nowhere/model.zip does not exist",
        ),
        (["--drivers", "policy:"], "--drivers", "needs its file"),
        (["--cars", "500"], "--cars", "at most 100"),
        (["--speeds", "2,3"], "--speeds", "2 speeds for 4 cars"),
        (["--speeds", "9"], "--speeds", "top speed"),
        (["--map", "corridor"], "--map", "needs a track"),
        (["--track", "nowhere.csv"], "--track", "does not exist"),
        (["--duration", "0"], "--duration", "must be a number > 0"),
        (["--env", "track=auto"], "--env track", "with --track"),
        (["--env", "terminate_on_collision=true"], "--env terminate_on_collision", "counts"),
        (["--live", "nohost:"], "--live", "PORT"),
    ],
)
def test_mistakes_are_one_line_and_exit_2(tmp_path, capsys, argv, flag, fragment) -> None:
    out = tmp_path / "never"
    with pytest.raises(SystemExit) as exc:
        main(["race", "--out", str(out), *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("racecar-sim race: error: ") and flag in err and fragment in err
    assert not out.exists()


def test_more_cars_than_the_track_holds_is_a_mistake(tmp_path, capsys) -> None:
    yaml, centerline = ring(tmp_path)
    out = tmp_path / "never"
    with pytest.raises(SystemExit) as exc:
        main(["race", "--map", str(yaml), "--track", str(centerline), "--cars", "30",
              "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1
    assert "--cars" in err and "at most" in err and not out.exists()


def test_a_policy_file_without_its_config_is_a_mistake(tmp_path, capsys) -> None:
    model = tmp_path / "agent" / "model.zip"
    model.parent.mkdir()
    model.write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip, no config.json beside it
    with pytest.raises(SystemExit) as exc:
        main(["race", "--cars", "2", "--drivers", f"pursuit,policy:{model}",
              "--out", str(tmp_path / "never")])  # fmt: skip
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1
    assert "--drivers" in err and "config.json is missing" in err


def test_a_localized_race_reports_each_filters_error(tmp_path, capsys) -> None:
    out = tmp_path / "mcl"
    argv = ["race", "--cars", "2", "--localize", "--particles", "200", "--duration", "1",
            "--video-fps", "0", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    rows = read_results(out)
    errors = [(float(r["mean_error"]), float(r["max_error"])) for r in rows]
    assert all(0 < mean <= peak < 0.3 for mean, peak in errors)  # tracking, each its own filter
    assert "MCL error mean / max (m)" in capsys.readouterr().out
