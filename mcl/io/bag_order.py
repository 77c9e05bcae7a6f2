"""Checks of a bag's message order while it is read: log time that runs backwards, and messages
read twice (exact copies, counted by [`mcl.io.salvage.Copies`][mcl.io.salvage.Copies]), each said in one line."""

from __future__ import annotations

__all__ = ["TimeOrder", "copies_warning"]


class TimeOrder:
    """Watches the log times (ns) of a bag's messages in the order they are read.

    Attributes:
        n_back: times a message's log time was earlier than that of the message read just before
            it (a chunk written out of order is one step back).
        max_back_s: the largest such step back, seconds.
        first_back_s: when (seconds since ``t0_ns``, the time before the step) time first ran back.
    """

    def __init__(self, t0_ns: int) -> None:
        self.t0_ns = int(t0_ns)
        self._previous: int | None = None
        self.n_back = 0
        self.max_back_s = 0.0
        self.first_back_s = 0.0

    def add(self, t_ns: int) -> None:
        """The next message's log time."""
        if self._previous is not None and t_ns < self._previous:
            if self.n_back == 0:
                self.first_back_s = (self._previous - self.t0_ns) * 1e-9
            self.n_back += 1
            self.max_back_s = max(self.max_back_s, (self._previous - t_ns) * 1e-9)
        self._previous = t_ns

    def warning(self) -> str:
        """One line: how often and how far time ran back, and that the reader sorted by time."""
        times = "once" if self.n_back == 1 else f"{self.n_back} times"
        return (
            f"log time runs backwards {times} in the bag (by up to {self.max_back_s:.3f} s, first "
            f"after {self.first_back_s:.3f} s); each topic's messages are read in time order"
        )


def copies_warning(n: int) -> str:
    """One line for ``n`` messages that were exact copies of earlier ones."""
    return (
        f"{n} messages are exact copies of earlier ones (same topic, log time and bytes, e.g. a "
        "chunk written twice); each was read once"
    )
