"""Numba's first compile, as the commands tell the user about it: a notice when the first kernel
actually compiles ([`compile_notice`][mcl.cli.compile_notice.compile_notice]) and the wall-clock
seconds the compiles took, measured ([`compile_report`][mcl.cli.compile_notice.compile_report]). A
run whose kernels all come from numba's on-disk cache says nothing."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any, TextIO

from racecar_sim.compile_log import on_first_compile

__all__ = ["COMPILE_SECONDS", "compile_notice", "compile_report"]


COMPILE_SECONDS = (20, 50)
"""Seconds of wall time numba took to compile the kernels of one drive on first runs on 2-core
machines (20 s on a calm one, 35 s on a fresh one, up to ~50 s when other work shares the cores);
the commands measure and print their own
([`compile_report`][mcl.cli.compile_notice.compile_report])."""


class _CompileClock:
    """Wall-clock seconds this process spends in numba compiles (``numba:compile`` events; a
    kernel loaded from the on-disk cache is not one), from ``start`` on."""

    def __init__(self) -> None:
        self._listener: Any = None

    def start(self) -> None:
        from numba.core import event

        if self._listener is None:
            self._listener = event.TimingListener()
            event.register("numba:compile", self._listener)

    def stop(self) -> float:
        """Stop listening; the seconds measured (0 when nothing was compiled here)."""
        from numba.core import event

        listener, self._listener = self._listener, None
        if listener is None:
            return 0.0
        event.unregister("numba:compile", listener)
        return float(listener.duration) if listener.done else 0.0


_COMPILE_CLOCK = _CompileClock()
_stop_notice: list[Callable[[], None]] = []  # the notice's listener while it listens


def compile_notice(stream: TextIO | None = None) -> None:
    """From now on, say so on ``stream`` (default stderr) when numba starts compiling the first
    kernel of ours, and measure the compiles
    ([`compile_report`][mcl.cli.compile_notice.compile_report] prints the seconds).

    Nothing is said when every kernel comes from numba's on-disk cache: the notice is numba's own
    ``numba:compile`` event ([on_first_compile][racecar_sim.compile_log.on_first_compile]), which
    fires only on a cache miss, not a guess from the cache's files made before the run.
    """
    low, high = COMPILE_SECONDS

    def say(name: str) -> None:
        print(
            f"compiling numba kernels ({name} first; the first run after an install or an edit: "
            f"{low}-{high} s of wall time on a 2-core machine, measured and printed at the end)...",
            file=stream if stream is not None else sys.stderr,
            flush=True,
        )

    for stop in _stop_notice:
        stop()
    _stop_notice[:] = [on_first_compile(say)]
    _COMPILE_CLOCK.start()


def compile_report(stream: TextIO | None = None) -> float:
    """Stop listening; print the wall-clock seconds this process spent compiling numba kernels
    (not loading them from the cache) since
    [`compile_notice`][mcl.cli.compile_notice.compile_notice], and return them (0, and nothing
    printed, when nothing was compiled)."""
    for stop in _stop_notice:
        stop()
    _stop_notice.clear()
    seconds = _COMPILE_CLOCK.stop()
    if seconds > 0:
        print(
            f"numba compiled its kernels in {seconds:.1f} s of this run (wall clock); they are "
            "cached on disk now, later runs load them",
            file=stream if stream is not None else sys.stderr,
            flush=True,
        )
    return seconds
