"""The fuzz family ``live``: misbehaving Foxglove clients against a short localized drive streamed
by a [DriveRecorder][mcl.io.bag_writer.DriveRecorder] attached as the wrapper's step hook (as
``drive --live`` attaches it).

A case is a seeded schedule of client actions, each due at a step of the drive: ``open`` (clients
that subscribe to a random subset of the channels and read), ``stuck`` (subscribe to everything,
then never read), ``abort`` (reset open clients), ``storm`` (many connections at once, half reset
during the handshake), ``churn`` (connect, subscribe, disconnect, again), ``garbage`` (random
bytes, before or after a handshake), ``half`` (half a handshake, then silence), ``unsubscribe``,
``badjson`` (malformed and out-of-range requests) and ``slow`` (reads a frame now and then).

The drive hands the due actions to a client thread without waiting on it, and must come out
exactly as the same drive without the live view (every estimate, every error). The server must
have held at most [MAX_CLIENTS][mcl.io.live.MAX_CLIENTS] clients, stayed alive, kept its peak
resident memory under [SERVER_RSS_MIB][tests.fuzz.live_cases.SERVER_RSS_MIB] and ended with
the drive.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import random
import threading
import time
from collections import Counter
from typing import Any

import numpy as np

__all__ = ["ACTIONS", "SERVER_RSS_MIB", "live_cases", "run_live"]

ACTIONS = ("open", "stuck", "abort", "storm", "churn", "garbage", "half", "unsubscribe",
           "badjson", "slow")  # fmt: skip
"""What a case's clients do (module doc)."""
SERVER_RSS_MIB = 300.0
"""Peak resident memory the server process may reach in a case (it idles at about 45 MiB)."""
_SMALL = {"map": "corridor", "n_beams": 60}
_REFERENCE: dict[int, list[np.ndarray]] = {}


def live_cases(seed: int, n: int) -> list[dict[str, Any]]:
    """``n`` seeded schedules (module doc)."""
    rng = random.Random(seed)
    cases = []
    for _ in range(n):
        steps = rng.choice([40, 80, 120])
        actions = [
            [rng.randrange(steps), rng.choice(ACTIONS), rng.choice([1, 2, 3, 5, 10, 25, 50])]
            for _ in range(rng.randint(1, 6))
        ]
        cases.append({"kind": "live", "steps": steps, "seed": rng.randrange(1 << 30),
                      "actions": sorted(actions)})  # fmt: skip
    return cases


class _Clients:
    """The case's clients, run by an event loop in a thread of their own."""

    def __init__(self, port: int, seed: int) -> None:
        self.port, self.rng = port, random.Random(seed)
        self.pool: list = []
        self.raw: list = []
        self.counts: Counter = Counter()
        self.loop = asyncio.new_event_loop()
        self.tasks: set = set()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def post(self, action: str, count: int) -> None:
        """Start ``action`` (never waits: the drive calls this)."""
        self.loop.call_soon_threadsafe(self._start, action, count)

    def _start(self, action: str, count: int) -> None:
        task = self.loop.create_task(getattr(self, f"_{action}")(count))
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    async def _ws(self, subscribe: str = "some", **kwargs):
        import websockets

        from mcl.bench.hostile_clients import SUBPROTOCOL

        try:
            ws = await websockets.connect(f"ws://127.0.0.1:{self.port}", open_timeout=10,
                                          subprotocols=[SUBPROTOCOL], max_size=None, **kwargs)  # fmt: skip
        except Exception:
            self.counts["refused or failed"] += 1
            return None
        with contextlib.suppress(Exception):
            while True:
                frame = await asyncio.wait_for(ws.recv(), 10)
                if isinstance(frame, str) and json.loads(frame).get("op") == "advertise":
                    channels = json.loads(frame)["channels"]
                    if subscribe == "some":
                        channels = [c for c in channels if self.rng.random() < 0.5]
                    subs = [{"id": i + 1, "channelId": c["id"]} for i, c in enumerate(channels)]
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    break
        return ws

    async def _read(self, ws, pause: float = 0.0) -> None:
        with contextlib.suppress(Exception):
            while True:
                await ws.recv()
                if pause:
                    await asyncio.sleep(pause)

    async def _open(self, count: int) -> None:
        for ws in await asyncio.gather(*(self._ws() for _ in range(count))):
            if ws is not None:
                self.pool.append(ws)
                self._spawn(self._read(ws))

    def _spawn(self, coroutine) -> None:
        task = self.loop.create_task(coroutine)
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    async def _slow(self, count: int) -> None:
        for ws in await asyncio.gather(*(self._ws("all", max_queue=1) for _ in range(count))):
            if ws is not None:
                self.pool.append(ws)
                self._spawn(self._read(ws, pause=0.5))

    async def _stuck(self, count: int) -> None:
        for ws in await asyncio.gather(*(self._ws("all", max_queue=1) for _ in range(count))):
            if ws is not None:
                ws.transport.pause_reading()
                self.pool.append(ws)

    async def _abort(self, count: int) -> None:
        for _ in range(min(count, len(self.pool))):
            self.pool.pop(self.rng.randrange(len(self.pool))).transport.abort()

    async def _unsubscribe(self, count: int) -> None:
        for ws in self.pool[:count]:
            with contextlib.suppress(Exception):
                ids = list(range(1, 9))
                await ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": ids}))

    async def _badjson(self, count: int) -> None:
        twice = [{"id": 1, "channelId": 1}, {"id": 1, "channelId": 1}]
        bad = ['{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99999}]}',
               "{not json", '{"op": "unsubscribe", "subscriptionIds": [-1]}', "[]",
               json.dumps({"op": "subscribe", "subscriptions": twice})]  # fmt: skip
        for ws in self.pool[:count]:
            with contextlib.suppress(Exception):
                await ws.send(self.rng.choice(bad))

    async def _storm(self, count: int) -> None:
        from mcl.bench.hostile_clients import storm

        stop = asyncio.Event()
        stop.set()  # open them all, then let them go at once
        await storm(self.port, stop, self.counts, n=count)

    async def _churn(self, count: int) -> None:
        for _ in range(count):
            ws = await self._ws()
            if ws is not None:
                ws.transport.abort()

    async def _raw(self) -> tuple[Any, Any] | None:
        try:
            reader, writer = await asyncio.open_connection("127.0.0.1", self.port)
        except OSError:
            return None
        self.raw.append(writer)
        return reader, writer

    async def _garbage(self, count: int) -> None:
        from mcl.bench.hostile_clients import _HANDSHAKE

        for _ in range(count):
            pair = await self._raw()
            if pair is None:
                continue
            if self.rng.random() < 0.5:
                pair[1].write(_HANDSHAKE.format(port=self.port).encode())
            pair[1].write(self.rng.randbytes(self.rng.choice([1, 100, 5000])))

    async def _half(self, count: int) -> None:
        from mcl.bench.hostile_clients import _HANDSHAKE

        for _ in range(count):
            pair = await self._raw()
            if pair is not None:
                pair[1].write(_HANDSHAKE.format(port=self.port)[: self.rng.randrange(80)].encode())

    def close(self) -> None:
        """Cancel everything and close every connection."""

        async def finish() -> None:
            for task in list(self.tasks):
                task.cancel()
            for ws in self.pool:
                ws.transport.abort()
            for writer in self.raw:
                writer.transport.abort()

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(finish(), self.loop).result(30)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(30)
        if not self.thread.is_alive():
            self.loop.close()


def _drive(steps: int, live: Any = None, clients: _Clients | None = None, case=None) -> list:
    """The drive's estimates and errors, step by step; with ``clients``, the case's actions are
    posted at their steps (the server ``live`` is the caller's to close)."""
    from mcl.cli.live_options import Pacer
    from mcl.wrappers.single import LocalizationWrapper
    from racecar_sim.env import RacecarEnv

    env = LocalizationWrapper(RacecarEnv(**_SMALL), {"filter": {"n_particles": 100}})
    recorder = None
    if live is not None:  # the live view as drive --live attaches it: a step hook
        from mcl.io.bag_writer import DriveRecorder

        recorder = DriveRecorder(None, env, live=live)
        env.add_step_hook(recorder)
    pace = Pacer(2.0 if live is not None else 0.0)
    due = list(case["actions"]) if case else []
    obs, info = env.reset(seed=3)
    out = []
    try:
        for k in range(steps):
            while clients is not None and due and due[0][0] <= k:
                _, action, count = due.pop(0)
                clients.post(action, count)
            obs, _, terminated, truncated, info = env.step(np.array([0.05, 1.0]))
            loc = info["localization"]
            out.append(np.array([*obs["pose_estimate"], loc["position_error"], loc["n_eff"]]))
            pace(float(info["time"]))
            if terminated or truncated:
                obs, info = env.reset(seed=3)
    finally:
        env.close()
        if recorder is not None:
            recorder.close()
    return out


def run_live(case: dict[str, Any], tmp) -> dict[str, Any] | None:
    """One case (module doc); None when everything held."""
    from mcl.io.bag_writer import start_live
    from mcl.io.live import MAX_CLIENTS

    steps = case["steps"]
    if steps not in _REFERENCE:
        _REFERENCE[steps] = _drive(steps)
    server = start_live(0)
    clients = _Clients(server.port, case["seed"])
    try:
        watched = _drive(steps, server, clients, case)
        stats = server.stats()
        pid = server.worker_pid
        with open(f"/proc/{pid}/status") as f:
            peak = int(f.read().split("VmHWM:")[1].split()[0]) / 1024
        alive = server.alive and pid is not None and _running(pid)
    finally:
        clients.close()
        server.close()
    if not alive:
        raise RuntimeError(f"the live server died during the case ({server.summary()})")
    if peak > SERVER_RSS_MIB:
        return {"outcome": "memory", "message": f"the server reached {peak:.0f} MiB"}
    assert stats["most_clients"] <= MAX_CLIENTS, f"{stats['most_clients']} clients at once"
    for k, (a, b) in enumerate(zip(watched, _REFERENCE[steps], strict=True)):
        assert np.array_equal(a, b), f"step {k}: {a} with the live view, {b} without"
    deadline = time.monotonic() + 30
    while _running(pid):
        assert time.monotonic() < deadline, "the server process outlived the drive's close"
        time.sleep(0.05)
    return {"outcome": "ok", "server_peak_mib": peak, **{f"server_{k}": v for k, v in stats.items()}}


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()[0] != "Z"
