"""Running many drives: a process pool (or inline), resume from complete logs, crash reporting.

Shared by every experiment (the noise sweep, global localization / kidnapping): each run is a
:class:`~mcl.experiments.runs.RunSpec` that writes ``<out>/logs/<run_id>.csv`` as it goes, so a run
that fails half-way keeps its log, and ``resume`` skips the runs whose log is complete.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import as_completed as futures_completed
from dataclasses import asdict
from pathlib import Path
from typing import Any, TextIO

from mcl.error_log import read_error_log
from mcl.experiments.metrics import DIVERGED_M, error_stats
from mcl.experiments.runs import RunResult, RunSpec, run_one

__all__ = [
    "execute_runs",
    "log_path",
    "record_settings",
    "run_pending",
    "run_spec_safely",
    "skipped_result",
]


def log_path(out_dir: Path, spec: RunSpec) -> Path:
    return out_dir / "logs" / f"{spec.run_id}.csv"


def _init_worker() -> None:
    """One numba thread per worker process: the pool already spreads the runs over the cores."""
    import numba

    numba.set_num_threads(1)


def run_spec_safely(spec: RunSpec, log_path: Path, diverged_m: float = DIVERGED_M) -> RunResult:
    """:func:`mcl.experiments.runs.run_one`, with any exception turned into a ``"failed"`` result."""
    try:
        return run_one(spec, log_path, diverged_m=diverged_m)
    except Exception as exc:  # a crashed run is reported; the sweep goes on
        where = traceback.extract_tb(exc.__traceback__)[-1]
        error = f"{type(exc).__name__}: {exc} (at {Path(where.filename).name}:{where.lineno})"
        return RunResult(spec=spec, status="failed", stats=None, log_path=log_path, error=error)


def skipped_result(spec: RunSpec, log_path: Path, diverged_m: float) -> RunResult:
    stats = error_stats(read_error_log(log_path), diverged_m)
    return RunResult(spec=spec, status="skipped", stats=stats, log_path=log_path)


def execute_runs(
    todo: Sequence[tuple[RunSpec, Path]],
    workers: int = 1,
    *,
    diverged_m: float = DIVERGED_M,
    progress: bool = False,
    total: int | None = None,
    done_already: int = 0,
    stream: TextIO | None = None,
    runner: Callable[[RunSpec, Path, float], RunResult] | None = None,
) -> list[RunResult]:
    """Run ``todo`` = [(spec, log path)]: inline when ``workers`` is 1, else in a spawn process pool.

    Each run is ``runner(spec, log_path, diverged_m)`` (default :func:`run_spec_safely`; another
    runner must be a module-level function so that worker processes can import it).

    A tqdm bar counts ``total`` runs (default: len(todo)) from ``done_already``; failures are
    reported on ``stream`` (default stderr) as they come. Returns the results in the order they
    finished; a run that raised, or whose worker process died, is a ``"failed"`` result.
    """
    from tqdm import tqdm

    bar = tqdm(total=total, initial=done_already, unit="run", disable=not progress, file=stream)
    run = runner if runner is not None else run_spec_safely
    results: list[RunResult] = []

    def finished(result: RunResult) -> None:
        results.append(result)
        if result.status == "failed":
            bar.write(f"run {result.spec.run_id} FAILED: {result.error}", file=stream)
        bar.update(1)

    try:
        if workers <= 1:
            for spec, path in todo:
                finished(run(spec, path, diverged_m))
            return results
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker) as pool:
            futures: dict[Future[RunResult], tuple[RunSpec, Path]] = {
                pool.submit(run, spec, path, diverged_m): (spec, path) for spec, path in todo
            }
            for future in futures_completed(futures):
                spec, path = futures[future]
                try:
                    result = future.result()
                except Exception as exc:  # the worker process itself died
                    result = RunResult(
                        spec=spec,
                        status="failed",
                        stats=None,
                        log_path=path,
                        error=f"worker process failed: {type(exc).__name__}: {exc}",
                    )
                finished(result)
    finally:
        bar.close()
    return results


def record_settings(config: Any, path: Path, resume: bool) -> None:
    """Record an experiment config (a dataclass) as JSON in ``path``; with ``resume``, refuse a folder
    made with other settings, naming the settings that differ.

    Logs are only reusable by runs with the same settings (map, particles, env, ...).
    """
    settings = json.dumps(asdict(config), sort_keys=True, default=str)
    if resume and path.is_file():
        before = path.read_text(encoding="utf-8").strip()
        if before != settings:
            old, new = json.loads(before), json.loads(settings)
            changed = sorted(k for k in new if old.get(k) != new[k])
            raise ValueError(
                f"--resume: {path.parent} holds runs with other settings ({', '.join(changed)} "
                "differ); use another output folder or drop --resume"
            )
    path.write_text(settings + "\n", encoding="utf-8")


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
    runner: Callable[[RunSpec, Path, float], RunResult] | None = None,
) -> list[RunResult]:
    """Run ``specs`` into ``out/logs/<run_id>.csv``; the results in the order of ``specs``.

    The folder's ``config.json`` records ``config`` (see :func:`record_settings`). With ``resume``,
    ``reuse(spec, log_path)`` may return a ``"skipped"`` result for a run whose output is complete;
    every other run goes to :func:`execute_runs` over ``workers`` processes (default: the CPU count).
    """
    ids = [s.run_id for s in specs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{type(config).__name__}: two runs share a name (repeated settings?)")
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
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
    )
    by_id.update({r.spec.run_id: r for r in done})
    return [by_id[i] for i in ids]
