"""Sweeps on Ray (mcl.experiments.ray_executor) against the process pool, on a local Ray with 2 CPUs:
the same logs, resume, a killed worker retried once then reported, the command line."""

from __future__ import annotations

import csv
import io
import os
import shutil
import signal
import sys
from pathlib import Path

import pytest

from mcl.experiments import runner
from mcl.experiments.noise_sweep import ExperimentConfig, run_experiment
from mcl.experiments.runner import execute_runs, make_executor, run_spec_safely
from mcl.experiments.runs import RunSpec
from mcl.wrappers.error_log import count_rows

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install -e '.[ray]')")

from mcl.experiments.ray_executor import RayExecutor  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
FAST_ENV = (("n_beams", 181),)
SWEEP = ExperimentConfig(
    uniform=(0.5,),
    gaussian=(0.5,),
    matched=False,
    seeds=2,
    duration=2.0,
    n_particles=150,
    env=FAST_ENV,
)
DIE_AFTER = 20  # steps a doomed run logs before its worker process is killed
pytestmark = [
    pytest.mark.filterwarnings(
        "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
    ),
    pytest.mark.filterwarnings("ignore::DeprecationWarning"),
]


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray with 2 CPUs for the module (the executors use it and leave it running)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    # The runner that kills its worker lives in this test module, which workers cannot import.
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def sweeps(local_ray, tmp_path_factory):
    """The same sweep through a 2-process pool and through Ray."""
    pool_out, ray_out = tmp_path_factory.mktemp("pool"), tmp_path_factory.mktemp("ray")
    pool = run_experiment(SWEEP, pool_out, workers=2, progress=False, stream=io.StringIO())
    stream = io.StringIO()
    on_ray = run_experiment(
        SWEEP, ray_out, progress=True, stream=stream, executor=RayExecutor(workers=2)
    )
    return pool, on_ray, stream.getvalue()


def _rows(path: Path, drop: tuple[str, ...]) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]


def test_ray_writes_the_same_logs_and_summaries_as_the_pool(sweeps) -> None:
    pool, on_ray, progress = sweeps
    assert [r.status for r in on_ray.results] == ["ok"] * 4
    assert [r.spec.run_id for r in on_ray.results] == [r.spec.run_id for r in pool.results]
    for a, b in zip(pool.results, on_ray.results, strict=True):
        assert b.log_path.parent == on_ray.out_dir / "logs"
        assert count_rows(b.log_path) == b.spec.n_steps
        assert _rows(a.log_path, ("update_s",)) == _rows(b.log_path, ("update_s",))
    timing = ("wall_s", "mean_update_s", "max_update_s", "median_update_s")
    assert _rows(pool.out_dir / "runs.csv", timing) == _rows(on_ray.out_dir / "runs.csv", timing)
    for name in ("summary.csv", "summary.md"):
        assert (pool.out_dir / name).read_text() == (on_ray.out_dir / name).read_text()
    assert (on_ray.out_dir / "plots" / "error_vs_coefficient.png").is_file()
    assert "4/4" in progress  # the progress bar counted every run


def test_ray_resume_skips_complete_runs_and_redoes_a_cut_one(sweeps, tmp_path) -> None:
    _, on_ray, _ = sweeps
    out = tmp_path / "resumed"
    shutil.copytree(on_ray.out_dir, out)
    cut = out / "logs" / f"{on_ray.results[1].spec.run_id}.csv"
    lines = cut.read_text().splitlines(keepends=True)
    cut.write_text("".join(lines[:11]) + lines[11][:5])  # a killed run: 10 rows and a half
    again = run_experiment(
        SWEEP, out, resume=True, progress=False, plots=False, executor=RayExecutor()
    )
    assert [r.status for r in again.results] == ["skipped", "ok", "skipped", "skipped"]
    assert _rows(cut, ("update_s",)) == _rows(on_ray.results[1].log_path, ("update_s",))


def test_a_kidnap_experiment_on_ray_matches_the_inline_run(local_ray, tmp_path) -> None:
    from mcl.experiments.recovery import RecoveryConfig, run_recovery_experiment

    config = RecoveryConfig(
        scenario="kidnap", seeds=2, duration=3.0, kidnap_time=1.0, time_limit=2.0, env=FAST_ENV
    )
    quiet = {"progress": False, "plots": False, "stream": io.StringIO()}
    inline = run_recovery_experiment(config, tmp_path / "inline", workers=1, **quiet)
    on_ray = run_recovery_experiment(
        config, tmp_path / "ray", executor=RayExecutor(workers=2), **quiet
    )
    assert [r.result.status for r in on_ray.runs] == ["ok", "ok"]
    for a, b in zip(inline.runs, on_ray.runs, strict=True):
        assert _rows(a.result.log_path, ("update_s",)) == _rows(b.result.log_path, ("update_s",))
        outcome = b.result.log_path.with_suffix(".json")  # written by the Ray worker
        assert outcome.read_text() == a.result.log_path.with_suffix(".json").read_text()
        assert a.result.outcome == b.result.outcome


def _dying_runner(spec: RunSpec, log_path: Path, diverged_m: float):
    """Seed 1 kills its worker process after DIE_AFTER steps every time; seed 2 only the first
    time (tries counted in a file beside the log); the others run normally."""
    tries_file = log_path.with_suffix(".tries")
    tries = int(tries_file.read_text()) + 1 if tries_file.is_file() else 1
    tries_file.write_text(str(tries))
    if spec.seed == 1 or (spec.seed == 2 and tries == 1):
        import mcl.wrappers.single

        step = mcl.wrappers.single.LocalizationWrapper.step

        def dying_step(self, action):
            if self._step >= DIE_AFTER:
                os.kill(os.getpid(), signal.SIGKILL)
            return step(self, action)

        mcl.wrappers.single.LocalizationWrapper.step = dying_step
    return run_spec_safely(spec, log_path, diverged_m)


def test_a_killed_worker_is_retried_once_then_reported_while_the_others_finish(
    local_ray, tmp_path
) -> None:
    specs = [RunSpec(duration=1.0, n_particles=100, env=FAST_ENV, seed=s) for s in range(3)]
    todo = [(s, tmp_path / f"{s.run_id}.csv") for s in specs]
    stream = io.StringIO()
    results = execute_runs(
        todo, runner=_dying_runner, executor=RayExecutor(workers=2), stream=stream
    )
    by_seed = {r.spec.seed: r for r in results}
    assert by_seed[0].status == "ok" and count_rows(todo[0][1]) == specs[0].n_steps
    dead = by_seed[1]
    assert dead.status == "failed" and "worker process died in 2 tries" in dead.error
    assert (tmp_path / "run_seed1.tries").read_text() == "2"
    assert count_rows(todo[1][1]) == DIE_AFTER  # the partial log of the last try stays
    assert "run_seed1 FAILED" in stream.getvalue()
    assert by_seed[2].status == "ok" and count_rows(todo[2][1]) == specs[2].n_steps
    assert (tmp_path / "run_seed2.tries").read_text() == "2"


def test_command_line_runs_on_ray(local_ray, tmp_path, capsys) -> None:
    from mcl.cli.experiment import main

    code = main(
        [
            "--uniform", "0.5", "--gaussian", "", "--no-matched", "--seeds", "1",
            "--duration", "0.5", "--particles", "100", "--no-plots", "--env", "n_beams=181",
            "--executor", "ray", "--out", str(tmp_path),
        ]
    )  # fmt: skip
    assert code == 0
    assert "1 runs done, 0 skipped" in capsys.readouterr().out
    assert count_rows(tmp_path / "logs" / "uniform_c0.5_seed0.csv") == 20


def test_executor_choice_errors_are_one_line(monkeypatch, capsys) -> None:
    from mcl.cli.experiment import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--ray-address", "auto"])
    assert exit_info.value.code == 2
    assert "--ray-address: needs --executor ray" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    with pytest.raises(SystemExit) as exit_info:
        main(["--executor", "ray"])
    assert exit_info.value.code == 2
    assert "pip install -e '.[ray]'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="unknown executor"):
        make_executor("dask")
    assert isinstance(make_executor("pool", workers=1), runner.InlineExecutor)


def test_a_pool_whose_worker_was_killed_tries_the_unfinished_runs_again(tmp_path) -> None:
    specs = [RunSpec(duration=1.0, n_particles=100, env=FAST_ENV, seed=s) for s in (0, 2)]
    todo = [(s, tmp_path / f"{s.run_id}.csv") for s in specs]
    results = execute_runs(todo, runner=_dying_runner, executor=runner.PoolExecutor(2))
    assert sorted(r.status for r in results) == ["ok", "ok"]
    assert (tmp_path / "run_seed2.tries").read_text() == "2"  # killed once, then finished
    assert all(count_rows(path) == spec.n_steps for spec, path in todo)
