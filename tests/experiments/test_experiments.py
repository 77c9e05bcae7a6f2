"""Tests of the noise experiment (mcl.experiments.noise_sweep), its runs (mcl.experiments.runs) and scripts/experiment.py."""

from __future__ import annotations

import csv
import importlib.util
import io
import math
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcl.experiments.runner as runner
from mcl.experiments.metrics import ErrorStats
from mcl.experiments.noise_report import METRICS, summarize
from mcl.experiments.noise_sweep import ExperimentConfig, run_experiment
from mcl.experiments.runner import execute_runs
from mcl.experiments.runs import RunResult, RunSpec, run_one
from mcl.experiments.scenarios import SCENARIOS, TrackingScenario, make_scenario
from mcl.filter.motion_model import MotionModelParams
from mcl.wrappers.error_log import count_rows, read_error_log

REPO = Path(__file__).resolve().parents[2]
FAST_ENV = (("n_beams", 181),)
TINY = ExperimentConfig(
    uniform=(0.01, 0.5),
    gaussian=(0.01, 0.5),
    matched=False,
    seeds=1,
    duration=5.0,
    n_particles=150,
    env=FAST_ENV,
)
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
)


def _load_script():
    spec = importlib.util.spec_from_file_location(
        "experiment_script", REPO / "scripts" / "experiment.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["experiment_script"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """The tiny sweep of the issue: 2 coefficients x 2 schemes x 1 seed x 5 s, run inline."""
    out = tmp_path_factory.mktemp("sweep")
    stream = io.StringIO()
    report = run_experiment(TINY, out, workers=1, progress=False, stream=stream)
    return report, stream.getvalue()


# ---------------------------------------------------------------------- the sweep
def test_summary_has_a_row_for_each_scheme_and_coefficient(sweep) -> None:
    report, _ = sweep
    wanted = {(s, c) for s in ("uniform", "gaussian") for c in (0.01, 0.5)}
    assert {(r.series, r.coefficient) for r in report.summary} == wanted
    assert all(r.n_runs == 1 and r.n_failed == 0 for r in report.summary)
    with (report.out_dir / "summary.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {(r["series"], float(r["coefficient"])) for r in rows} == wanted
    for row in rows:
        for name, _ in METRICS:
            assert math.isfinite(float(row[name]))
        assert float(row["max_error"]) >= float(row["p95_error"]) >= 0.0
        assert 0.0 <= float(row["diverged_fraction"]) <= 1.0
    table = [
        line
        for line in (report.out_dir / "summary.md").read_text().splitlines()
        if line.startswith("| uniform") or line.startswith("| gaussian")
    ]
    assert len(table) == 4


def test_every_run_logged_every_step(sweep) -> None:
    report, _ = sweep
    assert [r.status for r in report.results] == ["ok"] * 4
    for r in report.results:
        assert count_rows(r.log_path) == r.spec.n_steps == round(5.0 / r.spec.dt)
        assert r.stats is not None and r.stats.n_steps == r.spec.n_steps


def test_same_seed_gives_the_same_true_trajectory_for_all_schemes(sweep) -> None:
    report, _ = sweep
    logs = [read_error_log(r.log_path) for r in report.results]
    truth = logs[0].true_poses
    assert np.ptp(truth[:, 0]) + np.ptp(truth[:, 1]) > 2.0  # the car drove
    for log in logs[1:]:
        np.testing.assert_array_equal(log.true_poses, truth)
    estimates = {log.estimates.tobytes() for log in logs}
    assert len(estimates) == len(logs)  # ... while the filters differed


def test_bigger_noise_gives_bigger_error(sweep) -> None:
    report, _ = sweep
    by = {(r.series, r.coefficient): r.mean["mean_error"] for r in report.summary}
    for series in ("uniform", "gaussian"):
        assert by[(series, 0.5)] > by[(series, 0.01)]


def test_plots_are_written(sweep) -> None:
    report, _ = sweep
    plots = report.out_dir / "plots"
    names = ["error_vs_coefficient.png", "error_vs_noise_sd.png"]
    names += ["overlay_uniform.png", "overlay_gaussian.png"]
    names += [f"runs/{r.spec.run_id}.png" for r in report.results]
    for name in names:
        img = cv2.imread(str(plots / name))
        assert img is not None and img.shape[0] > 100 and img.shape[1] > 100, name
    assert {p for p in report.files if p.suffix == ".png"} == {plots / n for n in names}


def test_resume_skips_complete_runs_and_redoes_cut_ones(sweep, tmp_path) -> None:
    report, _ = sweep
    out = tmp_path / "resumed"
    shutil.copytree(report.out_dir, out)
    cut = out / "logs" / f"{report.results[2].spec.run_id}.csv"
    lines = cut.read_text().splitlines(keepends=True)
    cut.write_text("".join(lines[:51]) + lines[51][:7])  # a killed run: 50 rows and a half
    again = run_experiment(TINY, out, workers=1, resume=True, progress=False, plots=False)
    assert [r.status for r in again.results] == ["skipped", "skipped", "ok", "skipped"]
    redone = read_error_log(cut)
    original = read_error_log(report.results[2].log_path)
    np.testing.assert_array_equal(redone.true_poses, original.true_poses)
    np.testing.assert_array_equal(redone.estimates, original.estimates)
    assert [r.mean for r in again.summary] == [r.mean for r in report.summary]


def test_resume_refuses_a_folder_made_with_other_settings(sweep, tmp_path) -> None:
    report, _ = sweep
    out = tmp_path / "other"
    shutil.copytree(report.out_dir, out)
    other = ExperimentConfig(**{**TINY.__dict__, "n_particles": 99})
    with pytest.raises(ValueError, match="n_particles"):
        run_experiment(other, out, workers=1, resume=True, progress=False, plots=False)


def test_script_resumes_and_prints_the_summary(sweep, capsys) -> None:
    report, _ = sweep
    script = _load_script()
    code = script.main(
        [
            "--uniform", "0.01,0.5", "--gaussian", "0.01,0.5", "--no-matched", "--seeds", "1",
            "--duration", "5", "--particles", "150", "--resume", "--no-plots", "--workers", "1", "--env", "n_beams=181",
            "--out", str(report.out_dir),
        ]
    )  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0
    assert "| uniform | 0.01 |" in printed
    assert "0 runs done, 4 skipped" in printed
    assert str(report.out_dir.resolve()) in printed


# ---------------------------------------------------------------------- failures
def test_a_crashed_run_is_reported_and_the_others_finish(sweep, tmp_path, monkeypatch) -> None:
    real = runner.run_one

    def flaky(spec, log_path, **kwargs):
        if spec.series == "gaussian" and spec.nominal == 0.5:
            raise RuntimeError("wheel fell off")
        return real(spec, log_path, **kwargs)

    monkeypatch.setattr(runner, "run_one", flaky)
    config = ExperimentConfig(
        uniform=(0.01,), gaussian=(0.5,), matched=False, seeds=1, duration=0.5,
        n_particles=50, env=FAST_ENV,
    )  # fmt: skip
    stream = io.StringIO()
    report = run_experiment(config, tmp_path, workers=1, progress=False, stream=stream)
    assert [r.status for r in report.results] == ["ok", "failed"]
    assert "wheel fell off" in report.failed[0].error
    assert "gaussian_c0.5_seed0 FAILED" in stream.getvalue()
    md = (tmp_path / "summary.md").read_text()
    assert "## Failed runs" in md and "wheel fell off" in md
    row = next(r for r in report.summary if r.series == "gaussian")
    assert (row.n_runs, row.n_failed) == (0, 1)
    with (tmp_path / "runs.csv").open() as f:
        statuses = {r["run_id"]: r["status"] for r in csv.DictReader(f)}
    assert statuses == {"uniform_c0.01_seed0": "ok", "gaussian_c0.5_seed0": "failed"}


def test_process_pool_reports_a_crash_and_finishes_the_rest(tmp_path) -> None:
    good = RunSpec(duration=0.25, n_particles=50, env=FAST_ENV, series="good")
    bad = RunSpec(duration=0.25, n_particles=50, env=FAST_ENV, series="bad", scenario="nope")
    stream = io.StringIO()
    todo = [(good, tmp_path / "good.csv"), (bad, tmp_path / "bad.csv")]
    results = execute_runs(todo, workers=2, stream=stream)
    status = {r.spec.series: r for r in results}
    assert status["good"].status == "ok" and count_rows(tmp_path / "good.csv") == good.n_steps
    assert status["bad"].status == "failed" and "unknown scenario 'nope'" in status["bad"].error
    assert "FAILED" in stream.getvalue()


# ---------------------------------------------------------------------- configuration
def test_matched_series_has_the_variance_of_each_uniform_setting() -> None:
    config = ExperimentConfig(uniform=(0.3, 1.0), gaussian=(0.1,), seeds=2)
    specs = config.runs()
    assert len(specs) == 2 * (2 + 1 + 2)
    matched = [s for s in specs if s.series == "gaussian_matched"]
    assert {s.nominal for s in matched} == {0.3, 1.0}
    for s in matched:
        assert s.motion.scheme == "gaussian"
        sigma = s.motion.coefficients[0]
        # Var(U[-c, c]) = c^2 / 3
        assert sigma**2 == pytest.approx(s.nominal**2 / 3.0)
    assert {s.seed for s in specs} == {0, 1}
    assert len({s.run_id for s in specs}) == len(specs)


def test_config_errors_name_the_setting() -> None:
    with pytest.raises(ValueError, match="seeds"):
        ExperimentConfig(seeds=0)
    with pytest.raises(ValueError, match="uniform"):
        ExperimentConfig(uniform=(0.1, -1.0))
    with pytest.raises(ValueError, match="no runs"):
        ExperimentConfig(uniform=(), gaussian=())
    with pytest.raises(ValueError, match="driver"):
        RunSpec(driver="autopilot")
    with pytest.raises(ValueError, match="duration"):
        RunSpec(duration=0.0)
    with pytest.raises(ValueError, match="unknown scenario"):
        make_scenario("teleport")


def _stats(value: float) -> ErrorStats:
    return ErrorStats(10, 1.0, value, value, value, value, value / 10, min(value, 1.0), 1e-3)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 50.0), min_size=1, max_size=6))
def test_summary_across_seeds(values) -> None:
    spec = RunSpec(series="uniform", nominal=0.1, motion=MotionModelParams("uniform", 0.1))
    results = [
        RunResult(spec=spec, status="ok", stats=_stats(v), log_path=Path("x.csv")) for v in values
    ]
    results.append(RunResult(spec=spec, status="failed", stats=None, log_path=Path("y.csv")))
    (row,) = summarize(results)
    assert (row.n_runs, row.n_failed) == (len(values), 1)
    assert row.mean["mean_error"] == pytest.approx(np.mean(values))
    assert min(values) - 1e-9 <= row.mean["max_error"] <= max(values) + 1e-9
    if len(values) > 1:
        assert row.sd["mean_error"] == pytest.approx(np.std(values, ddof=1), abs=1e-9)
    else:
        assert math.isnan(row.sd["mean_error"])
    assert row.noise_sd == pytest.approx(0.1 / math.sqrt(3.0))


# ---------------------------------------------------------------------- scenarios
def test_a_registered_scenario_is_used_by_the_runs(tmp_path, monkeypatch) -> None:
    seen: list[tuple[int, float]] = []

    @dataclass(frozen=True)
    class Recorder(TrackingScenario):
        name: str = "recorder"

        def before_step(self, env, step, time, rng) -> None:
            seen.append((step, time))

    monkeypatch.setitem(SCENARIOS, "recorder", Recorder)
    spec = RunSpec(scenario="recorder", duration=0.25, n_particles=50, env=FAST_ENV)
    result = run_one(spec, tmp_path / "log.csv")
    assert result.status == "ok"
    assert [k for k, _ in seen] == list(range(1, spec.n_steps + 1))
    np.testing.assert_allclose([t for _, t in seen], np.arange(spec.n_steps) * spec.dt)
