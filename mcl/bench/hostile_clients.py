"""Misbehaving Foxglove clients for the live view's safety: they attack a server on 127.0.0.1 while
a drive streams to it (``racecar-sim bench live_hostile``, ``tests/io/test_live_safety.py``, the
fuzz family ``live``). Needs ``websockets`` (extra ``[dev]``).

The kinds ([KINDS][mcl.bench.hostile_clients.KINDS]):

- ``stuck``: subscribes to every channel, then never reads again (its receive buffers fill);
- ``storm``: 50 connections opened at once, half of them aborted (TCP reset) during the handshake,
  the other half kept open;
- ``churn``: connects, subscribes, disconnects, again and again;
- ``slow``: subscribes to everything and reads one frame a second;
- ``silent``: opens a TCP connection and sends nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import struct
import threading
from collections import Counter
from collections.abc import Iterable

__all__ = ["KINDS", "SUBPROTOCOL", "HostileClients", "attack"]

SUBPROTOCOL = "foxglove.sdk.v1"
"""The WebSocket subprotocol foxglove-sdk's server speaks (and the only one it accepts)."""
KINDS = ("stuck", "storm", "churn", "slow", "silent")
"""The misbehaviours (module doc)."""
_HANDSHAKE = (
    "GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
    f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
)


def _url(port: int) -> str:
    return f"ws://127.0.0.1:{port}"


async def _subscribe_all(ws) -> int:
    """Wait for the server's ``advertise`` and subscribe to every channel; the channel count."""
    while True:
        frame = await ws.recv()
        if isinstance(frame, str) and json.loads(frame).get("op") == "advertise":
            channels = json.loads(frame)["channels"]
            subs = [{"id": i + 1, "channelId": c["id"]} for i, c in enumerate(channels)]
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            return len(channels)


async def _connect(port: int, counts: Counter, **kwargs):
    import websockets

    try:
        return await websockets.connect(
            _url(port), subprotocols=[SUBPROTOCOL], open_timeout=10, **kwargs
        )
    except Exception as exc:  # a refusal (HTTP 503) or a closed server
        counts["refused" if "503" in str(exc) else f"failed ({type(exc).__name__})"] += 1
        return None


async def stuck(port: int, stop: asyncio.Event, counts: Counter) -> None:
    """Subscribe to everything, then never read (the library stops reading at one queued frame)."""
    ws = await _connect(port, counts, max_queue=1, max_size=None)
    if ws is None:
        return
    with contextlib.suppress(Exception):
        await asyncio.wait_for(_subscribe_all(ws), 10)
        counts["stuck subscribed"] += 1
    ws.transport.pause_reading()  # nothing more comes off the socket
    await stop.wait()
    ws.transport.abort()


async def slow(port: int, stop: asyncio.Event, counts: Counter) -> None:
    """Subscribe to everything and read one frame a second."""
    ws = await _connect(port, counts, max_queue=1, max_size=None)
    if ws is None:
        return
    with contextlib.suppress(Exception):
        await asyncio.wait_for(_subscribe_all(ws), 10)
        while not stop.is_set():
            await asyncio.wait_for(ws.recv(), 10)
            counts["slow frames"] += 1
            await asyncio.sleep(1.0)
    ws.transport.abort()


async def _raw_open(port: int, abort: bool, counts: Counter, keep: list) -> None:
    """One storm connection: the handshake sent, then a reset (``abort``) or kept open."""
    try:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
    except OSError:
        counts["failed"] += 1
        return
    sock = writer.get_extra_info("socket")
    if abort:
        writer.write(_HANDSHAKE.format(port=port)[:60].encode())  # half a handshake
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        writer.transport.abort()  # RST
        counts["aborted"] += 1
        return
    writer.write(_HANDSHAKE.format(port=port).encode())
    try:
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 15)
    except (OSError, TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
        counts["failed"] += 1
        writer.transport.abort()
        return
    counts["accepted" if b" 101 " in head else "refused" if b" 503 " in head else "failed"] += 1
    keep.append(writer)


async def storm(port: int, stop: asyncio.Event, counts: Counter, n: int = 50) -> None:
    """``n`` connections at once, every second one reset mid-handshake, the others kept."""
    keep: list = []
    await asyncio.gather(*(_raw_open(port, i % 2 == 1, counts, keep) for i in range(n)))
    await stop.wait()
    for writer in keep:
        writer.transport.abort()


async def churn(port: int, stop: asyncio.Event, counts: Counter, pause: float = 0.02) -> None:
    """Connect, subscribe, disconnect, until ``stop``."""
    while not stop.is_set():
        ws = await _connect(port, counts, max_size=None)
        if ws is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(_subscribe_all(ws), 5)
                counts["churned"] += 1
            ws.transport.abort()
        await asyncio.sleep(pause)


async def silent(port: int, stop: asyncio.Event, counts: Counter) -> None:
    """A TCP connection that never says anything."""
    try:
        _, writer = await asyncio.open_connection("127.0.0.1", port)
    except OSError:
        counts["failed"] += 1
        return
    counts["silent"] += 1
    await stop.wait()
    writer.transport.abort()


async def attack(port: int, kinds: Iterable[str], stop: asyncio.Event) -> Counter:
    """Run one client of each of ``kinds`` against ``port`` until ``stop`` is set; what happened
    (``accepted``, ``refused``, ``aborted``, ``churned``, ...)."""
    counts: Counter = Counter()
    runs = {"stuck": stuck, "storm": storm, "churn": churn, "slow": slow, "silent": silent}
    await asyncio.gather(*(runs[k](port, stop, counts) for k in kinds), return_exceptions=True)
    return counts


class HostileClients:
    """[attack][mcl.bench.hostile_clients.attack] in a thread of its own: ``start()``, then
    ``stop()`` returns the counts."""

    def __init__(self, port: int, kinds: Iterable[str]) -> None:
        self.port, self.kinds = port, list(kinds)
        self.counts: Counter = Counter()
        self._loop = asyncio.new_event_loop()
        self._stop = asyncio.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="hostile clients")

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self.counts = self._loop.run_until_complete(attack(self.port, self.kinds, self._stop))
        finally:
            asyncio.set_event_loop(None)
            self._loop.close()

    def start(self) -> HostileClients:
        """Start attacking."""
        self._thread.start()
        return self

    def stop(self, timeout: float = 30.0) -> Counter:
        """Stop every client; the counts."""
        with contextlib.suppress(RuntimeError):  # the loop closed: the attack ended on its own
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout)
        return self.counts
