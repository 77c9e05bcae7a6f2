"""Tell the user when numba compiles one of our kernels: the Python API's notice of a cold start.

numba compiles a kernel on its first call and keeps it in an on-disk cache (``cache=True``), so the
first run after an install, a checkout or an edit spends 20-50 s of wall time compiling on a 2-core
machine and later runs load the kernels in well under a second. Nothing is printed by the library:
at the first compile of a kernel of ``racecar_sim`` or ``mcl`` in a process it logs one INFO
message on the ``racecar_sim`` logger ([`LOGGER`][racecar_sim.compile_log.LOGGER]);
``logging.basicConfig(level=logging.INFO)`` shows it. A kernel loaded from the cache is not a
compile (numba fires its ``numba:compile`` event only on a cache miss), so a warm run logs nothing.

[`on_first_compile`][racecar_sim.compile_log.on_first_compile] is the hook under it, which the
``racecar-sim`` commands use for their own notice on stderr.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

__all__ = ["LOGGER", "OUR_PACKAGES", "install", "on_first_compile"]

LOGGER = logging.getLogger("racecar_sim")
"""The package's logger (the compile notice is its INFO message)."""

OUR_PACKAGES = ("racecar_sim", "mcl")
"""Top-level packages whose kernels count as ours."""

_installed: list[Any] = []  # the library's own listener, once per process


def _kernel_name(event: Any) -> str | None:
    """``module.function`` of the kernel a ``numba:compile`` event compiles, or None when it is not
    one of ours (numba's own implementations, a user's kernel)."""
    dispatcher = (event.data or {}).get("dispatcher")
    func = getattr(dispatcher, "py_func", None)
    module = getattr(func, "__module__", "") or ""
    if module.split(".", 1)[0] not in OUR_PACKAGES:
        return None
    return f"{module}.{getattr(func, '__qualname__', '?')}"


def on_first_compile(callback: Callable[[str], None]) -> Callable[[], None]:
    """Call ``callback(kernel name)`` once, when numba starts compiling the first kernel of ours
    from now on (never when every kernel comes from the on-disk cache); returns a function that
    stops listening."""
    from numba.core import event

    class _First(event.Listener):
        fired = False

        def on_start(self, ev: Any) -> None:
            if self.fired:
                return
            name = _kernel_name(ev)
            if name is not None:
                self.fired = True
                callback(name)

        def on_end(self, ev: Any) -> None:
            pass

    listener = _First()
    event.register("numba:compile", listener)
    return lambda: event.unregister("numba:compile", listener)


def _log(name: str) -> None:
    LOGGER.info(
        "compiling numba kernels (%s first; 20-50 s of wall time on a 2-core machine on the "
        "first run after an install or an edit; cached on disk for later runs)...",
        name,
    )


def install() -> None:
    """Log the first compile of a kernel of ours in this process (idempotent; called when the
    env modules are imported)."""
    if not _installed:
        _installed.append(on_first_compile(_log))
