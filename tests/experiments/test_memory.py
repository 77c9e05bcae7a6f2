"""Memory of a long drive: the per-step loop keeps nothing per step, and reading the error log at the
end of a run costs about its columns, not its text split into fields (which was ~1.2 KB per step:
a 30-minute drive peaked 70 MB above a 1-minute one). Python allocations only (tracemalloc); the
soak benchmark (``racecar-sim bench soak``) measures the whole process's resident memory."""

from __future__ import annotations

import gc
import tracemalloc

import numpy as np

from mcl.experiments.runs import RunSpec, run_one
from mcl.wrappers.error_log import HEADER, ErrorLogWriter, read_error_log


def _write_log(path, n: int) -> None:
    rng = np.random.default_rng(1)
    with ErrorLogWriter(path) as log:
        for k in range(1, n + 1):
            pose = rng.normal(size=3)
            log.write(k, 0.025 * k, pose, pose + 0.01, 0.01, 0.001, 1234.5, 1.23e-3)


def test_reading_a_long_error_log_costs_about_its_columns(tmp_path) -> None:
    n = 20_000
    path = tmp_path / "log.csv"
    _write_log(path, n)
    gc.collect()
    tracemalloc.start()
    try:
        log = read_error_log(path)
        kept, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(log) == n and log.step[-1] == n
    columns = 8 * len(HEADER)  # bytes per row of the float64 columns
    assert kept / n < 1.5 * columns  # what the log holds: its columns
    # the text of a row split into 12 Python strings is ~1.2 KB; blocks of rows + one concatenate
    # stay within a few times the columns
    assert peak / n < 4 * columns, f"peak {peak / n:.0f} bytes per row"


def test_the_drive_loop_keeps_nothing_per_step(tmp_path) -> None:
    """Python memory still held per step over two windows of 500 steps (250..750, 750..1250) of a
    drive (the car keeps the wall segments near it as it explores: bounded by the map, a few bytes
    per step here). Memory kept per step shows in both windows; something made once (a kernel
    loaded from numba's cache in a fresh process, a lazy import) in one only, so the smaller of
    the two is held to the bound."""
    held: dict[int, int] = {}
    count = [0]

    def on_step(record) -> None:
        count[0] += 1
        if count[0] == 250:
            gc.collect()
            tracemalloc.start()
        elif count[0] in (750, 1250):
            gc.collect()
            held[count[0]] = tracemalloc.get_traced_memory()[0]
            if count[0] == 1250:
                tracemalloc.stop()

    spec = RunSpec(duration=1251 * 0.025, n_particles=200, env=(("n_beams", 181),), series="m")
    try:
        run_one(spec, tmp_path / "log.csv", step_hooks=lambda wrapped: [on_step])
    finally:
        tracemalloc.stop()
    windows = (held[750] / 500, (held[1250] - held[750]) / 500)
    per_step = min(windows)
    assert per_step < 100, f"{windows[0]:.0f} and {windows[1]:.0f} bytes per step still held"
