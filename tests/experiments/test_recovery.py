"""Global localization and kidnapping in the simulator: the scenarios, the experiment, its script.

The end-to-end runs drive the real env on bundled maps with the experiment's filter settings
(:func:`mcl.experiments.recovery.recovery_localization`); each takes a few seconds, hence ``slow``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mcl.experiments.recovery import RecoveryConfig, run_recovery_experiment
from mcl.experiments.runs import RunSpec, run_one
from mcl.experiments.scenarios import GlobalScenario, KidnapScenario, make_scenario
from mcl.wrappers.error_log import read_error_log
from mcl.wrappers.single import LocalizationWrapper
from racecar_sim.env import RacecarEnv

REPO = Path(__file__).resolve().parents[2]
FAST_ENV = (("n_beams", 181),)


def test_kidnap_scenario_moves_the_car_once_far_away_into_free_space() -> None:
    env = RacecarEnv("basement_loop")
    env.reset(seed=3)
    start = env.pose.copy()
    scenario = make_scenario("kidnap", kidnap_time=0.5, min_distance=5.0)
    assert isinstance(scenario, KidnapScenario)
    assert scenario.reset_options()["init"] == "pose"
    rng = np.random.default_rng(0)
    for k in range(1, 40):
        t = (k - 1) * env.dt
        scenario.before_step(env, k, t, rng)
        if t < 0.5 - 1e-9:
            np.testing.assert_array_equal(env.pose, start)  # not yet
    moved = env.pose.copy()
    assert math.dist(moved[:2], start[:2]) >= 5.0
    assert env.physics.pose_is_free(moved)
    out = scenario.outcome()
    assert out["lost_at"] == pytest.approx(0.5)
    np.testing.assert_allclose(out["kidnap_to"], moved)
    np.testing.assert_allclose(out["kidnap_from"], start)
    with pytest.raises(ValueError, match="kidnap_time"):
        KidnapScenario(kidnap_time=-1.0)


def test_scenarios_record_the_particle_count_and_the_ambiguity_flag(tmp_path) -> None:
    spec = RunSpec(
        map="basement_loop", scenario="global", duration=0.5, n_particles=300, env=FAST_ENV,
        config=RecoveryConfig().localization,
    )  # fmt: skip
    result = run_one(spec, tmp_path / "log.csv")
    out = result.outcome
    assert out["lost_at"] == 0.0
    assert len(out["n_particles"]) == len(out["ambiguous"]) == spec.n_steps
    assert set(out["ambiguous"]) <= {0, 1}
    assert GlobalScenario().reset_options() == {"init": "global"}


@pytest.mark.slow
def test_a_seeded_kidnap_on_the_default_map_recovers_within_the_limit(tmp_path) -> None:
    config = RecoveryConfig(scenario="kidnap", seeds=1, first_seed=2, kidnap_time=2.0)
    report = run_recovery_experiment(config, tmp_path, workers=1, progress=False, plots=False)
    (run,) = report.runs
    assert run.result.status == "ok"
    stats = run.stats
    assert stats.lost_at == pytest.approx(2.0)
    log = read_error_log(run.result.log_path)
    after = log.time > 2.1
    assert log.position_error[after].max() > 2.0  # it really was kidnapped
    assert stats.success and stats.convergence_s <= config.limit
    assert stats.error_after < 0.1
    assert stats.peak_particles > 1000  # the lost filter grew its set
    assert report.success_rate == 1.0


@pytest.mark.slow
def test_the_corridor_is_reported_ambiguous_not_confidently_wrong(tmp_path) -> None:
    config = RecoveryConfig(map="corridor", scenario="global", seeds=1, duration=8.0)
    report = run_recovery_experiment(config, tmp_path, workers=1, progress=False, plots=False)
    (run,) = report.runs
    flags = np.asarray(run.result.outcome["ambiguous"], dtype=bool)
    log = read_error_log(run.result.log_path)
    assert flags.mean() > 0.9
    assert run.stats.wrong_fraction < 0.02
    # ... and it is right to be unsure: the estimate is not the truth most of the time.
    assert np.mean(log.position_error > 1.0) > 0.5


@pytest.mark.slow
def test_script_runs_a_tiny_kidnap_experiment_and_resumes(tmp_path) -> None:
    out = tmp_path / "kidnap"
    cmd = [
        sys.executable, str(REPO / "scripts" / "experiment.py"), "--scenario", "kidnap",
        "--seeds", "2", "--kidnap-time", "0.5", "--duration", "1.5", "--particles", "3000",
        "--env", "n_beams=181", "--workers", "1", "--out", str(out),
    ]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "| runs | success (≤ 15 s)" in done.stdout
    assert "2 runs done, 0 skipped" in done.stdout
    for seed in (0, 1):
        log = read_error_log(out / "logs" / f"kidnap_seed{seed}.csv")
        assert len(log) == 60
        outcome = json.loads((out / "logs" / f"kidnap_seed{seed}.json").read_text())
        assert outcome["lost_at"] == pytest.approx(0.5)
    with (out / "runs.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["run_id"] for r in rows] == ["kidnap_seed0", "kidnap_seed1"]
    for name in ("overlay.png", "convergence.png", "particles.png", "runs/kidnap_seed0.png"):
        assert (out / "plots" / name).is_file()
    again = subprocess.run([*cmd, "--resume"], capture_output=True, text=True, cwd=REPO)
    assert again.returncode == 0, again.stderr
    assert "0 runs done, 2 skipped" in again.stdout
    other = subprocess.run([*cmd[:-2], "--out", str(out), "--resume", "--kidnap-time", "1.0"])
    assert other.returncode != 0  # a folder made with other settings is refused


def test_config_errors_are_named() -> None:
    with pytest.raises(ValueError, match="scenario"):
        RecoveryConfig(scenario="tracking")
    with pytest.raises(ValueError, match="seeds"):
        RecoveryConfig(seeds=0)
    with pytest.raises(ValueError, match="duration"):
        RecoveryConfig(scenario="kidnap", kidnap_time=10.0, duration=5.0)
    assert RecoveryConfig(scenario="kidnap").total_duration == pytest.approx(25.0)
    assert RecoveryConfig().limit == 10.0 and RecoveryConfig(scenario="kidnap").limit == 15.0


def test_wrapper_info_reports_how_far_to_trust_the_estimate() -> None:
    env = LocalizationWrapper(
        RacecarEnv("basement_loop", n_beams=181), {"filter": {"n_particles": 500}}
    )  # (200 particles under the 0.1 m tracking hit can be two clumps after one scan: ambiguous)
    _, info = env.reset(seed=0)
    loc = info["localization"]
    assert loc["covariance"].shape == (3, 3)
    np.testing.assert_allclose(loc["covariance"], env.filter.covariance())
    assert loc["n_particles"] == 500 and loc["n_clusters"] >= 1
    assert 0.0 < loc["top_weight"] <= 1.0
    assert loc["position_sd"] == pytest.approx(
        math.sqrt(np.linalg.eigvalsh(loc["covariance"][:2, :2])[-1])
    )
    assert loc["ambiguous"] is False  # started around the truth
    _, info = env.reset(seed=0, options={"init": "global"})
    assert info["localization"]["n_particles"] > 500  # sized from the free area
    env.close()


def test_io_free_summary_of_failed_runs() -> None:
    from mcl.experiments.recovery import RecoveryRun
    from mcl.experiments.recovery_report import summary_markdown
    from mcl.experiments.runs import RunResult

    spec = RecoveryConfig(seeds=1).runs()[0]
    failed = RecoveryRun(RunResult(spec, "failed", None, Path("x.csv"), error="boom"), None)
    text = summary_markdown(RecoveryConfig(seeds=1), [failed])
    assert "0 (1 failed)" in text and "failed: boom" in text
    assert io.StringIO(text).readline().startswith("| runs |")
