"""Running many drives: a process pool (or inline), resume from complete logs, crash reporting.

Shared by every experiment (the noise sweep, global localization / kidnapping): each run is a
[`RunSpec`][mcl.experiments.runs.RunSpec] that writes ``<out>/logs/<run_id>.csv`` as it goes, so a run
that fails half-way keeps its log, and ``resume`` skips the runs whose log is complete.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import as_completed as futures_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict
from pathlib import Path
from typing import Any, TextIO

from mcl.experiments.executors import Executor, Runner, worker_died
from mcl.experiments.metrics import DIVERGED_M, error_stats
from mcl.experiments.runs import RunResult, RunSpec, run_one
from mcl.wrappers.error_log import read_error_log
from racecar_sim.file_guard import claim_folder, writable

__all__ = [
    "EXECUTORS",
    "Executor",
    "InlineExecutor",
    "PoolExecutor",
    "Runner",
    "execute_runs",
    "log_path",
    "make_executor",
    "record_settings",
    "run_pending",
    "run_spec_safely",
    "settings_difference",
    "skipped_result",
    "worker_died",
]


_RETRIES = 1  # times a run whose worker process died is tried again


def log_path(out_dir: Path, spec: RunSpec) -> Path:
    return out_dir / "logs" / f"{spec.run_id}.csv"


def _init_worker() -> None:
    """One numba thread per worker process: the pool already spreads the runs over the cores."""
    import numba

    numba.set_num_threads(1)


def run_spec_safely(spec: RunSpec, log_path: Path, diverged_m: float = DIVERGED_M) -> RunResult:
    """[`mcl.experiments.runs.run_one()`][mcl.experiments.runs.run_one], with any exception turned into a ``"failed"`` result."""
    try:
        return run_one(spec, log_path, diverged_m=diverged_m)
    except Exception as exc:  # a crashed run is reported; the sweep goes on
        where = traceback.extract_tb(exc.__traceback__)[-1]
        error = f"{type(exc).__name__}: {exc} (at {Path(where.filename).name}:{where.lineno})"
        return RunResult(spec=spec, status="failed", stats=None, log_path=log_path, error=error)


def skipped_result(spec: RunSpec, log_path: Path, diverged_m: float) -> RunResult:
    stats = error_stats(read_error_log(log_path), diverged_m)
    return RunResult(spec=spec, status="skipped", stats=stats, log_path=log_path)


class InlineExecutor:
    """Every run in this process, one after the other."""

    def run_all(
        self, runner: Runner, todo: Sequence[tuple[RunSpec, Path]], diverged_m: float
    ) -> Iterator[RunResult]:
        for spec, path in todo:
            yield runner(spec, path, diverged_m)


class PoolExecutor:
    """A spawn process pool of ``workers`` processes on this machine, one numba thread each.

    When a worker process dies, the pool breaks and every unfinished run fails with it (the
    standard library cannot tell which run killed it): those runs are tried once more in a
    fresh pool, then reported as failed.
    """

    def __init__(self, workers: int) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be a positive integer, got {workers!r}")
        self.workers = workers

    def run_all(
        self, runner: Runner, todo: Sequence[tuple[RunSpec, Path]], diverged_m: float
    ) -> Iterator[RunResult]:
        tries = dict.fromkeys(range(len(todo)), 0)
        pending = list(range(len(todo)))
        context = multiprocessing.get_context("spawn")
        while pending:
            broken: list[int] = []
            workers = min(self.workers, len(pending))
            with ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker) as pool:
                futures: dict[Future[RunResult], int] = {
                    pool.submit(runner, *todo[i], diverged_m): i for i in pending
                }
                for future in futures_completed(futures):
                    i = futures[future]
                    try:
                        yield future.result()
                    except BrokenProcessPool as exc:  # a worker process died
                        tries[i] += 1
                        if tries[i] > _RETRIES:
                            yield worker_died(*todo[i], f"worker process died: {exc}")
                        else:
                            broken.append(i)
                    except Exception as exc:  # the result could not come back
                        yield worker_died(*todo[i], f"worker failed: {type(exc).__name__}: {exc}")
            pending = sorted(broken)


def make_executor(
    name: str = "pool", workers: int | None = None, address: str | None = None
) -> Executor:
    """The executor called ``name``: ``"pool"`` (``workers`` processes, default the CPU count;
    inline when 1) or ``"ray"`` (Ray on this machine, or the cluster at ``address``: ``"auto"``
    or ``HOST:PORT``; ``workers`` caps the runs in flight).

    Raises:
        ValueError: an unknown name, ``address`` without Ray, workers < 1, or Ray not installed.
    """
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise ValueError(f"workers must be >= 1, got {workers}")
    if name == "pool":
        if address is not None:
            raise ValueError("a Ray address needs the ray executor (--executor ray)")
        n = workers if workers is not None else (os.cpu_count() or 1)
        return InlineExecutor() if n <= 1 else PoolExecutor(n)
    if name == "ray":
        from mcl.experiments.ray_executor import RayExecutor

        return RayExecutor(address=address, workers=workers)
    raise ValueError(f"unknown executor {name!r}; choose one of {list(EXECUTORS)}")


EXECUTORS: tuple[str, ...] = ("pool", "ray")
"""Names `make_executor()` knows."""


def execute_runs(
    todo: Sequence[tuple[RunSpec, Path]],
    workers: int = 1,
    *,
    diverged_m: float = DIVERGED_M,
    progress: bool = False,
    total: int | None = None,
    done_already: int = 0,
    stream: TextIO | None = None,
    runner: Runner | None = None,
    executor: Executor | None = None,
) -> list[RunResult]:
    """Run ``todo`` = [(spec, log path)] on ``executor`` (default: inline when ``workers`` is 1,
    else a `PoolExecutor` of ``workers`` processes).

    Each run is ``runner(spec, log_path, diverged_m)`` (default `run_spec_safely()`; another
    runner must be a module-level function so that worker processes can import it).

    A tqdm bar counts ``total`` runs (default: len(todo)) from ``done_already``; failures are
    reported on ``stream`` (default stderr) as they come. Returns the results in the order they
    finished; a run that raised, or whose worker process died, is a ``"failed"`` result.
    """
    from tqdm import tqdm

    if executor is None:
        executor = InlineExecutor() if workers <= 1 else PoolExecutor(workers)
    bar = tqdm(total=total, initial=done_already, unit="run", disable=not progress, file=stream)
    results: list[RunResult] = []
    try:
        for result in executor.run_all(runner or run_spec_safely, todo, diverged_m):
            results.append(result)
            if result.status == "failed":
                bar.write(f"run {result.spec.run_id} FAILED: {result.error}", file=stream)
            bar.update(1)
    finally:
        bar.close()
    return results


def settings_difference(config: Any, path: Path) -> str | None:
    """Why runs recorded in ``path`` (a ``config.json``) cannot be resumed with ``config``, naming
    the settings that differ; None when they are the same or nothing is recorded."""
    if not path.is_file():
        return None
    settings = json.dumps(asdict(config), sort_keys=True, default=str)
    before = path.read_text(encoding="utf-8").strip()
    if before == settings:
        return None
    try:
        old = json.loads(before)
    except ValueError:
        old = {}
    new = json.loads(settings)
    changed = sorted(k for k in new if not isinstance(old, dict) or old.get(k) != new[k])
    return (
        f"--resume: {path.parent} holds runs with other settings ({', '.join(changed)} "
        "differ); use another output folder or drop --resume"
    )


def record_settings(config: Any, path: Path, resume: bool) -> None:
    """Record an experiment config (a dataclass) as JSON in ``path``; with ``resume``, refuse a folder
    made with other settings, naming the settings that differ
    ([settings_difference][mcl.experiments.runner.settings_difference]).

    Logs are only reusable by runs with the same settings (map, particles, env, ...).
    """
    problem = settings_difference(config, path) if resume else None
    if problem is not None:
        raise ValueError(problem)
    settings = json.dumps(asdict(config), sort_keys=True, default=str)
    writable(path).write_text(settings + "\n", encoding="utf-8")


def run_pending(
    config: Any,
    specs: Sequence[RunSpec],
    out: Path,
    *,
    workers: int | None,
    resume: bool,
    reuse: Callable[[RunSpec, Path], RunResult | None],
    progress: bool,
    stream: TextIO,
    diverged_m: float = DIVERGED_M,
    runner: Runner | None = None,
    executor: Executor | None = None,
) -> list[RunResult]:
    """Run ``specs`` into ``out/logs/<run_id>.csv``; the results in the order of ``specs``.

    ``out`` is claimed first ([claim_folder][racecar_sim.file_guard.claim_folder]: a new, empty or
    racecar-sim folder; [NotOurs][racecar_sim.file_guard.NotOurs] for any other).

    The folder's ``config.json`` records ``config`` (see `record_settings()`). With ``resume``,
    ``reuse(spec, log_path)`` may return a ``"skipped"`` result for a run whose output is complete;
    every other run goes to `execute_runs()` on ``executor`` (default: a pool of ``workers``
    processes, the CPU count by default).
    """
    ids = [s.run_id for s in specs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{type(config).__name__}: two runs share a name (repeated settings?)")
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    claim_folder(out)
    (out / "logs").mkdir(parents=True, exist_ok=True)
    record_settings(config, out / "config.json", resume)
    by_id: dict[str, RunResult] = {}
    todo: list[tuple[RunSpec, Path]] = []
    for spec in specs:
        path = log_path(out, spec)
        kept = reuse(spec, path) if resume else None
        if kept is not None:
            by_id[spec.run_id] = kept
        else:
            todo.append((spec, path))
    done = execute_runs(
        todo,
        min(workers, max(len(todo), 1)),
        diverged_m=diverged_m,
        progress=progress,
        total=len(specs),
        done_already=len(by_id),
        stream=stream,
        runner=runner,
        executor=executor,
    )
    by_id.update({r.spec.run_id: r for r in done})
    return [by_id[i] for i in ids]
