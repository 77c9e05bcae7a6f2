"""Races against f1tenth_gym's multi-agent env: agent-steps per second with every car scanning.

Workload (`WORKLOAD`), the same for both simulators: ``num_agents`` cars one behind the
other on the longest straight of the map (`column_start()`), ``--race-spacing`` metres between
rear axles, every car a 1080-beam lidar over 4.7 rad out to 30 m with a fresh scan every step
(each car's scan sees the others), dt 0.01 s, all cars on the same open-loop slalom at 1 m/s
([`slalom()`][mcl.bench.peer_f1tenth.slalom]), so they follow each other without crashing (checked:
collisions are reported). Only the step is timed. f1tenth_gym (branch dev-dynamics) runs in its
own venv as a subprocess ([`mcl.bench.peer_f1tenth`][mcl.bench.peer_f1tenth]), our [`racecar_sim.RaceEnv`][racecar_sim.RaceEnv] in
this process, its scans cast on ``--race-workers`` threads (default 1); the two are interleaved size by size, round by round,
and the report gives medians of agent-steps per second and the median of the per-round ratios.
A last row times our race alone at ``--race-max-cars`` cars (beyond what f1tenth_gym is run at).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from mcl.bench.peer_f1tenth import ENV_SETTINGS, PEER_PREAMBLE, SPEED, _Peer, slalom
from racecar_sim.maps import OccupancyMap

__all__ = ["RACE_PEER_SCRIPT", "WORKLOAD", "column_poses", "column_start", "compare_race"]

WORKLOAD = (
    "N cars one behind the other on a straight, each a 1080-beam lidar over 4.7 rad, 30 m range, a "
    "fresh scan of every car every step (the others in it), dt 0.01 s, all on one slalom at 1 m/s "
    "(steer 0.3 cos(pi t) rad), no crashes"
)


def column_start(grid: OccupancyMap, length: float, clearance: float = 0.6) -> np.ndarray:
    """A world pose [x, y, theta] from which ``length`` metres straight ahead stay ``clearance``
    metres from every wall (the distance field sampled every 5 cm); deterministic (20 000 poses
    drawn with a fixed seed, the one with the longest clear line).

    Raises:
        ValueError: no line that long on the map (the longest is named).
    """
    rng = np.random.default_rng(0)
    poses = grid.sample_free_poses(rng, 20_000, clearance=clearance)
    steps = np.arange(0.0, length + 0.05, 0.05)
    reach = np.zeros(len(poses))
    for k in range(0, len(poses), 2000):  # blocks keep the (block, steps, 2) points small
        p = poses[k : k + 2000]
        d = np.stack([np.cos(p[:, 2]), np.sin(p[:, 2])], axis=1)
        pts = p[:, None, :2] + steps[None, :, None] * d[:, None, :]
        blocked = grid.distance_at(pts) < clearance
        first = np.where(blocked.any(axis=1), blocked.argmax(axis=1), len(steps))
        reach[k : k + 2000] = steps[np.minimum(first, len(steps) - 1)] * (first < len(steps)) + (
            first == len(steps)
        ) * (length + 1.0)
    best = int(np.argmax(reach))
    if reach[best] < length:
        raise ValueError(
            f"map {grid.name!r}: no straight line of {length:.1f} m {clearance} m clear of walls "
            f"(longest {reach[best]:.1f} m); use fewer cars, a smaller --race-spacing or fewer steps"
        )
    return poses[best]


def column_poses(start: np.ndarray, n: int, spacing: float) -> np.ndarray:
    """(n, 3) rear-axle poses: car ``n - 1`` at ``start``, each car ``spacing`` m ahead of the
    next along ``start``'s heading (car 0 leads)."""
    d = np.array([math.cos(start[2]), math.sin(start[2])])
    ahead = (n - 1 - np.arange(n))[:, None] * spacing
    out = np.empty((n, 3))
    out[:, :2] = start[:2] + ahead * d
    out[:, 2] = start[2]
    return out


RACE_PEER_SCRIPT = (
    PEER_PREAMBLE
    + r"""
envs = {}
print(json.dumps({"ready": True, "module": f1tenth_gym.__file__,
                  "gymnasium": gym.__version__}), flush=True)
for line in sys.stdin:
    cmd = json.loads(line)
    if cmd["op"] != "run":
        break
    n = cmd["agents"]
    if n not in envs:
        envs[n] = gym.make("f1tenth_gym:f1tenth-v0", config={
            "map": track, "num_agents": n, "timestep": 0.01, "integrator": "rk4", "model": "st",
            "control_input": ["speed", "steering_angle"], "observation_config": {"type": "original"},
            "reset_config": {"type": "map_random_static"}})
    env = envs[n]
    env.reset(options={"poses": np.array(cmd["poses"])})
    wall = cpu = 0.0
    hit = False
    for k in range(cmd["steps"]):
        a = np.tile([cfg["steer"] * math.cos(math.pi * k * 0.01), cfg["speed"]], (n, 1))
        w0, c0 = time.perf_counter(), time.process_time()
        obs, _, _, _, _ = env.step(a)
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
        hit = hit or bool(np.any(obs["collisions"]))
    print(json.dumps({"wall": wall, "cpu": cpu, "steps": cmd["steps"] * n, "collided": hit}),
          flush=True)
"""
)
"""Run by the peer's Python (``-c``): loads the map once, makes one env per agent count, and times
one episode per ``{"op": "run", "steps": S, "agents": N, "poses": [[x, y, theta], ...]}`` line."""


def _run_ours(env, steps: int, poses: np.ndarray, seed: int) -> dict[str, Any]:
    env.reset(seed=seed, options={"poses": poses})
    wall = cpu = 0.0
    hit = False
    agents = list(env.possible_agents)
    for k in range(steps):
        action = np.array(slalom(k))
        actions = dict.fromkeys(agents, action)
        w0, c0 = time.perf_counter(), time.process_time()
        _, _, _, _, infos = env.step(actions)
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
        hit = hit or any(info["collision"] for info in infos.values())
    return {"wall": wall, "cpu": cpu, "steps": steps * len(agents), "collided": hit}


class _RacePeer:
    """The f1tenth_gym subprocess of `RACE_PEER_SCRIPT`."""

    def __init__(self, python: str, path: str, map_yaml: Path) -> None:
        self._peer = _Peer(python, path, map_yaml, np.zeros(3), script=RACE_PEER_SCRIPT)
        self.info = self._peer.info

    def run(self, steps: int, poses: np.ndarray) -> dict[str, Any]:
        proc = self._peer.proc
        assert proc.stdin is not None
        cmd = {"op": "run", "steps": steps, "agents": len(poses), "poses": poses.tolist()}
        proc.stdin.write(json.dumps(cmd) + "\n")
        proc.stdin.flush()
        return self._peer.answer("wall")

    def close(self) -> None:
        self._peer.close()


def compare_race(
    grid: OccupancyMap,
    map_yaml: Path,
    python: str | None,
    path: str | None,
    *,
    sizes: tuple[int, ...] = (2, 4, 8, 16),
    max_cars: int = 32,
    steps: int = 300,
    runs: int = 3,
    spacing: float = 1.0,
    workers: int = 1,
) -> dict[int, dict[str, float]]:
    """Interleaved races of ``sizes`` cars in f1tenth_gym (when ``python`` and ``path`` are
    given) and in ours, then ours alone at ``max_cars``; prints the table, returns the medians."""
    from racecar_sim.race.env import RaceEnv

    biggest = max(max(sizes), max_cars)
    column = None
    for n in sorted({*sizes, max_cars}, reverse=True):
        try:
            column = column_start(grid, (n - 1) * spacing + steps * 0.01 * SPEED + 1.0)
            break
        except ValueError:
            if n == min(sizes):
                raise
    assert column is not None
    print(f"workload: {WORKLOAD}; map {grid.name}, rear car at {np.round(column, 2).tolist()}, "
          f"{spacing} m apart, {steps}-step races, {runs} rounds after a warm-up, only the step timed, "
          f"ours casting on {workers} thread(s), {max_cars} cars on one")  # fmt: skip
    peer = None
    if python and path:
        peer = _RacePeer(python, path, map_yaml)
        print(f"f1tenth_gym: {peer.info['module']} (gymnasium {peer.info['gymnasium']})")
    else:
        print("f1tenth_gym: not measured (give --f1tenth-python and --f1tenth-path)")
    ours = {n: RaceEnv(grid, n_cars=n, track=None, workers=workers, **ENV_SETTINGS) for n in sizes}
    rows: dict[int, dict[str, list[dict[str, Any]]]] = {n: {"peer": [], "ours": []} for n in sizes}
    extra: list[dict[str, Any]] = []
    try:
        for r in range(runs + 1):  # round 0 warms up (numba kernels, the peer's caches)
            warm = r == 0
            s = 30 if warm else steps
            for n in sizes:
                poses = column_poses(column, n, spacing)
                res_peer = peer.run(s, poses) if peer else None
                res_ours = _run_ours(ours[n], s, poses, seed=r)
                if not warm:
                    if res_peer is not None:
                        rows[n]["peer"].append(res_peer)
                    rows[n]["ours"].append(res_ours)
        if max_cars > max(sizes):
            try:
                poses = column_poses(
                    column_start(grid, (max_cars - 1) * spacing + 1.0), max_cars, spacing
                )
                big = RaceEnv(grid, n_cars=max_cars, track=None, workers=1, **ENV_SETTINGS)
                _run_ours(big, 30, poses, 0)
                extra = [_run_ours(big, steps // 3, poses, r) for r in range(runs)]
            except ValueError as exc:
                print(f"{max_cars} cars: not run ({exc})")
    finally:
        if peer:
            peer.close()
    return _report(rows, extra, max_cars, biggest)


def _rate(res: dict[str, Any], clock: str = "wall") -> float:
    return res["steps"] / res[clock]


def _report(rows, extra, max_cars: int, biggest: int) -> dict[int, dict[str, float]]:
    """The table: medians of agent-steps/s by the wall clock and by CPU time, and the medians of
    the per-round ratios (the rounds share the machine's load)."""
    print("| cars | f1tenth_gym agent-steps/s (wall, CPU) | ours agent-steps/s (wall, CPU) | "
          "x f1tenth_gym, wall (rounds) | x f1tenth_gym, CPU | ours race steps/s | "
          "collisions (peer, ours) |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---:|")
    out: dict[int, dict[str, float]] = {}
    for n, r in rows.items():
        ours = statistics.median(_rate(x) for x in r["ours"])
        ours_cpu = statistics.median(_rate(x, "cpu") for x in r["ours"])
        peer = peer_cpu = ratio = ratio_cpu = math.nan
        ratio_text = "-"
        if r["peer"]:
            peer = statistics.median(_rate(x) for x in r["peer"])
            peer_cpu = statistics.median(_rate(x, "cpu") for x in r["peer"])
            pairs = list(zip(r["ours"], r["peer"], strict=True))
            ratios = [_rate(a) / _rate(b) for a, b in pairs]
            ratio = statistics.median(ratios)
            ratio_cpu = statistics.median(_rate(a, "cpu") / _rate(b, "cpu") for a, b in pairs)
            ratio_text = f"{ratio:.1f} ({min(ratios):.1f}-{max(ratios):.1f})"
        hits = (sum(x["collided"] for x in r["peer"]), sum(x["collided"] for x in r["ours"]))
        print(f"| {n} | {peer:.0f}, {peer_cpu:.0f} | {ours:.0f}, {ours_cpu:.0f} | {ratio_text} | "
              f"{ratio_cpu:.1f} | {ours / n:.0f} | {hits[0]}, {hits[1]} |")  # fmt: skip
        out[n] = {"peer": peer, "ours": ours, "ratio": ratio, "ratio_cpu": ratio_cpu}
    if extra:
        ours = statistics.median(_rate(x) for x in extra)
        ours_cpu = statistics.median(_rate(x, "cpu") for x in extra)
        hits = sum(x["collided"] for x in extra)
        print(f"| {max_cars} | not run | {ours:.0f}, {ours_cpu:.0f} | - | - | {ours / max_cars:.0f} | "
              f"-, {hits} |")  # fmt: skip
        out[max_cars] = {"peer": math.nan, "ours": ours, "ratio": math.nan, "ratio_cpu": math.nan}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(
        f"load average {load:.1f} on {os.cpu_count()} CPUs after the run; a race step is "
        "real time at 100 race steps/s (dt 0.01 s)"
    )
    return out
