"""The live view's server process: it owns foxglove-sdk, so that nothing a viewer does can stall the
drive ([LiveServer][mcl.io.live.LiveServer] starts it and feeds it).

Run by path (``python -P live_worker.py STATUS_FD``), it imports only the standard library and
``foxglove``, never ``mcl``. It reads framed messages on its standard input (a pipe the drive
writes without ever blocking), logs them on foxglove-sdk channels, and says where it listens in
one JSON line on its standard output. Clients do not reach foxglove-sdk directly: a gate on the
public address accepts at most ``max_clients`` at once and on average
[ACCEPT_RATE][mcl.io.live_worker.ACCEPT_RATE] new ones a second (one more gets ``HTTP 503``
after [REFUSE_DELAY_S][mcl.io.live_worker.REFUSE_DELAY_S] and is closed), closes a client that sends no handshake within [HANDSHAKE_S][mcl.io.live_worker.HANDSHAKE_S] or
reads nothing for [STALL_S][mcl.io.live_worker.STALL_S], and forwards the rest to the SDK's server
on a private loopback port through bounded buffers (the SDK then drops the oldest messages of a
slow client, ``message_backlog_size`` of them kept).

State goes back through ``STATUS_FD``, a shared file mapped by both processes (layout:
[STATUS][mcl.io.live_worker.STATUS], then one subscriber flag byte per topic at
[FLAGS_AT][mcl.io.live_worker.FLAGS_AT], then a reason text at
[REASON_AT][mcl.io.live_worker.REASON_AT]). The process ends when its input ends (the drive
closed it or died), when its parent is gone, or with the parent's death signal (Linux).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import mmap
import os
import queue
import select
import signal
import struct
import sys
import threading
import time
from typing import NoReturn

HEADER = struct.Struct("<IHQ")
"""A message's frame header: payload bytes (u32), topic index (u16), log time in ns (u64)."""
CONFIG = 0xFFFF
"""The topic index of the first frame, whose payload is the JSON configuration."""
STATUS = struct.Struct("<8q")
"""Counters at the start of the status file: port, state (1 serving, 2 failed, 3 stopped),
clients now, most clients at once, clients refused, clients accepted, clients closed for
stalling, messages logged."""
FLAGS_AT = 128
"""Offset of the per-topic subscriber flags (1: some client subscribes) in the status file."""
REASON_AT = 2048
"""Offset of the last failure's text (UTF-8, NUL-padded, at most 1 KiB) in the status file."""
STATUS_BYTES = 4096
"""Size of the status file."""
HANDSHAKE_S = 10.0
"""Seconds a new connection has to send its first bytes before the gate closes it."""
STALL_S = 10.0
"""Seconds a client may go without reading before the gate closes it."""
ACCEPT_RATE = 5.0
"""New clients the gate accepts per second on average (bursts of up to ``max_clients``); one more
is refused like a client over the bound, so that a client connecting in a loop cannot keep the
server (and the machine the drive runs on) busy."""
REFUSE_DELAY_S = 1.0
"""Seconds the gate holds a refused connection before its ``HTTP 503`` (at most
[MAX_HELD][mcl.io.live_worker.MAX_HELD] at once; more are refused at once): a client that connects
in a loop then tries about once a second, not hundreds of times, and costs the machine next to
nothing."""
MAX_HELD = 64
"""Refused connections the gate holds at once (each an open socket)."""
STOP_S = 0.5
"""Seconds the process gives foxglove-sdk's server to close its clients when its input ends (a
client that reads nothing cannot hold up the drive's end)."""
CHUNK = 65536
"""Bytes forwarded at a time; with asyncio's write limits, what the gate buffers per client."""
_REFUSAL = (
    "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nConnection: close\r\n"
    "Content-Length: {n}\r\n\r\n{text}"
)


class Status:
    """The status file as this process writes it."""

    def __init__(self, fd: int) -> None:
        self.map = mmap.mmap(fd, STATUS_BYTES)
        self.values = [0] * 8

    def set(self, index: int, value: int) -> None:
        self.values[index] = value
        self.map[index * 8 : index * 8 + 8] = struct.pack("<q", value)

    def add(self, index: int, delta: int = 1) -> None:
        self.set(index, self.values[index] + delta)

    def flag(self, topic: int, on: bool) -> None:
        self.map[FLAGS_AT + topic] = 1 if on else 0

    def reason(self, text: str) -> None:
        data = text.encode("utf-8", "replace")[:1023]
        self.map[REASON_AT : REASON_AT + 1024] = data + b"\0" * (1024 - len(data))


PORT, STATE, CLIENTS, MOST, REFUSED, ACCEPTED, STALLED, LOGGED = range(8)


class Gate:
    """Accepts at most ``max_clients`` at once on the public address and forwards each to the
    SDK's server on ``upstream`` (a loopback port), through bounded buffers."""

    def __init__(self, status: Status, upstream: int, max_clients: int) -> None:
        self.status, self.upstream, self.max_clients = status, upstream, max_clients
        self.active = 0
        self.held = 0
        self.tokens, self.refilled = float(max_clients), time.monotonic()
        self.loop = asyncio.new_event_loop()

    def take_token(self) -> bool:
        """Whether a new client may come in now (a token bucket of ``max_clients`` tokens,
        refilled at [ACCEPT_RATE][mcl.io.live_worker.ACCEPT_RATE] a second)."""
        now = time.monotonic()
        self.tokens = min(self.max_clients, self.tokens + (now - self.refilled) * ACCEPT_RATE)
        self.refilled = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True

    def start(self, host: str, port: int) -> int:
        """Bind ``host:port`` and serve in a daemon thread; the bound port."""
        server = self.loop.run_until_complete(
            asyncio.start_server(self.handle, host, port, backlog=128, limit=CHUNK)
        )
        threading.Thread(target=self.loop.run_forever, daemon=True, name="gate").start()
        return int(server.sockets[0].getsockname()[1])

    async def handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        status = self.status
        if self.active >= self.max_clients or not self.take_token():
            status.add(REFUSED)
            if self.held < MAX_HELD:  # the tarpit (REFUSE_DELAY_S)
                self.held += 1
                try:
                    await asyncio.sleep(REFUSE_DELAY_S)
                finally:
                    self.held -= 1
            text = (
                f"racecar-sim live view: too many clients (at most {self.max_clients} at once, "
                f"{ACCEPT_RATE:g} new ones a second)\n"
            )
            writer.write(_REFUSAL.format(n=len(text), text=text).encode())
            with contextlib.suppress(Exception):
                await asyncio.wait_for(writer.drain(), 1.0)
            writer.transport.abort()
            return
        self.active += 1
        status.add(ACCEPTED)
        status.set(CLIENTS, self.active)
        status.set(MOST, max(status.values[MOST], self.active))
        up_writer = None
        try:
            first = await asyncio.wait_for(reader.read(CHUNK), HANDSHAKE_S)
            if not first:
                return
            up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.upstream)
            up_writer.write(first)
            pumps = {
                asyncio.ensure_future(self.pump(reader, up_writer)),
                asyncio.ensure_future(self.pump(up_reader, writer, stalls=True)),
            }
            _, pending = await asyncio.wait(pumps, return_when=asyncio.FIRST_COMPLETED)
            for task in pending:
                task.cancel()
            await asyncio.gather(*pending, return_exceptions=True)
        except (OSError, TimeoutError, asyncio.IncompleteReadError):
            pass
        finally:
            for w in (writer, up_writer):
                if w is not None:
                    w.transport.abort()
            self.active -= 1
            status.set(CLIENTS, self.active)

    async def pump(
        self, src: asyncio.StreamReader, dst: asyncio.StreamWriter, stalls: bool = False
    ) -> None:
        """Copy ``src`` to ``dst`` until either ends; a ``dst`` that drains nothing for
        [STALL_S][mcl.io.live_worker.STALL_S] ends it (counted when ``stalls``)."""
        try:
            while data := await src.read(CHUNK):
                dst.write(data)
                try:
                    await asyncio.wait_for(dst.drain(), STALL_S)
                except TimeoutError:
                    if stalls:
                        self.status.add(STALLED)
                    return
        except OSError:
            return


def _config(fd: int) -> tuple[dict, bytearray]:
    """The JSON configuration frame read from ``fd``, and what was read after it."""
    buffer = bytearray()
    while len(buffer) < HEADER.size or len(buffer) < HEADER.size + HEADER.unpack_from(buffer)[0]:
        chunk = os.read(fd, CHUNK)
        if not chunk:
            raise SystemExit(0)
        buffer += chunk
    n, topic, _ = HEADER.unpack_from(buffer)
    if topic != CONFIG:
        raise SystemExit("the first frame is not the configuration")
    config = json.loads(bytes(buffer[HEADER.size : HEADER.size + n]))
    return config, buffer[HEADER.size + n :]


def hard_exit(code: int) -> NoReturn:
    """End this process now with ``code``: the server's own threads (foxglove-sdk's) may never
    stop, so a normal exit could wait on them forever. The process image is replaced by a bare
    interpreter that exits with ``code`` (``execv`` ends every other thread at once, runs no exit
    handler and flushes nothing). The one place the worker leaves this way."""
    os.execv(sys.executable, [sys.executable, "-S", "-c", f"raise SystemExit({int(code)})"])


def _watch_parent(parent: int) -> None:
    """End this process when its parent is gone (also when the main thread is stuck)."""
    while os.getppid() == parent:
        time.sleep(0.5)
    hard_exit(0)


def _death_signal() -> None:
    """Linux: SIGKILL this process when the thread that started it ends."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def serve(status_fd: int) -> None:
    """Read the configuration, start the SDK's server and the gate, then log every framed
    message of standard input until it ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the drive's; it closes our input
    with contextlib.suppress(OSError):  # the lowest priority: a viewer never takes the CPU from
        os.nice(19)  # the drive (not Linux's idle class: on a busy machine it would show nothing)
    status = Status(status_fd)
    config, buffer = _config(0)
    if config.get("death_signal"):
        _death_signal()
    threading.Thread(target=_watch_parent, args=(config["parent"],), daemon=True).start()
    try:
        import foxglove

        context = foxglove.Context()
        channels = []
        for spec in config["topics"]:
            schema = foxglove.Schema(
                name=spec["type"], encoding="ros2msg", data=spec["schema"].encode()
            )
            channels.append(
                foxglove.Channel(
                    spec["topic"], schema=schema, message_encoding="cdr", context=context
                )
            )
        latched = {i for i, spec in enumerate(config["topics"]) if spec["latched"]}
        resend: queue.SimpleQueue[int] = queue.SimpleQueue()
        index = {spec["topic"]: i for i, spec in enumerate(config["topics"])}

        class Resend(foxglove.ServerListener):
            def on_subscribe(self, client, channel) -> None:
                i = index.get(channel.topic)
                if i in latched:
                    resend.put(i)

        server = foxglove.start_server(
            name=config["name"], host="127.0.0.1", port=0, context=context,
            server_listener=Resend(), message_backlog_size=int(config["backlog"]),
        )  # fmt: skip
        gate = Gate(status, int(server.port), int(config["max_clients"]))
        port = gate.start(config["host"], int(config["port"]))
    except Exception as exc:
        status.set(STATE, 2)
        status.reason(f"{type(exc).__name__}: {exc}")
        print(json.dumps({"error": str(exc) or type(exc).__name__}), flush=True)
        hard_exit(1)
    status.set(PORT, port)
    status.set(STATE, 1)
    print(json.dumps({"port": port}), flush=True)
    with contextlib.suppress(OSError):
        sys.stdout.close()
        os.close(1)
    last: dict[int, tuple[bytes, int]] = {}
    polled = 0.0
    while True:
        ready, _, _ = select.select([0], [], [], 0.1)
        if ready:
            chunk = os.read(0, 1 << 20)
            if not chunk:
                break
            buffer += chunk
        at = logged = 0
        while len(buffer) - at >= HEADER.size:
            n, topic, ns = HEADER.unpack_from(buffer, at)
            if len(buffer) - at - HEADER.size < n:
                break
            data = bytes(buffer[at + HEADER.size : at + HEADER.size + n])
            at += HEADER.size + n
            if topic in latched:
                last[topic] = (data, ns)
            if topic < len(channels):
                channels[topic].log(data, log_time=ns)
                logged += 1
        if at:
            del buffer[:at]
            status.add(LOGGED, logged)
        while not resend.empty():
            topic = resend.get()
            if topic in last:
                channels[topic].log(last[topic][0], log_time=last[topic][1])
        now = time.monotonic()
        if now - polled >= 0.1:
            polled = now
            for i, channel in enumerate(channels):
                status.flag(i, channel.has_sinks())
    status.set(STATE, 3)
    stopping = threading.Thread(target=server.stop, daemon=True)
    stopping.start()
    stopping.join(STOP_S)
    hard_exit(0)


if __name__ == "__main__":
    try:
        serve(int(sys.argv[1]))
    except SystemExit:
        raise
    except BaseException as exc:  # one line for the drive's warning, never a traceback
        with contextlib.suppress(Exception):
            Status(int(sys.argv[1])).reason(f"{type(exc).__name__}: {exc}")
        hard_exit(1)
