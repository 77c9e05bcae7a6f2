"""What every executor shares: the `Runner` type, the `Executor` protocol and the
result of a run whose worker died.

Below [`mcl.experiments.runner`][mcl.experiments.runner] (the local executors, `make_executor()`) and
[`mcl.experiments.ray_executor`][mcl.experiments.ray_executor] (Ray tasks), which both use it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Protocol

from mcl.experiments.runs import RunResult, RunSpec

__all__ = ["Executor", "Runner", "worker_died"]

Runner = Callable[[RunSpec, Path, float], RunResult]
"""``runner(spec, log_path, diverged_m) -> RunResult``: one run (a module-level function, so that
worker processes, local or on a Ray cluster, can import it)."""


class Executor(Protocol):
    """Where runs execute: `InlineExecutor`, `PoolExecutor` or
    `mcl.experiments.ray_executor.RayExecutor`.

    ``run_all(runner, todo, diverged_m)`` runs ``runner(spec, path, diverged_m)`` for every
    ``(spec, path)`` of ``todo`` and yields each `RunResult` as it finishes. A run whose
    worker process died comes back as a ``"failed"`` result; the others go on.
    """

    def run_all(
        self, runner: Runner, todo: Sequence[tuple[RunSpec, Path]], diverged_m: float
    ) -> Iterator[RunResult]: ...


def worker_died(spec: RunSpec, path: Path, why: str) -> RunResult:
    """The ``"failed"`` result of a run whose worker process died (its log keeps its rows)."""
    return RunResult(spec=spec, status="failed", stats=None, log_path=path, error=why)
