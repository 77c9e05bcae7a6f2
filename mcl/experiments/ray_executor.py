"""Runs on Ray: a local Ray on this machine, or an existing cluster (the optional extra ``[ray]``).

`RayExecutor` is an [`mcl.experiments.runner.Executor`][mcl.experiments.runner.Executor]: each run is one Ray task
(one CPU, one numba thread) calling the same runner as the process pool, so a run's log is the
same whichever executor ran it (apart from the ``update_s`` timing column). The sweep's logic stays
in the driver: resume, the progress bar, crash reporting, summaries and plots.

Files. A task on the driver's own node writes its log straight into the output folder, row by
row, so a worker that dies mid-run leaves its partial log there. A task on another node of a
cluster writes into a temporary folder there and sends back every file the run wrote (the log, a
recovery run's outcome ``.json``), which the driver puts into the output folder; a partial log of
a worker that died on another node stays lost with it. Every node needs this package installed
(``pip install -e '.[ray]'``, same version) and the maps the runs name.

Dead workers. Ray tries a task again once when its worker process dies (``max_retries``); a run
that dies twice is reported as failed while the others finish. Exceptions inside a run are not
retried: the runner turns them into ``"failed"`` results, as in the pool.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from mcl.experiments.executors import Runner, worker_died
from mcl.experiments.runs import RunResult, RunSpec
from racecar_sim.file_guard import writable

__all__ = ["RayExecutor", "require_ray"]

_RETRIES = 1  # Ray tries a task again this many times when its worker process dies


def require_ray() -> Any:
    """The ``ray`` module; ``ValueError`` with the install hint when it is missing."""
    try:
        import ray
    except ImportError:
        raise ValueError(
            "the ray executor needs Ray: pip install -e '.[ray]' (or pip install ray)"
        ) from None
    return ray


def _run_task(
    runner: Runner, spec: RunSpec, path: str, diverged_m: float, driver_node: str
) -> tuple[RunResult, dict[str, bytes] | None]:
    """The Ray task: the run, and the files it wrote when it ran away from the driver's node."""
    import numba
    import ray

    numba.set_num_threads(1)  # the cluster already spreads the runs over the cores
    if ray.get_runtime_context().get_node_id() == driver_node:
        return runner(spec, Path(path), diverged_m), None
    with tempfile.TemporaryDirectory(prefix="mcl-run-") as tmp:
        local = Path(tmp) / Path(path).name
        result = runner(spec, local, diverged_m)
        files = {f.name: f.read_bytes() for f in Path(tmp).iterdir() if f.is_file()}
    return replace(result, log_path=Path(path)), files


class RayExecutor:
    """Runs as Ray tasks (see the module docstring).

    Args:
        address: None starts a local Ray on this machine (``workers`` CPUs, default all);
            ``"auto"`` or ``"HOST:PORT"`` joins a running cluster. When Ray is already
            initialised in this process (e.g. by a test), that instance is used and left running.
        workers: most runs in flight at once (default: the cluster's CPUs).
    """

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        require_ray()
        if workers is not None and (
            isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
        ):
            raise ValueError(f"workers must be a positive integer, got {workers!r}")
        if address is not None and not str(address).strip():
            raise ValueError("the Ray address must be 'auto' or HOST:PORT, got an empty string")
        self.address = address
        self.workers = workers

    def _connect(self, ray: Any) -> bool:
        """Initialise Ray unless it is already; True when this call started it."""
        if ray.is_initialized():
            return False
        quiet = {"include_dashboard": False, "log_to_driver": False}
        if self.address is None:
            ray.init(num_cpus=self.workers or os.cpu_count() or 1, **quiet)
        else:
            try:
                ray.init(address=self.address, **quiet)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise ValueError(f"cannot join the Ray cluster at {self.address!r}: {exc}") from exc
        return True

    def run_all(
        self, runner: Runner, todo: Sequence[tuple[RunSpec, Path]], diverged_m: float
    ) -> Iterator[RunResult]:
        """Yield each run's result as its task finishes (at most ``workers`` in flight)."""
        ray = require_ray()
        if not todo:
            return
        started = self._connect(ray)
        try:
            task = ray.remote(num_cpus=1, max_retries=_RETRIES, retry_exceptions=False)(_run_task)
            driver_node = ray.get_runtime_context().get_node_id()
            runner_ref = ray.put(runner)
            limit = self.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
            queue = list(todo)
            queue.reverse()
            in_flight: dict[Any, tuple[RunSpec, Path]] = {}
            while queue or in_flight:
                while queue and len(in_flight) < limit:
                    spec, path = queue.pop()
                    ref = task.remote(runner_ref, spec, str(path), diverged_m, driver_node)
                    in_flight[ref] = (spec, path)
                ready, _ = ray.wait(list(in_flight), num_returns=1)
                spec, path = in_flight.pop(ready[0])
                yield self._collect(ray, ready[0], spec, path)
        finally:
            if started:
                ray.shutdown()

    @staticmethod
    def _collect(ray: Any, ref: Any, spec: RunSpec, path: Path) -> RunResult:
        try:
            result, files = ray.get(ref)
        except ray.exceptions.WorkerCrashedError:
            return worker_died(
                spec, path, f"worker process died in {_RETRIES + 1} tries (killed or crashed)"
            )
        except ray.exceptions.RayError as exc:  # node lost, object lost, task cancelled, ...
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            return worker_died(spec, path, f"Ray: {type(exc).__name__}: {first}")
        for name, data in (files or {}).items():
            path.parent.mkdir(parents=True, exist_ok=True)
            writable(path.parent / name).write_bytes(data)
        return result
