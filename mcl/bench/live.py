"""Benchmark the live view: what streaming a drive to Foxglove costs in steps per second.

The main job's drive (``basement_loop``, wall follower, MCL with ``--particles``, the env's
defaults) runs ``--steps`` steps three ways, interleaved round by round: without the live view,
with the server running but no client (nothing is serialized), and with a client in another
process subscribed to every topic (every message serialized and sent: the scan at 40 Hz, the
odometry and the truth every step, the estimate, at most 500 particles and the transforms at every
scan). Each round resets with the same seed, so the three drive the same route; reported are the
median rates and the medians of the per-round ratios to the plain drive.

    .venv/bin/python -m mcl.bench.live [--steps 800] [--rounds 5] [--particles 1500]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import time

import gymnasium as gym

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl import DEFAULT_PARTICLES, LocalizationWrapper
from mcl.io import DriveRecorder, start_live
from racecar_sim.drivers import WallFollower


def _client(port: int, ready, stop) -> None:
    """Subscribe to every advertised channel and count the frames until ``stop`` is set."""
    import asyncio

    import websockets

    async def run() -> None:
        async with websockets.connect(
            f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], max_size=None
        ) as ws:
            while not stop.is_set():
                try:
                    frame = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, str) and json.loads(frame).get("op") == "advertise":
                    channels = json.loads(frame)["channels"]
                    subs = [{"id": i + 1, "channelId": c["id"]} for i, c in enumerate(channels)]
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    ready.set()

    asyncio.run(run())


class Timed:
    """Wraps a live recorder (a step hook) to add up the seconds spent streaming."""

    def __init__(self, recorder) -> None:
        self.recorder, self.seconds, self.calls = recorder, 0.0, 0

    def __call__(self, *args) -> None:
        t0 = time.perf_counter()
        self.recorder(*args)
        self.seconds += time.perf_counter() - t0
        self.calls += 1


def drive(env: LocalizationWrapper, steps: int, seed: int) -> float:
    """Steps per second of wall time of ``steps`` steps after a reset with ``seed`` (a live
    view streams through the env's step hook)."""
    obs, _ = env.reset(seed=seed)
    driver = WallFollower.for_env(env)
    t0 = time.perf_counter()
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(driver(obs))
        if terminated or truncated:
            obs, _ = env.reset(seed=seed)
    return steps / (time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=800)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--particles", type=int, default=DEFAULT_PARTICLES)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    config = {"filter": {"n_particles": args.particles}}
    plain = LocalizationWrapper(gym.make("RacecarSim-v0"), config)
    idle = LocalizationWrapper(gym.make("RacecarSim-v0"), config)
    watched = LocalizationWrapper(gym.make("RacecarSim-v0"), config)
    servers = {"live, no client": start_live(0), "live, watched": start_live(0)}
    timed = {
        name: Timed(DriveRecorder(None, env, live=servers[name]))
        for name, env in (("live, no client", idle), ("live, watched", watched))
    }  # the live view as drive --live attaches it, timed
    idle.add_step_hook(timed["live, no client"])
    watched.add_step_hook(timed["live, watched"])
    context = multiprocessing.get_context("spawn")
    ready, stop = context.Event(), context.Event()
    port = servers["live, watched"].port
    client = context.Process(target=_client, args=(port, ready, stop), daemon=True)
    client.start()
    if not ready.wait(120):
        raise SystemExit("the benchmark's client did not subscribe within 120 s")
    for env in (plain, idle, watched):
        drive(env, 50, args.seed)  # warm-up: kernels, tables, the client's subscriptions
    for t in timed.values():
        t.seconds, t.calls = 0.0, 0
    rates: dict[str, list[float]] = {"plain": [], "live, no client": [], "live, watched": []}
    for r in range(args.rounds):
        order = list(zip(rates, (plain, idle, watched), strict=True))
        for name, env in order if r % 2 == 0 else order[::-1]:
            rates[name].append(drive(env, args.steps, args.seed))
    stop.set()
    client.join(10)
    sent = servers["live, watched"].n_published
    for env in (plain, idle, watched):
        env.close()
    for server in servers.values():
        server.close()
    print(f"{args.steps} steps x {args.rounds} rounds, {args.particles} particles, basement_loop")
    print("| drive | steps/s (median) | x plain (median of rounds) | streaming, ms per step |")
    print("|---|---:|---:|---:|")
    for name, values in rates.items():
        ratio = statistics.median(v / p for v, p in zip(values, rates["plain"], strict=True))
        cost = f"{1e3 * timed[name].seconds / timed[name].calls:.3f}" if name in timed else "-"
        print(f"| {name} | {statistics.median(values):.0f} | {ratio:.3f} | {cost} |")
    print(f"messages streamed to the client: {sent}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
