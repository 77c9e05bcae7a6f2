"""Numba's first compile, as the commands tell the user about it: whether the on-disk kernel cache
is warm (:func:`kernels_cached`), a notice before a cold start (:func:`compile_notice`) and the
wall-clock seconds the compiles took, measured (:func:`compile_report`)."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any, TextIO

__all__ = ["COMPILE_SECONDS", "compile_notice", "compile_report", "kernel_modules", "kernels_cached"]


COMPILE_SECONDS = (20, 50)
"""Seconds of wall time numba took to compile the kernels of one drive on first runs on 2-core
machines (20 s on a calm one, 35 s on a fresh one, up to ~50 s when other work shares the cores);
the commands measure and print their own (:func:`compile_report`)."""


class _CompileClock:
    """Wall-clock seconds this process spends in numba compiles (``numba:compile`` events; a
    kernel loaded from the on-disk cache is not one), from :meth:`start` on."""

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
_CACHED_KERNEL = re.compile(r"^\s*@\S*njit\([^)]*cache=True", re.MULTILINE)


def kernel_modules() -> list[str]:
    """Modules of racecar_sim and mcl holding numba kernels compiled with ``cache=True`` (found by
    reading the source, without importing every module)."""
    import mcl
    import racecar_sim

    names = []
    for package in (racecar_sim, mcl):
        root = Path(package.__file__).resolve().parent
        for path in sorted(root.rglob("*.py")):
            text = path.read_text(encoding="utf-8", errors="replace")
            if _CACHED_KERNEL.search(text):
                parts = path.relative_to(root.parent).with_suffix("").parts
                names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def kernels_cached() -> bool:
    """Whether numba's on-disk cache (``cache=True``) already holds most of the compiled kernels.

    A module counts as compiled when one of its kernels has a cache index that matches the source
    (numba's own check of the source file's time stamp). The cache counts as warm when at least
    half of :func:`kernel_modules` are compiled: a fresh checkout or install has none, a run
    compiles those it uses (not every module's kernels run in every command), and a module edited
    since then recompiles in a few seconds. Any surprise counts as cold.
    """
    import importlib

    try:
        from numba.core.registry import CPUDispatcher

        names = kernel_modules()
        compiled = 0
        for name in names:
            module = importlib.import_module(name)
            kernels = [
                v
                for v in vars(module).values()
                if isinstance(v, CPUDispatcher)
                and v.__module__ == name
                and v.targetoptions.get("inline") != "always"
            ]
            compiled += any(k._cache._cache_file._load_index() for k in kernels)
        return bool(names) and 2 * compiled >= len(names)
    except Exception:
        return False


def compile_notice(stream: TextIO | None = None) -> bool:
    """Say so when the numba kernels have to be compiled first, and start measuring how long the
    compiles take (:func:`compile_report` prints it); returns whether it said so."""
    if kernels_cached():
        return False
    low, high = COMPILE_SECONDS
    print(
        f"compiling numba kernels (first run only; {low}-{high} s of wall time on a 2-core "
        "machine, measured and printed at the end)...",
        file=stream if stream is not None else sys.stderr,
        flush=True,
    )
    _COMPILE_CLOCK.start()
    return True


def compile_report(stream: TextIO | None = None) -> float:
    """After :func:`compile_notice` said it: print the wall-clock seconds this process spent
    compiling numba kernels (not loading them from the cache) and stop measuring; returns them
    (0, and nothing printed, when there was no notice or nothing was compiled here)."""
    seconds = _COMPILE_CLOCK.stop()
    if seconds > 0:
        print(
            f"numba compiled its kernels in {seconds:.1f} s of this run (wall clock); they are "
            "cached on disk now, later runs load them",
            file=stream if stream is not None else sys.stderr,
            flush=True,
        )
    return seconds
