"""The nav2 amcl peer: our drives and maps in amcl's frames (numpy only), and amcl itself (its own
venv, skipped when absent) keeping a still car with a perfect scan on the truth."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.bench import amcl_bench, peer_amcl, peers
from mcl.bench.amcl_inputs import (
    amcl_grid,
    amcl_ranges,
    estimates_between,
    odometry_poses,
    update_steps,
)
from mcl.experiments.recorded import RecordedDrive, record_drive
from mcl.filter.motion_model import compose, twist_to_odometry
from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.raycast import RayCaster
from tests.conftest import SHARED_MAPS, lidar_pose, room_map
from tests.skips import need_shared, shared_missing

REPO = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------- the map in amcl's frame
def _amcl_cell_occupied(grid, xy: np.ndarray) -> np.ndarray:
    """amcl's own look-up (map.hpp: MAP_GXWX rounds from the origin it is given), written out."""
    ox, oy = grid.amcl_origin
    i = np.floor((xy[:, 0] - ox) / grid.resolution + 0.5).astype(int)
    j = np.floor((xy[:, 1] - oy) / grid.resolution + 0.5).astype(int)
    ny, nx = grid.data.shape
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    out = np.ones(len(xy), dtype=bool)
    out[inside] = grid.data[j[inside], i[inside]] != 0
    return out


@settings(max_examples=25)
@given(yaw=st.sampled_from([0.0, 3.14, math.pi, -1.2, 0.4]), seed=st.integers(0, 2**31 - 1))
def test_amcl_sees_free_and_occupied_where_our_map_has_them(yaw, seed):
    base = room_map()
    grid = OccupancyMap(base.occupied, base.resolution, (1.0, -2.0, yaw), name="room")
    converted = amcl_grid(grid)
    rng = np.random.default_rng(seed)
    # points two cells from any boundary: free ones by our distance field, occupied ones inside
    free = grid.sample_free_poses(rng, 300, clearance=2.5 * grid.resolution)[:, :2]
    assert not _amcl_cell_occupied(converted, free).any()
    rows, cols = np.nonzero(_eroded(grid.occupied))
    pick = rng.integers(0, len(rows), 300)
    walls = grid.grid_to_world(np.stack([rows[pick], cols[pick]], axis=-1))
    assert _amcl_cell_occupied(converted, walls).all()
    # and off the map is a wall to amcl
    w, h = grid.extent
    far = grid.map_to_world(np.array([[-1.0, -1.0], [w + 1.0, h + 1.0]]))
    assert _amcl_cell_occupied(converted, far).all()


def _eroded(occ: np.ndarray, cells: int = 2) -> np.ndarray:
    out = occ.copy()
    for axis in (0, 1):
        for shift in range(1, cells + 1):
            out &= np.roll(occ, shift, axis) & np.roll(occ, -shift, axis)
    out[:cells], out[-cells:], out[:, :cells], out[:, -cells:] = False, False, False, False
    return out


# ---------------------------------------------------------------- odometry, scans, updates
@settings(max_examples=30)
@given(
    twists=st.lists(
        st.tuples(st.floats(-3, 3), st.floats(-0.3, 0.3), st.floats(-4, 4)), min_size=2,
        max_size=40,
    ),
    dt=st.sampled_from([0.01, 0.025, 0.1]),
)  # fmt: skip
def test_odometry_poses_compose_the_twists_as_our_filter_moves(twists, dt):
    odom = np.array(twists, dtype=np.float32)
    poses = odometry_poses(odom, dt)
    pose = np.zeros((1, 3))
    for k in range(1, len(odom)):
        pose = compose(pose, twist_to_odometry(odom[k].astype(np.float64), dt))
        np.testing.assert_allclose(poses[k, :2], pose[0, :2], atol=1e-9)
        assert abs(math.remainder(poses[k, 2] - pose[0, 2], 2 * math.pi)) < 1e-9


def test_updates_follow_nav2s_thresholds():
    n = 60
    straight = np.tile([1.1, 0.0, 0.0], (n, 1))  # 1.1 m/s for 0.025 s: 2.75 cm a step along x
    at = update_steps(odometry_poses(straight, 0.025), np.ones(n, bool), 0.25, 0.2)
    np.testing.assert_array_equal(at, [0, 10, 20, 30, 40, 50])  # more than 0.25 m: 10 steps
    spin = np.tile([0.0, 0.0, 0.45], (n, 1))  # 0.01125 rad a step
    at = update_steps(odometry_poses(spin, 0.025), np.ones(n, bool), 0.25, 0.2)
    np.testing.assert_array_equal(at, [0, 18, 36, 54])  # more than 0.2 rad: 18 steps
    fresh = np.arange(n) % 4 == 0  # a scan every 4th step: updates only there
    at = update_steps(odometry_poses(straight, 0.025), fresh, 0.25, 0.2)
    np.testing.assert_array_equal(at, [0, 12, 24, 36, 48])
    still = np.zeros((n, 3))
    assert update_steps(odometry_poses(still, 0.025), np.ones(n, bool), 0.25, 0.2).tolist() == [0]
    assert len(update_steps(odometry_poses(still, 0.025), np.ones(n, bool), -1.0, -1.0)) == n


def test_scan_readings_without_a_return_go_in_at_max_range():
    pairs = amcl_ranges(np.array([1.5, 30.0, 31.0, 0.0, np.nan, np.inf, 29.9]),
                        np.linspace(-1, 1, 7), 30.0)  # fmt: skip
    assert pairs[:, 0].tolist() == [1.5, 30.0, 30.0, 30.0, 30.0, 30.0, 29.9]
    np.testing.assert_array_equal(pairs[:, 1], np.linspace(-1, 1, 7))


@settings(max_examples=30)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 60))
def test_between_updates_the_estimate_follows_the_odometry(seed, n):
    rng = np.random.default_rng(seed)
    truth = np.cumsum(rng.normal(0, 0.2, (n, 3)), axis=0)
    odom_frame = rng.uniform(-5, 5, 3)  # the odom frame is anywhere in the world
    poses = compose(np.tile(odom_frame, (n, 1)), truth)  # odom-frame poses of the same motion
    at = np.unique(np.concatenate([[0], rng.integers(0, n, 3)]))
    est = estimates_between(truth[at], at, poses)  # amcl exact at its updates
    np.testing.assert_allclose(est[:, :2], truth[:, :2], atol=1e-9)
    assert np.all(np.abs(np.remainder(est[:, 2] - truth[:, 2] + np.pi, 2 * np.pi) - np.pi) < 1e-9)


# ---------------------------------------------------------------- parameters and the command
def test_params_are_nav2s_and_checked():
    p = peer_amcl.NAV2_DEFAULTS
    assert (p.min_particles, p.max_particles, p.max_beams, p.update_min_d) == (500, 2000, 60, 0.25)
    assert (peer_amcl.WITH_RECOVERY.recovery_alpha_slow,
            peer_amcl.WITH_RECOVERY.recovery_alpha_fast) == (0.001, 0.1)  # fmt: skip
    with pytest.raises(ValueError, match="beam model"):
        peer_amcl.AmclParams(laser_model_type="likelihood_field")
    with pytest.raises(ValueError, match="min_particles"):
        peer_amcl.AmclParams(min_particles=3000)


def test_part_skips_with_the_reason_when_amcl_cannot_be_had(capsys, monkeypatch):
    world = SHARED_MAPS / "stata_basement.yaml"
    if not world.is_file():  # the part checks the real maps first, then amcl
        pytest.skip(shared_missing(world))
    monkeypatch.setattr(peer_amcl, "amcl_python", lambda given=None: (None, "no amcl here"))
    assert peers.amcl_part(peers_args(["--only", "amcl"])) == 0
    assert "skipped: no amcl here" in capsys.readouterr().out
    monkeypatch.undo()
    python, why = peer_amcl.amcl_python("/nonexistent/python")
    assert python is None and "/nonexistent/python cannot import amcl" in why


def test_the_tables_go_only_into_a_folder_of_ours(tmp_path, capsys, monkeypatch):
    """A folder of the user's (here with a file named as one of the bench's tables) is refused
    before anything runs, and nothing in it changes."""
    monkeypatch.setattr(peer_amcl, "amcl_python", lambda given=None: (None, "no amcl here"))
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "amcl_results.csv").write_text("keep\n")
    assert peers.amcl_part(peers_args(["--only", "amcl", "--out", str(mine)])) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in mine.iterdir()) == ["amcl_results.csv"]
    assert (mine / "amcl_results.csv").read_text() == "keep\n"


def test_bad_seeds_is_a_one_line_error(capsys):
    with pytest.raises(SystemExit) as exited:
        peers.main(["--only", "amcl", "--seeds", "0"])
    assert exited.value.code == 2 and "--seeds" in capsys.readouterr().err


def test_lost_means_more_than_two_percent_over_a_metre():
    assert not amcl_bench.lost(np.r_[np.zeros(98), 2.0, 2.0])
    assert amcl_bench.lost(np.r_[np.zeros(97), 2.0, 2.0, 2.0])


def peers_args(argv):
    import argparse

    parser = argparse.ArgumentParser()
    peers.add_arguments(parser)
    return parser.parse_args(argv)


# ---------------------------------------------------------------- amcl itself (its own venv)
def _amcl_or_skip() -> str:
    python = os.environ.get("AMCL_PYTHON") or str(REPO / "out/peers/amcl-venv/bin/python")
    if not Path(python).exists():
        pytest.skip(
            f"nav2 amcl bindings not found at {python}: set $AMCL_PYTHON, or run "
            "racecar-sim bench peers --only amcl once (it makes out/peers/amcl-venv)"
        )
    return python


def _still_drive(grid: OccupancyMap, pose: np.ndarray, steps: int = 15) -> RecordedDrive:
    """A car standing at ``pose`` with perfect scans and odometry (1080 beams, 10 m)."""
    angles, mount, max_range = np.linspace(-2.355, 2.355, 1080), 0.275, 10.0
    scan = RayCaster(grid, max_range).cast(lidar_pose(pose, mount), angles)[0]
    n = steps + 1
    return RecordedDrive(
        time=np.arange(n) * 0.025, dt_steps=np.r_[0.0, np.full(steps, 0.025)],
        truth=np.tile(pose, (n, 1)), odom=np.zeros((n, 3), np.float32), fresh=np.ones(n, bool),
        scans=np.tile(scan.astype(np.float32), (n, 1)), beam_angles=angles, mount_offset=mount,
        max_range=max_range, dt=0.025, world_map=grid.name,
    )  # fmt: skip


@settings(max_examples=4)
@given(seed=st.integers(0, 10_000))
def test_a_still_car_with_a_perfect_scan_stays_on_the_truth(seed):
    python = _amcl_or_skip()
    grid = resolve_map("basement_loop")
    pose = grid.sample_free_poses(np.random.default_rng(seed), 1, clearance=0.6)[0]
    every_scan = peer_amcl.AmclParams(update_min_d=-1.0, update_min_a=-1.0)
    run = peer_amcl.localize_with_amcl(python, amcl_grid(grid), _still_drive(grid, pose), seed,
                                       every_scan)  # fmt: skip
    assert run.position_error[-1] < 0.1
    assert abs(run.heading_error[-1]) < 0.05


def test_a_map_half_a_metre_off_pulls_amcl_off_the_truth():
    """The control of the test above: the same scans against a displaced map fail it."""
    python = _amcl_or_skip()
    grid = resolve_map("basement_loop")
    pose = grid.sample_free_poses(np.random.default_rng(7), 1, clearance=0.6)[0]
    ox, oy, yaw = grid.origin
    moved = OccupancyMap(grid.occupied, grid.resolution, (ox + 0.5, oy, yaw), name="moved")
    every_scan = peer_amcl.AmclParams(update_min_d=-1.0, update_min_a=-1.0)
    run = peer_amcl.localize_with_amcl(python, amcl_grid(moved), _still_drive(grid, pose), 7,
                                       every_scan)  # fmt: skip
    assert run.position_error[-1] > 0.2


def test_amcl_tracks_a_recorded_drive():
    python = _amcl_or_skip()
    drive = record_drive("basement_loop", seed=2, duration=15.0)
    run = peer_amcl.localize_with_amcl(python, amcl_grid(resolve_map("basement_loop")), drive, 2)
    assert run.position_error.mean() < 0.15
    assert run.position_error.max() < 0.5


def test_results_survive_a_restart_and_the_report_covers_the_seeds_asked(tmp_path):
    rows = [
        {"world": w, "seed": s, "filter": f, "mean_error_m": 0.1 * (s + 1), "p95_error_m": 0.5,
         "max_error_m": 1.5, "pct_over_1m": 3.0 * s, "lost": amcl_bench.lost(
             np.r_[np.zeros(100 - 3 * s), np.full(3 * s, 2.0)]), "cpu_s": 1.0, "found_s": None}
        for w in ("ideal", "cluttered") for s in range(3) for f in amcl_bench.FILTERS
    ]  # fmt: skip
    amcl_bench._write(tmp_path, rows, 3, 60.0, ["ideal", "cluttered"])
    back = amcl_bench.read_rows(tmp_path / "amcl_results.csv")
    assert back == rows
    report = amcl_bench.results_md(back, 2, 60.0, ["cluttered"])
    assert "## cluttered: per seed" in report and "ideal" not in report.split("## Summary")[1]
    # seeds 0 and 1 only: means 0.1 and 0.2 (median 0.150), seed 1 at 3 % over 1 m is lost
    assert "| cluttered | ours | 2 | 0.150 | 1/2 | 1.5 |" in report
    assert "\n| 1 | 0.200 |" in report and "\n| 2 | " not in report  # per-seed rows: 0, 1


def test_the_kidnap_worlds_report_how_many_cars_each_filter_found_and_when(tmp_path):
    # ours finds seeds 0 and 1 (3.0 s, 16.0 s: too late), amcl none; seed 2 found by both at 1 s
    found = {("ours", 0): 3.0, ("ours", 1): 16.0, ("ours", 2): 1.0, ("amcl", 2): 1.0}
    rows = [
        {"world": "clean_kidnap", "seed": s, "filter": f, "mean_error_m": 5.0, "p95_error_m": 9.0,
         "max_error_m": 9.0, "pct_over_1m": 50.0, "lost": True, "cpu_s": 1.0,
         "found_s": found.get((f, s), math.nan)}
        for s in range(3) for f in amcl_bench.FILTERS
    ] + [{"world": "clean", "seed": 0, "filter": f, "mean_error_m": 0.05, "p95_error_m": 0.1,
          "max_error_m": 0.2, "pct_over_1m": 0.0, "lost": False, "cpu_s": 1.0, "found_s": None}
         for f in amcl_bench.FILTERS]  # fmt: skip
    amcl_bench._write(tmp_path, rows, 3, 30.0, ["clean_kidnap", "clean"])
    back = amcl_bench.read_rows(tmp_path / "amcl_results.csv")
    assert [r["found_s"] for r in back if r["world"] == "clean"] == [None] * 3
    assert math.isnan(next(r["found_s"] for r in back if (r["filter"], r["seed"]) == ("amcl", 0)))
    report = amcl_bench.results_md(back, 3, 30.0, ["clean_kidnap", "clean"])
    assert "| clean_kidnap | ours | 3 | 2/3 | 2.00 | 3.00 |" in report  # 1 s and 3 s; 16 s is late
    assert "| clean_kidnap | amcl | 3 | 1/3 | 1.00 | 1.00 |" in report
    assert "| clean_kidnap | amcl_recovery | 3 | 0/3 | – | – |" in report
    assert "| clean | " not in report.split("## Kidnaps")[1].split("##")[0]  # no kidnap there
    assert "\n| 1 | 5.000 | 16.00 | 5.000 | never | 5.000 | never |" in report
    assert amcl_bench.kidnaps_md([r for r in back if r["world"] == "clean"]) == ""


def test_a_results_file_from_before_the_kidnaps_reads_and_grows(tmp_path):
    # the columns of a file written before found_s existed: its rows read as drives without a
    # kidnap, and rows of a kidnap world can be written beside them
    (tmp_path / "amcl_results.csv").write_text(
        "world,seed,filter,mean_error_m,p95_error_m,max_error_m,pct_over_1m,lost,cpu_s\n"
        "clean,0,ours,0.05,0.1,0.2,0.0,False,1.0\n"
    )
    old = amcl_bench.read_rows(tmp_path / "amcl_results.csv")
    assert old[0]["found_s"] is None
    new = {**old[0], "world": "clean_kidnap", "found_s": 4.5}
    amcl_bench._write(tmp_path, [*old, new], 1, 30.0, ["clean", "clean_kidnap"])
    assert [r["found_s"] for r in amcl_bench.read_rows(tmp_path / "amcl_results.csv")] == [None, 4.5]


def test_the_command_line_offers_every_world_of_the_benchmark():
    for world in amcl_bench.WORLDS:
        assert peers_args(["--amcl-worlds", world]).amcl_worlds == [world]
    with pytest.raises(SystemExit):
        peers_args(["--amcl-worlds", "kidnap"])


def test_a_drive_too_short_for_the_kidnap_is_refused_naming_the_flag(tmp_path, capsys):
    out = tmp_path / "amcl"
    args = ["--only", "amcl", "--out", str(out), "--amcl-worlds", "clean", "clean_kidnap",
            "--amcl-duration", "10"]  # fmt: skip
    assert peers.amcl_part(peers_args(args)) == 2
    err = capsys.readouterr().err
    assert "--amcl-duration 10" in err and "clean_kidnap" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_rerun_of_ours_keeps_amcls_rows_and_the_recorded_drive(tmp_path):
    """Rows are kept per world, seed and filter: ``rerun=["ours"]`` or deleting ours' row runs
    ours alone on the drive recorded before; amcl's (planted) rows stay and amcl never starts
    (its python does not exist, so starting it would raise)."""
    need_shared("maps/stata_basement.yaml", "maps/basement_fixed_aligned.yaml")
    out, no_amcl = tmp_path / "amcl", "/nonexistent/amcl-python"
    planted = [
        {"world": "clean", "seed": 0, "filter": f, "mean_error_m": 7.0, "p95_error_m": 7.0,
         "max_error_m": 7.0, "pct_over_1m": 100.0, "lost": True, "cpu_s": 1.0, "found_s": None}
        for f in amcl_bench.FILTERS
    ]  # fmt: skip
    out.mkdir()
    amcl_bench._write(out, planted, 1, 2.0, ["clean"])
    said: list[str] = []
    assert amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, out, echo=said.append) == planted
    assert not (out / "drives").exists() and not any("seed 0:" in s for s in said)

    def by_filter() -> dict[str, float]:
        rows = amcl_bench.read_rows(out / "amcl_results.csv")
        assert len(rows) == 3
        return {r["filter"]: r["mean_error_m"] for r in rows}

    amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, out, echo=said.append, rerun=["ours"])
    first = by_filter()
    assert first["amcl"] == first["amcl_recovery"] == 7.0 and first["ours"] < 0.5
    drive = out / "drives" / "clean_seed0_2s.npz"
    recorded = drive.stat().st_mtime_ns
    # ours' row deleted by hand: ours alone runs again, on the same recorded drive
    kept = [r for r in amcl_bench.read_rows(out / "amcl_results.csv") if r["filter"] != "ours"]
    amcl_bench._write(out, kept, 1, 2.0, ["clean"])
    amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, out, echo=said.append)
    again = by_filter()
    assert again["amcl"] == again["amcl_recovery"] == 7.0 and again["ours"] < 0.5
    assert drive.stat().st_mtime_ns == recorded
    with pytest.raises(ValueError, match="unknown filters"):
        amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, out, rerun=["amcl_fast"])
    # the command line offers the same names
    assert peers_args(["--amcl-rerun", *amcl_bench.FILTERS]).amcl_rerun == list(amcl_bench.FILTERS)


def test_rows_made_on_one_map_are_never_mixed_with_another_maps(tmp_path):
    """The filters' map is remembered in ``--out``: a folder of rows on the default map refuses a
    run on another map (nothing changes), and a folder of that map's rows reports it by name."""
    need_shared("maps/stata_basement.yaml", "maps/basement_fixed_aligned.yaml")
    other = SHARED_MAPS / "basement_fixed_aligned.yaml"
    no_amcl = "/nonexistent/amcl-python"
    planted = [
        {"world": "clean", "seed": 0, "filter": f, "mean_error_m": 7.0, "p95_error_m": 7.0,
         "max_error_m": 7.0, "pct_over_1m": 100.0, "lost": True, "cpu_s": 1.0, "found_s": None}
        for f in amcl_bench.FILTERS
    ]  # fmt: skip
    default_rows, other_rows = tmp_path / "default", tmp_path / "other"
    for out in (default_rows, other_rows):
        out.mkdir()
        amcl_bench._write(out, planted, 1, 2.0, ["clean"])
    before = (default_rows / "amcl_results.csv").read_bytes()
    with pytest.raises(ValueError, match=r"holds rows of filters on .*stata_basement\.yaml"):
        amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, default_rows, filter_map=other)
    assert (default_rows / "amcl_results.csv").read_bytes() == before
    (other_rows / amcl_bench.MAP_NOTE).write_text(f"{other.resolve()}\n")
    assert amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, other_rows,
                                    filter_map=other) == planted  # fmt: skip
    assert "filters on basement_fixed_aligned.yaml" in (other_rows / "amcl_results.md").read_text()
    with pytest.raises(ValueError, match=r"holds rows of filters on .*basement_fixed_aligned"):
        amcl_bench.run_benchmark(no_amcl, ["clean"], 1, 2.0, other_rows)


def test_a_drive_gives_amcl_the_same_errors_whatever_ran_before():
    """The same drive and seed through amcl alone and after another drive in the same peer: the
    same errors, bit for bit (the bindings reseed drand48 by a per-process count of initial poses;
    it must not leak from one run into the next). Another seed on the same drive differs: the seed
    is what varies a run."""
    python = _amcl_or_skip()
    grid = amcl_grid(resolve_map("basement_loop"))
    first, drive = (record_drive("basement_loop", seed=s, duration=8.0) for s in (4, 5))
    alone = peer_amcl.localize_with_amcl(python, grid, drive, 3).position_error
    peer = peer_amcl.AmclPeer(python, grid)
    try:
        for d, seed in ((first, 9), (drive, 3), (drive, 8)):
            peer.submit(d, seed)
        runs = [peer.collect()[0].position_error for _ in range(3)]
    finally:
        peer.close()
    np.testing.assert_array_equal(runs[1], alone)
    assert not np.array_equal(runs[2], alone)


def test_our_filter_settings_reach_the_benchmark_and_bad_ones_are_one_line(
    tmp_path, capsys, monkeypatch
):
    """``--ours-filter KEY=VALUE`` sets our filter's config in the amcl part (a calibrated
    odometry scale here); a malformed or out-of-range one is a one-line error naming the flag,
    before any folder is made."""
    need_shared("maps/stata_basement.yaml", "maps/basement_fixed_aligned.yaml")
    seen = {}

    def fake_run(python, worlds, seeds, duration, out, config=None, echo=print, rerun=(),
                 filter_map=None):
        seen["config"] = config
        return []

    monkeypatch.setattr(peer_amcl, "amcl_python", lambda given=None: ("/fake/python", ""))
    monkeypatch.setattr(amcl_bench, "run_benchmark", fake_run)
    monkeypatch.setattr(amcl_bench, "results_md", lambda *a: "")
    out = tmp_path / "amcl"
    args = ["--only", "amcl", "--out", str(out), "--amcl-worlds", "clean",
            "--ours-filter", "filter.odometry_scale.initial=1.056",
            "--ours-filter", "filter.odometry_scale.learn=false"]  # fmt: skip
    assert peers.amcl_part(peers_args(args)) == 0
    scale = seen["config"].filter.odometry_scale
    assert scale.initial == 1.056 and scale.learn is False
    for bad, says in (("filter.odometry_scale.initial=3", "initial"), ("nonsense", "KEY=VALUE"),
                      ("filter.odometry_scale.learn=[", "YAML")):  # fmt: skip
        fresh = tmp_path / f"bad_{len(says)}"
        bad_args = ["--only", "amcl", "--out", str(fresh), "--ours-filter", bad]
        assert peers.amcl_part(peers_args(bad_args)) == 2
        err = capsys.readouterr().err
        assert "--ours-filter" in err and says in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1 and not fresh.exists()


def test_amcl_gets_the_same_odometry_calibration_as_ours():
    """A calibration in our config (filter.odometry_bias) is undone in the odometry amcl gets, so
    both filters run on the same calibrated odometry; without one amcl gets the drive as recorded."""
    from mcl.wrappers.localization import as_localization_config
    from racecar_sim.sensors.scan_effects import OdometryBias

    drive = record_drive("basement_loop", seed=1, duration=1.0)
    assert amcl_bench.calibrated(drive, as_localization_config(None)) is drive
    bias = {"scale": [-0.05, 0.0, 0.1], "offset": [-0.03, -0.01, 0.04]}
    config = as_localization_config({"filter": {"odometry_bias": bias}})
    given = amcl_bench.calibrated(drive, config)
    # reading the calibrated odometry through the bias gives back what was recorded
    np.testing.assert_allclose(OdometryBias(**bias).apply(given.odom), drive.odom, atol=1e-5)
    assert not np.allclose(given.odom, drive.odom)
    np.testing.assert_array_equal(given.scans, drive.scans)
    np.testing.assert_array_equal(given.truth, drive.truth)


def test_the_peer_removes_only_the_files_it_made(tmp_path):
    """A file of the user's where the peer would write its next run's input is refused before
    anything is written and stays; a finished run's files and the grid are removed at the end,
    and a user file beside them in the work folder is left alone."""
    python = _amcl_or_skip()
    grid = amcl_grid(resolve_map("basement_loop"))
    drive = record_drive("basement_loop", seed=4, duration=2.0)
    mine = tmp_path / "mine.txt"
    mine.write_text("keep\n")
    peer = peer_amcl.AmclPeer(python, grid, work=tmp_path)
    try:
        peer.submit(drive, 1)
        peer.collect()
        stem = f"run_{os.getpid()}_{id(peer)}_2"
        planted = tmp_path / f"{stem}_in.npz"
        planted.write_text("the user's\n")
        with pytest.raises(FileExistsError, match="only its own files"):
            peer.submit(drive, 1)
    finally:
        peer.close()
    assert planted.read_text() == "the user's\n" and mine.read_text() == "keep\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["mine.txt", planted.name])


def test_a_filter_map_that_does_not_load_is_one_line_before_any_folder(tmp_path, capsys):
    need_shared("maps/stata_basement.yaml", "maps/basement_fixed_aligned.yaml")
    out = tmp_path / "amcl"
    args = ["--only", "amcl", "--out", str(out), "--amcl-filter-map", str(tmp_path / "no.yaml")]
    assert peers.amcl_part(peers_args(args)) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--amcl-filter-map" in err[0] and "no.yaml" in err[0]
    assert not out.exists()
