"""Soak: does a long headless drive stay in flat memory?

Drives the main job (``racecar-sim drive``: the wall follower on the default bundled map, MCL with
the default particle count, no video, no progress bar) for ``--minutes`` of simulated time in one
run. At each mark (default 10, 60 and 120 simulated minutes) it prints:

* the drive loop's resident memory: peak so far (``ru_maxrss``), current, and current after
  handing the allocator's free pages back (glibc's ``malloc_trim``);
* what the end of a drive of that length adds: ``drive`` then reads the whole error log back,
  computes its statistics and plots it. That is done in a child process on the log as it stands,
  which prints the resident memory the read, the statistics and the plot added there; so the marks'
  own reads leave nothing in the drive's process, and the loop's figures are the loop's alone.

A drive of that length peaks at about the loop's peak plus that addition. Flat memory means the
loop's figures stay level from mark to mark, and the addition grows by the error log's own
arrays (12 float64 columns, 96 bytes per row) and little else.

    .venv/bin/python scripts/bench_soak.py [--minutes 120] [--marks 10,60,120] [--quick]

The drive is the same for the same seed; wall time depends on the machine (about 3 ms per step
on a calm core). It is a benchmark, not a test: the test of the reader's memory per row is in
``tests/experiments/test_memory.py``.
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcl.experiments.runs import RunSpec, run_one
from mcl.filter.params import DEFAULT_PARTICLES
from racecar_sim.maps import DEFAULT_MAP

_MIB = 2.0**20


def peak_rss_mib() -> float:
    """Peak resident memory of this process so far, MiB (``ru_maxrss``: KiB on Linux, bytes on
    macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / _MIB if sys.platform == "darwin" else peak / 1024.0


def current_rss_mib() -> float:
    """Current resident memory, MiB (``/proc/self/statm``; NaN where there is none)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as f:
            pages = int(f.read().split()[1])
    except (OSError, IndexError, ValueError):
        return float("nan")
    return pages * resource.getpagesize() / _MIB


def trimmed_rss_mib() -> float:
    """Current resident memory, MiB, after glibc's ``malloc_trim(0)`` has returned the free heap
    pages to the system (just the current RSS where glibc is not the allocator)."""
    name = ctypes.util.find_library("c")
    if name and sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(name).malloc_trim(0)
        except (OSError, AttributeError):
            pass
    return current_rss_mib()


_END_OF_RUN = """
import sys
from pathlib import Path
from mcl.wrappers.error_log import read_error_log
from mcl.experiments.metrics import error_stats
from mcl.experiments.plots import plot_error_vs_time

def status_kib(field):
    with open("/proc/self/status", encoding="ascii") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(field + ":"))

with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
    f.write("5")  # the peak (VmHWM) starts again from the current RSS, not from the imports' peak
before = status_kib("VmRSS")
log = read_error_log(Path(sys.argv[1]))
error_stats(log)
plot_error_vs_time(log, Path(sys.argv[2]))
print(len(log), status_kib("VmHWM") - before)
"""


def end_of_run_mib(log_path: Path, plot_path: Path) -> tuple[int, float]:
    """What the end of ``drive`` adds to a process's peak resident memory, MiB: reading the error
    log back, its statistics and its plot, measured in a child process (Linux: the peak ``VmHWM``
    reset to the current RSS after the imports, through ``/proc/self/clear_refs``); returns the
    rows read and the MiB added (NaN where ``/proc`` does not allow it)."""
    done = subprocess.run(
        [sys.executable, "-c", _END_OF_RUN, str(log_path), str(plot_path)],
        capture_output=True, text=True,
    )  # fmt: skip
    if done.returncode != 0:
        return -1, float("nan")
    rows, kib = done.stdout.split()[-2:]
    return int(rows), int(kib) / 1024.0


def _marks(text: str) -> tuple[float, ...]:
    try:
        values = tuple(sorted(float(v) for v in text.split(",") if v.strip()))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated minutes, got {text!r}"
        ) from None
    if not values or values[0] <= 0:
        raise argparse.ArgumentTypeError(f"every mark must be > 0 minutes, got {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default=DEFAULT_MAP, help="bundled map name or map YAML")
    parser.add_argument(
        "--minutes", type=float, default=120.0, help="simulated minutes of the drive"
    )
    parser.add_argument(
        "--marks",
        type=_marks,
        default=(10.0, 60.0, 120.0),
        help="simulated minutes at which the peak memory is printed, comma-separated",
    )
    parser.add_argument("--particles", type=int, default=DEFAULT_PARTICLES)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--quick", action="store_true", help="a 3-minute drive with marks at 1, 2 and 3 minutes"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.minutes, args.marks = 3.0, (1.0, 2.0, 3.0)
    if args.minutes <= 0 or args.particles < 1:
        parser.error("--minutes must be > 0 and --particles >= 1")
    marks = [m for m in args.marks if m <= args.minutes]
    if not marks:
        parser.error(f"--marks: none is within the drive's {args.minutes:g} minutes")
    spec = RunSpec(
        map=str(args.map),
        seed=args.seed,
        duration=60.0 * args.minutes,
        n_particles=args.particles,
        series="soak",
    )
    mark_steps = {round(60.0 * m / spec.dt): m for m in marks}
    print(
        f"soak: {args.minutes:g} simulated minutes ({spec.n_steps} steps of {spec.dt:g} s) on "
        f"{Path(spec.map).stem}, wall follower, {spec.n_particles} particles, no video; "
        f"marks at {', '.join(f'{m:g}' for m in marks)} min",
        flush=True,
    )
    rows: list[tuple[float, int, float, float, float, float]] = []  # min, step, MiB x3, s
    with tempfile.TemporaryDirectory(prefix="racecar-soak-") as tmp:
        log_path = Path(tmp) / "error_log.csv"
        t0 = time.perf_counter()
        count = [0]

        def on_step(record: object) -> None:
            count[0] += 1
            minutes = mark_steps.get(count[0])
            if minutes is None:
                return
            row = (minutes, count[0], peak_rss_mib(), current_rss_mib(), trimmed_rss_mib(),
                   time.perf_counter() - t0)  # fmt: skip
            n_rows, added = end_of_run_mib(log_path, Path(tmp) / "error.png")
            rows.append(row)
            print(
                f"  {minutes:6g} min ({count[0]:7d} steps): the loop's peak RSS {row[2]:7.1f} MiB, "
                f"current {row[3]:7.1f} MiB, trimmed {row[4]:7.1f} MiB; reading back its "
                f"{n_rows} rows adds {added:5.1f} MiB; wall {row[5]:7.0f} s",
                flush=True,
            )

        run_one(spec, log_path, step_hooks=lambda wrapped: [on_step])
    if len(rows) >= 2:
        first, last = rows[0], rows[-1]
        steps = last[1] - first[1]
        for name, k in (("peak", 2), ("current", 3), ("trimmed", 4)):
            grown = last[k] - first[k]
            print(
                f"the loop's {name} RSS from {first[0]:g} to {last[0]:g} min: {grown:+.1f} MiB "
                f"over {steps} steps ({1024.0**2 * grown / steps:.0f} bytes per step)"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
