"""Watch a drive or a replay live in Foxglove: a Foxglove WebSocket server (the ``foxglove-sdk``
package, extra ``[live]``) that streams the topics of the MCAP recording as they are made.

The messages are the recording's own ([BagRecorder][mcl.io.bag_writer.BagRecorder]): ROS 2 CDR
bytes with their ``ros2msg`` schemas, on the same topics (``/scan``, ``/odom``, ``/tf``,
``/tf_static``, ``/ground_truth``, ``/pf/pose``, ``/pf/particles``, ``/map``), so a Foxglove layout
made for a recording works live too. ``/map`` and ``/tf_static`` are sent once and again to each
client that subscribes later. Nothing is serialized for a topic no client subscribes to.

A viewer cannot slow, stall or change the drive: the server runs in a process of its own
([mcl.io.live_worker][mcl.io.live_worker]), which the drive feeds through a pipe it never waits
on, nor on the server's start (``wait=False``: the messages wait in the pipe meanwhile). When
the pipe is full, a topic's unsent messages are replaced by its newer ones (newest wins, counted
in [LiveServer.n_dropped][mcl.io.live.LiveServer.n_dropped]); the server holds at most
[MAX_CLIENTS][mcl.io.live.MAX_CLIENTS] clients at once and accepts on average
[ACCEPT_RATE][mcl.io.live_worker.ACCEPT_RATE] new ones a second (one more is refused with HTTP
503 after [REFUSE_DELAY_S][mcl.io.live_worker.REFUSE_DELAY_S]), keeps [BACKLOG][mcl.io.live.BACKLOG]
messages per client (the oldest dropped for a slow one) and ends with the drive; if it dies first,
the drive warns in one line and goes on.

Open Foxglove, "Open connection", ``ws://localhost:PORT`` (subprotocol ``foxglove.sdk.v1``).
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
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import mcl.io.live_worker as worker

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["BACKLOG", "DEFAULT_HOST", "LATCHED", "MAX_CLIENTS", "START_WAIT_S", "LiveServer", "parse_live_address"]

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
"""Seconds the server process has to say where it listens."""
START_WAIT_S = 5.0
"""Seconds `close()` waits for a server started without waiting to say where it listens."""


def parse_live_address(text: str | int) -> tuple[str, int]:
    """``"[HOST:]PORT"`` as (host, port); the host defaults to [DEFAULT_HOST][mcl.io.live.DEFAULT_HOST].

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
        wait: wait for the server's start here (False: return at once, so that the start, about
            0.3 s of a process importing foxglove-sdk, runs while the drive does; messages go
            into the pipe meanwhile, and [wait_ready][mcl.io.live.LiveServer.wait_ready] or
            [port][mcl.io.live.LiveServer.port] waits for it).

    Raises:
        ValueError: a bad address, or ``max_clients`` / ``backlog`` below 1.
        RuntimeError: foxglove-sdk is not installed, or (with ``wait``) the port cannot be
            bound.
    """

    def __init__(
        self,
        address: str | int,
        types: dict[str, str],
        typestore: Typestore,
        name: str = "racecar-sim",
        max_clients: int = MAX_CLIENTS,
        backlog: int = BACKLOG,
        wait: bool = True,
    ) -> None:
        self.host, port = parse_live_address(address)
        self.requested_port = port
        """The port asked for (0: any free one; [port][mcl.io.live.LiveServer.port] is the bound one)."""
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
        self._pending: dict[int, list[bytes]] = {}  # topic -> one moment's unsent frames
        self._batch: list[tuple[int, bytes]] = []  # this moment's frames (publish flush=False)
        self._partial = memoryview(b"")
        self._dead: str | None = None
        self.n_published = 0
        """Messages handed to the server (each one whole)."""
        self.n_dropped = 0
        """Messages replaced by a newer one of their topic before the server could take them."""
        with tempfile.TemporaryFile() as status_file:  # the map keeps its own handle
            status_file.truncate(worker.STATUS_BYTES)
            self._status = mmap.mmap(status_fd := status_file.fileno(), worker.STATUS_BYTES)
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
        self._port: int | None = None
        self._start_error: str | None = None
        self._answer_lock = threading.Lock()
        try:
            self._proc.stdin.write(worker.HEADER.pack(len(data), worker.CONFIG, 0) + data)
            self._proc.stdin.flush()
        except (OSError, ValueError) as exc:
            self._start_error = f"the server process did not start ({exc})"
        self._fd = self._proc.stdin.fileno()
        os.set_blocking(self._fd, False)
        with contextlib.suppress(OSError, AttributeError, ImportError):
            import fcntl  # POSIX; F_SETPIPE_SZ on Linux only

            fcntl.fcntl(self._fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        self._waiter: threading.Thread | None = None
        if wait:
            try:
                self.wait_ready()
            except RuntimeError:
                self._stop()
                raise

    def wait_ready(self, timeout: float = START_S) -> int:
        """Wait (at most ``timeout`` seconds) until the server listens; its port. Messages
        published before are in the pipe already: the server takes them when it is up.

        Raises:
            RuntimeError: the port cannot be bound, the process did not start, or it has not
                said where it listens within ``timeout``.
        """
        with self._answer_lock:
            if self._port is None and self._start_error is None:
                answer = self._answer(timeout)
                if answer is None:
                    raise RuntimeError(f"the live view's server is not up after {timeout:g} s")
                if "port" in answer:
                    self._port = int(answer["port"])
                else:
                    self._start_error = str(answer.get("error"))
        if self._port is None:
            raise RuntimeError(
                f"cannot serve the live view on {self.host}:{self.requested_port}: "
                f"{self._start_error}"
            )
        return self._port

    def when_ready(self, ready: Callable[[str], None], failed: Callable[[str], None]) -> None:
        """Call ``ready(url)`` once the server listens, or ``failed(reason)`` if it cannot start
        (then the drive goes on without it), from a thread of its own: the caller does not wait
        for the start."""

        def wait() -> None:
            try:
                self.wait_ready()
            except RuntimeError as exc:
                if self._proc is not None:  # not closed meanwhile
                    self._dead = str(exc)
                    failed(str(exc))
                return
            if self._proc is not None:
                ready(self.url)

        self._waiter = threading.Thread(target=wait, daemon=True, name="live view start")
        self._waiter.start()

    def _answer(self, timeout: float) -> dict | None:
        """The server process's one line: ``{"port": N}`` or ``{"error": "..."}``; None when it
        has said nothing within ``timeout`` seconds (it may still)."""
        proc = self._proc
        if proc is None:
            return {"error": "the server was closed before it started"}
        out = proc.stdout
        try:
            ready, _, _ = select.select([out], [], [], timeout)
            if not ready:
                return None
            line = out.readline()
            out.close()
        except (OSError, ValueError):  # closed meanwhile (close() from another thread)
            line = b""
        try:
            return json.loads(line)
        except ValueError:
            return {"error": f"the server process did not start (exit code {proc.poll()})"}

    @property
    def port(self) -> int:
        """The port the server listens on (waits for its start: [wait_ready][mcl.io.live.LiveServer.wait_ready])."""
        return self._port if self._port is not None else self.wait_ready()

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
        """Messages waiting for room in the pipe (one moment's per topic, plus those queued since
        the last flush and one half-written write)."""
        waiting = sum(len(frames) for frames in self._pending.values()) + len(self._batch)
        return waiting + (1 if self._partial else 0)

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
        never waiting: when the pipe is full, the unsent messages of the same topic are replaced.
        With ``flush=False`` it is only queued with the others of this moment (several of one
        topic, e.g. two ``/tf``, all go): `flush()` hands them over in one write."""
        if self._dead is not None or self._proc is None:
            return
        frame = worker.HEADER.pack(len(data), self._index[topic], int(log_time_ns)) + data
        self._batch.append((self._index[topic], frame))
        if flush:
            self.flush()

    def flush(self) -> None:
        """Write what the pipe takes now, the queued messages in one write; keep the rest for the
        next call (never waits). A topic's messages still unsent from an earlier call are
        replaced by this call's (newest wins, counted in ``n_dropped``)."""
        if self._dead is not None or self._proc is None:
            return
        if self._batch:
            fresh: dict[int, list[bytes]] = {}
            for i, frame in self._batch:
                fresh.setdefault(i, []).append(frame)
            self._batch.clear()
            for i, frames in fresh.items():
                self.n_dropped += len(self._pending.pop(i, ()))
                self._pending[i] = frames
        try:
            while True:
                if not self._partial:
                    if not self._pending:
                        return
                    frames = [f for group in self._pending.values() for f in group]
                    self.n_published += len(frames)
                    self._partial = memoryview(b"".join(frames))
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
        if code is None:  # the pipe broke as it died: give the system a moment to reap it
            with contextlib.suppress(subprocess.TimeoutExpired):
                code = self._proc.wait(timeout=0.5)
        reason = self._status[worker.REASON_AT : worker.REASON_AT + 1024].split(b"\0", 1)[0]
        why = f"exit code {code}" if code is not None else type(exc).__name__
        if reason:
            why += f": {reason.decode('utf-8', 'replace')}"
        self._dead = why
        self._pending.clear()
        self._batch.clear()
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
        """Stop the server process (clients are disconnected); unsent messages are dropped. A
        server still starting ([when_ready][mcl.io.live.LiveServer.when_ready]) gets up to
        [START_WAIT_S][mcl.io.live.START_WAIT_S] to say where it listens first."""
        if getattr(self, "_proc", None) is None:
            return
        waiter = getattr(self, "_waiter", None)
        if waiter is not None and waiter is not threading.current_thread():
            waiter.join(START_WAIT_S)  # a run shorter than the start still hears the address
        if self._dead is None and hasattr(self, "_fd"):
            self.flush()
        self._stop()

    def _stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        atexit.unregister(self.close)
        for pipe in (proc.stdin, proc.stdout):  # the server's input ends: it stops
            with contextlib.suppress(OSError):
                pipe.close()
        try:
            proc.wait(2.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        mapped, self._status = self._status, bytes(self._status)  # the last counts stay readable
        with contextlib.suppress(BufferError):  # a reader mid-read: the collector closes it
            mapped.close()
        if self._waiter is not None and self._waiter is not threading.current_thread():
            self._waiter.join(START_S)

    def __deepcopy__(self, memo: dict) -> LiveServer:
        """The same server: a running process, not a value (a deep copy of its holder shares it)."""
        return self

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
