"""The opponents experiment: car-sized boxes held ahead show up in the scan where they stand, a run
is reproducible and logs the error, the table pools the seeds, the command refuses bad flags."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mcl.cli.opponents
from mcl.agents.track import track_for_map
from mcl.cli.main import main
from mcl.experiments.opponents import CAR_LENGTH, OpponentsScenario, box_corners
from mcl.experiments.opponents_run import OpponentRun, opponents_table, run_opponents
from mcl.wrappers.error_log import read_error_log
from racecar_sim.env import EnvConfig, RacecarEnv


def test_box_corners_span_the_footprint() -> None:
    c = box_corners(np.array([1.0, 2.0]), math.pi / 2, 0.55, 0.30)
    np.testing.assert_allclose(c.mean(axis=0), [1.0, 2.0])
    np.testing.assert_allclose(np.ptp(c[:, 1]), 0.55, atol=1e-12)  # length along +y
    np.testing.assert_allclose(np.ptp(c[:, 0]), 0.30, atol=1e-12)


def test_an_opponent_ahead_shortens_the_beams_in_front() -> None:
    track = track_for_map("basement_loop")
    env = RacecarEnv("basement_loop", obstacles={"boxes": 1}, terminate_on_collision=False)
    s0 = 5.0
    start = np.array([*track.point_at(s0), track.heading_at(s0)])
    env.reset(seed=0, options={"pose": start})
    scenario = OpponentsScenario(n=1, gaps=(2.0,), track=track)

    class Wrapped:
        unwrapped = env

    scenario.before_step(Wrapped, 1, 0.0, None)
    obs, *_ = env.step(np.array([0.0, 0.0]))
    front = np.abs(env.lidar.angles) < 0.02
    # rear axle -> box centre 2 m along the loop; its near face is half a length closer, and the
    # lidar sits mount_offset ahead of the rear axle (the loop is straight here)
    want = 2.0 - CAR_LENGTH / 2 - env.lidar.params.mount_offset
    assert abs(float(np.median(obs["scan"][front])) - want) < 0.08


def test_a_run_is_reproducible_and_logs_every_step(tmp_path) -> None:
    run = OpponentRun(opponents=1, method="beam_skip", seed=2, duration=1.0, n_particles=300)
    a = run_opponents(run, tmp_path / "a.csv")
    b = run_opponents(run, tmp_path / "b.csv")
    la, lb = read_error_log(a.log_path), read_error_log(b.log_path)
    assert len(la) == round(1.0 / EnvConfig.dt)
    np.testing.assert_array_equal(la.position_error, lb.position_error)
    assert a.collisions == 0
    assert la.position_error.max() < 0.5
    assert 0.0 <= a.skipped_beams < 0.5 and a.converged > 0.5
    rows = opponents_table([a, b])
    assert len(rows) == 1 and rows[0]["seeds"] == 2 and rows[0]["steps"] == 2 * len(la)
    assert rows[0]["median_m"] == pytest.approx(float(np.median(la.position_error)))


def test_bad_run_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="method"):
        OpponentRun(method="magic")
    with pytest.raises(ValueError, match="gaps"):
        OpponentsScenario(n=3, gaps=(2.0,))


def test_command_mistakes_exit_2_before_any_run(monkeypatch, capsys, tmp_path) -> None:
    def started(*args, **kwargs):
        raise AssertionError("a run started although the command line had a mistake")

    monkeypatch.setattr(mcl.cli.opponents, "run_opponents", started)
    for argv, flag in (
        (["--opponents", "4", "--gaps", "2,3"], "--gaps"),
        (["--methods", "magic"], "--methods"),
        (["--seeds", "0"], "--seeds"),
    ):
        try:
            code = main(["opponents", *argv, "--out", str(tmp_path / "out")])
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err
        assert code == 2 and flag in err and "Traceback" not in err
        assert not (tmp_path / "out").exists()
