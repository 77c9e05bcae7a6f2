"""Watch a drive or a replay live in Foxglove: a Foxglove WebSocket server (the ``foxglove-sdk``
package, extra ``[live]``) that streams the topics of the MCAP recording as they are made.

The messages are the recording's own ([BagRecorder][mcl.io.bag_writer.BagRecorder]): ROS 2 CDR
bytes with their ``ros2msg`` schemas, on the same topics (``/scan``, ``/odom``, ``/tf``,
``/tf_static``, ``/ground_truth``, ``/pf/pose``, ``/pf/particles``, ``/map``), so a Foxglove layout
made for a recording works live too. ``/map`` and ``/tf_static`` are sent once and again to each
client that subscribes later. Nothing is serialized for a topic no client subscribes to.

A viewer cannot slow, stall or change the drive: the server runs in a process of its own
([mcl.io.live_worker][mcl.io.live_worker]), which the drive feeds through a pipe it never waits
on. When the pipe is full, a topic's unsent message is replaced by its newer one (newest wins,
counted in [LiveServer.n_dropped][mcl.io.live.LiveServer.n_dropped]); the server holds at most
[MAX_CLIENTS][mcl.io.live.MAX_CLIENTS] clients at once and accepts on average
[ACCEPT_RATE][mcl.io.live_worker.ACCEPT_RATE] new ones a second (one more is refused with HTTP
503), and keeps [BACKLOG][mcl.io.live.BACKLOG] messages per client (the oldest dropped for a
slow one). The server process ends with the drive; if it dies first, the drive warns in one line
and goes on.

Open Foxglove, "Open connection", ``ws://localhost:PORT`` (WebSocket subprotocol
``foxglove.sdk.v1``).
"""

from __future__ import annotations

import atexit
import contextlib
import importlib.util
import json
import mmap
import os
import select
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import mcl.io.live_worker as worker

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["BACKLOG", "DEFAULT_HOST", "LATCHED", "MAX_CLIENTS", "LiveServer", "parse_live_address"]

DEFAULT_HOST = "127.0.0.1"
"""The server binds to this address unless a host is given (only this machine can connect)."""
LATCHED = ("/map", "/tf_static")
"""Topics whose last message every new subscriber receives (they are published once)."""
MAX_CLIENTS = 8
"""Clients the server holds at once; one more gets HTTP 503 and is closed."""
BACKLOG = 128
"""Messages the server keeps per client; a slow client loses the oldest."""
PIPE_BYTES = 1 << 20
"""Bytes of the pipe from the drive to the server (Linux; elsewhere the system's default)."""
START_S = 60.0
"""Seconds the server process has to say where it listens (its start, before the drive)."""


def parse_live_address(text: str | int) -> tuple[str, int]:
    """``"[HOST:]PORT"`` as (host, port); the host defaults to
    [DEFAULT_HOST][mcl.io.live.DEFAULT_HOST].

    Raises:
        ValueError: not ``PORT`` or ``HOST:PORT`` with a port in 0-65535 (0: any free port).
    """
    spec = str(text).strip()
    host, sep, port_text = spec.rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    host = host.strip("[]")  # [::1]:8765
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"expected [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765, got {spec!r}") from None
    if not 0 <= port <= 65535 or (sep and not host):
        raise ValueError(f"expected [HOST:]PORT with a port in 0-65535, got {spec!r}")
    return host, port


class LiveServer:
    """A Foxglove WebSocket server with one channel per recorded topic, in a process of its own
    (module doc); this object is the drive's end, which never blocks.

    Args:
        address: ``"[HOST:]PORT"`` (see [parse_live_address][mcl.io.live.parse_live_address]) or
            a port number.
        types: topic -> ROS 2 message type, e.g. ``{"/scan": "sensor_msgs/msg/LaserScan"}``.
        typestore: the rosbags typestore that serializes the messages (for the schemas).
        name: the server's name shown in Foxglove.
        max_clients: clients served at once (default [MAX_CLIENTS][mcl.io.live.MAX_CLIENTS]).
        backlog: messages kept per client (default [BACKLOG][mcl.io.live.BACKLOG]).

    Raises:
        ValueError: a bad address, or ``max_clients`` / ``backlog`` below 1.
        RuntimeError: foxglove-sdk is not installed, or the port cannot be bound.
    """

    def __init__(
        self,
        address: str | int,
        types: dict[str, str],
        typestore: Typestore,
        name: str = "racecar-sim",
        max_clients: int = MAX_CLIENTS,
        backlog: int = BACKLOG,
    ) -> None:
        self.host, port = parse_live_address(address)
        if int(max_clients) < 1 or int(backlog) < 1:
            raise ValueError(f"max_clients and backlog must be >= 1, got {max_clients}, {backlog}")
        if importlib.util.find_spec("foxglove") is None:
            raise RuntimeError(
                "the live view needs foxglove-sdk: pip install -e '.[live]' in a checkout, "
                "pip install 'racecar-sim[live]' from PyPI"
            )
        self.max_clients = int(max_clients)
        self.topics = list(types)
        self._index = {topic: i for i, topic in enumerate(self.topics)}
        self._latched = {self._index[t] for t in LATCHED if t in self._index}
        self._pending: dict[int, bytes] = {}
        self._partial = memoryview(b"")
        self._dead: str | None = None
        self.n_published = 0
        """Messages handed to the server (each one whole)."""
        self.n_dropped = 0
        """Messages replaced by a newer one of their topic before the server could take them."""
        self._status_file = tempfile.TemporaryFile()
        self._status_file.truncate(worker.STATUS_BYTES)
        self._status = mmap.mmap(self._status_file.fileno(), worker.STATUS_BYTES)
        status_fd = self._status_file.fileno()
        self._proc = subprocess.Popen(
            [sys.executable, "-P", str(Path(worker.__file__)), str(status_fd)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            pass_fds=(status_fd,), close_fds=True,
        )  # fmt: skip
        atexit.register(self.close)
        config = {
            "name": name, "host": self.host, "port": port, "max_clients": self.max_clients,
            "backlog": int(backlog), "parent": os.getpid(),
            "death_signal": threading.current_thread() is threading.main_thread(),
            "topics": [
                {"topic": t, "type": kind, "latched": t in LATCHED,
                 "schema": typestore.generate_msgdef(kind, ros_version=2)[0]}
                for t, kind in types.items()
            ],
        }  # fmt: skip
        data = json.dumps(config).encode()
        try:
            self._proc.stdin.write(worker.HEADER.pack(len(data), worker.CONFIG, 0) + data)
            self._proc.stdin.flush()
            answer = self._answer()
        except (OSError, ValueError) as exc:
            answer = {"error": f"the server process did not start ({exc})"}
        if "port" not in answer:
            self._stop()
            raise RuntimeError(
                f"cannot serve the live view on {self.host}:{port}: {answer.get('error')}"
            )
        self.port = int(answer["port"])
        self._fd = self._proc.stdin.fileno()
        os.set_blocking(self._fd, False)
        with contextlib.suppress(OSError, AttributeError, ImportError):
            import fcntl  # POSIX; F_SETPIPE_SZ on Linux only

            fcntl.fcntl(self._fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)

    def _answer(self) -> dict:
        """The server process's one line: ``{"port": N}`` or ``{"error": "..."}``."""
        out = self._proc.stdout
        ready, _, _ = select.select([out], [], [], START_S)
        line = out.readline() if ready else b""
        out.close()
        try:
            return json.loads(line)
        except ValueError:
            return {"error": f"the server process did not start (exit code {self._proc.poll()})"}

    @property
    def url(self) -> str:
        """What to type into Foxglove's "Open connection"."""
        host = "localhost" if self.host in ("127.0.0.1", "0.0.0.0", "::", "::1") else self.host
        return f"ws://{host}:{self.port}"

    @property
    def worker_pid(self) -> int | None:
        """The server process's id (None once closed)."""
        return self._proc.pid if self._proc is not None else None

    @property
    def n_pending(self) -> int:
        """Messages waiting for room in the pipe (at most one per topic, plus one half written)."""
        return len(self._pending) + (1 if self._partial else 0)

    @property
    def alive(self) -> bool:
        """Whether the server process still takes messages."""
        return self._dead is None

    def wants(self, topic: str) -> bool:
        """Whether a message on ``topic`` would reach anyone (latched topics always count)."""
        i = self._index.get(topic)
        if i is None or self._dead is not None or self._proc is None:
            return False
        return i in self._latched or self._status[worker.FLAGS_AT + i] != 0

    def publish(self, topic: str, log_time_ns: int, data: bytes, flush: bool = True) -> None:
        """Hand one serialized message on ``topic`` (stamped ``log_time_ns``) to the server,
        never waiting: when the pipe is full, an unsent message of the same topic is replaced.
        With ``flush=False`` it is only queued: `flush()` hands the queue over in one write."""
        if self._dead is not None or self._proc is None:
            return
        i = self._index[topic]
        if self._pending.pop(i, None) is not None:
            self.n_dropped += 1
        self._pending[i] = worker.HEADER.pack(len(data), i, int(log_time_ns)) + bytes(data)
        if flush:
            self.flush()

    def flush(self) -> None:
        """Write what the pipe takes now, the queued messages in one write; keep the rest for the
        next call (never waits)."""
        if self._dead is not None or self._proc is None:
            return
        try:
            while True:
                if not self._partial:
                    if not self._pending:
                        return
                    self.n_published += len(self._pending)
                    self._partial = memoryview(b"".join(self._pending.values()))
                    self._pending.clear()
                n = os.write(self._fd, self._partial)
                self._partial = self._partial[n:]
        except BlockingIOError:
            return
        except OSError as exc:
            self._died(exc)

    def _died(self, exc: BaseException) -> None:
        """The server process is gone: one warning, then the drive goes on without it."""
        code = self._proc.poll()
        reason = self._status[worker.REASON_AT : worker.REASON_AT + 1024].split(b"\0", 1)[0]
        why = f"exit code {code}" if code is not None else type(exc).__name__
        if reason:
            why += f": {reason.decode('utf-8', 'replace')}"
        self._dead = why
        self._pending.clear()
        self._partial = memoryview(b"")
        print(f"warning: the live view's server stopped ({why}); the drive goes on without it",
              file=sys.stderr, flush=True)  # fmt: skip

    def stats(self) -> dict[str, int]:
        """Counts so far: ``published`` and ``dropped`` (this end), and from the server
        ``clients`` (now), ``most_clients`` (at once), ``refused``, ``accepted``, ``stalled``
        (closed for reading nothing) and ``logged`` (messages it sent on)."""
        values = worker.STATUS.unpack_from(self._status, 0)
        return {
            "published": self.n_published, "dropped": self.n_dropped,
            "clients": values[worker.CLIENTS], "most_clients": values[worker.MOST],
            "refused": values[worker.REFUSED], "accepted": values[worker.ACCEPTED],
            "stalled": values[worker.STALLED], "logged": values[worker.LOGGED],
        }  # fmt: skip

    def summary(self) -> str:
        """One line: messages sent and dropped, clients at most at once and refused."""
        s = self.stats()
        text = (
            f"live view: {s['published']} messages to the server, {s['dropped']} dropped "
            f"(the server was behind); at most {s['most_clients']} of {self.max_clients} "
            f"clients at once, {s['refused']} refused, {s['stalled']} closed for not reading"
        )
        return text + (f"; the server stopped ({self._dead})" if self._dead else "")

    def close(self) -> None:
        """Stop the server process (clients are disconnected); unsent messages are dropped."""
        if getattr(self, "_proc", None) is None:
            return
        if self._dead is None and hasattr(self, "_fd"):
            self.flush()
        self._stop()

    def _stop(self) -> None:
        proc, self._proc = self._proc, None
        atexit.unregister(self.close)
        with contextlib.suppress(OSError):
            proc.stdin.close()  # the server's input ends: it stops
        try:
            proc.wait(2.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def __deepcopy__(self, memo: dict) -> LiveServer:
        """The same server: it is a running process, not a value (a deep copy of whatever holds
        it shares it)."""
        return self

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
