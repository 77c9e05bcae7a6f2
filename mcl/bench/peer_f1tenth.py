"""The f1tenth_gym peer: simulator steps per second on f1tenth_gym's own workload, same run.

f1tenth_gym is not on PyPI and needs ``gymnasium==0.29.1`` (this project needs Gymnasium 1.x), so
it runs in its own virtual environment, as a subprocess of this benchmark: get its public
repository (``f1tenth/f1tenth_gym``, branch ``dev-dynamics``), make a venv with
``pip install gymnasium==0.29.1 /path/to/f1tenth_gym``, and pass ``--f1tenth-python
/path/to/venv/bin/python --f1tenth-path /path/to/f1tenth_gym`` (the checkout is put first on the
subprocess's ``sys.path``). None of its code is copied here; `PEER_SCRIPT` only calls its
Gymnasium API.

Workload (`WORKLOAD`), the same for both simulators: one car, a 1080-beam lidar over 4.7 rad
out to 30 m with a fresh scan every step, dt = 0.01 s, an open-loop slalom at 1 m/s (steering
``0.3 cos(pi t)`` rad), episodes of ``--sim-steps`` steps from the same start pose on the same map
(`start_pose()` picks a pose on a long straight corridor; only ``env.step`` is timed, resets
are not). f1tenth_gym reads the map as a converted copy (grayscale PNG and the YAML keys it knows)
in a temporary folder. Its defaults otherwise: single-track model, RK4, Gaussian range noise of
0.01 m; ours: the pymunk car with the four-part beam noise and odometry noise.

The runs are interleaved round by round (peer, our single env, our vector env of ``--num-envs``
cars stepped with one parallel cast), so a change of load on a shared machine hits all of them;
the report gives medians of steps per second by the wall clock and by CPU time (the vector env's
threads add up their CPU time, so its figure is wall clock) and the median of the per-round ratios.
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl.bench.peer_process import PeerProcess
from racecar_sim.maps import OccupancyMap
from racecar_sim.raycast import RayCaster

__all__ = [
    "ENV_SETTINGS",
    "PEER_PREAMBLE",
    "PEER_SCRIPT",
    "WORKLOAD",
    "compare",
    "slalom",
    "start_pose",
]

ENV_SETTINGS: dict[str, Any] = {
    "n_beams": 1080,
    "fov": 4.7,
    "max_range": 30.0,
    "dt": 0.01,
    "lidar_rate": 100.0,
    "terminate_on_collision": False,
}
"""RacecarSim-v0 settings of the workload: f1tenth_gym's lidar and time step, a scan every step."""

WORKLOAD = (
    "one car, 1080 beams over 4.7 rad, 30 m range, a fresh scan every step, dt 0.01 s, "
    "slalom at 1 m/s (steer 0.3 cos(pi t) rad)"
)
SPEED = 1.0  # m/s
STEER = 0.3  # rad, slalom amplitude


def slalom(k: int, dt: float = 0.01) -> tuple[float, float]:
    """The workload's action at step ``k``: (steer rad, speed m/s)."""
    return STEER * math.cos(math.pi * k * dt), SPEED


def start_pose(grid: OccupancyMap, length: float, clearance: float = 1.0) -> np.ndarray:
    """A world pose [x, y, theta] at least ``clearance`` m from walls, facing ``length`` m of room.

    Deterministic: the pose (of 20 000 drawn with a fixed seed) whose three rays at 0 and
    +-0.15 rad reach farthest; raises ``ValueError`` when none reaches ``length`` metres.
    """
    rng = np.random.default_rng(0)
    poses = grid.sample_free_poses(rng, 20_000, clearance=clearance)
    reach = RayCaster(grid, max(30.0, length)).cast(poses, np.array([-0.15, 0.0, 0.15])).min(axis=1)
    best = int(np.argmax(reach))
    if reach[best] < length:
        raise ValueError(
            f"map {grid.name!r}: no straight stretch of {length:.0f} m for the slalom "
            f"(longest {reach[best]:.1f} m); use fewer --sim-steps"
        )
    return poses[best]


PEER_PREAMBLE = r"""
import json, math, os, sys, tempfile, time
cfg = json.loads(sys.argv[1])
sys.path.insert(0, cfg["path"])
import numpy as np, yaml
from PIL import Image
import gymnasium as gym
import f1tenth_gym
from f1tenth_gym.envs.track import Track

src = cfg["map"]
with open(src) as f:
    spec = yaml.safe_load(f)
with tempfile.TemporaryDirectory() as tmp:
    Image.open(os.path.join(os.path.dirname(src), spec["image"])).convert("L").save(
        os.path.join(tmp, "map.png"))
    keys = {"image": "map.png", "resolution": float(spec["resolution"]),
            "origin": [float(v) for v in spec["origin"]], "negate": int(spec.get("negate", 0)),
            "occupied_thresh": float(spec.get("occupied_thresh", 0.65)),
            "free_thresh": float(spec.get("free_thresh", 0.196))}
    with open(os.path.join(tmp, "map.yaml"), "w") as f:
        yaml.safe_dump(keys, f)
    track = Track.from_track_path(os.path.join(tmp, "map.yaml"))
"""
"""The start of a peer script: reads ``cfg`` (JSON in ``argv[1]``), imports f1tenth_gym from
its checkout and loads the map as its ``Track`` (a converted copy in a temporary folder)."""

PEER_SCRIPT = (
    PEER_PREAMBLE
    + r"""
env = gym.make("f1tenth_gym:f1tenth-v0", config={
    "map": track, "num_agents": 1, "timestep": 0.01, "integrator": "rk4", "model": "st",
    "control_input": ["speed", "steering_angle"], "observation_config": {"type": "original"},
    "reset_config": {"type": "map_random_static"}})
pose = np.array([cfg["pose"]])
print(json.dumps({"ready": True, "module": f1tenth_gym.__file__,
                  "gymnasium": gym.__version__}), flush=True)
for line in sys.stdin:
    cmd = json.loads(line)
    if cmd["op"] != "run":
        break
    env.reset(options={"poses": pose})
    wall = cpu = 0.0
    for k in range(cmd["steps"]):
        action = np.array([[cfg["steer"] * math.cos(math.pi * k * 0.01), cfg["speed"]]])
        w0, c0 = time.perf_counter(), time.process_time()
        obs, _, _, _, _ = env.step(action)
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
    print(json.dumps({"wall": wall, "cpu": cpu, "steps": cmd["steps"],
                      "collided": bool(obs["collisions"][0]),
                      "end": [float(obs["poses_x"][0]), float(obs["poses_y"][0])]}), flush=True)
"""
)
"""Run by the peer's Python (``-c``): loads the map and the env once, then times one episode per
``{"op": "run", "steps": N}`` line on stdin and answers with one JSON line."""


class _Peer(PeerProcess):
    """The f1tenth_gym subprocess (see `PEER_SCRIPT`)."""

    def __init__(
        self, python: str, path: str, map_yaml: Path, pose: np.ndarray, script: str = PEER_SCRIPT
    ) -> None:
        cfg = {"path": path, "map": str(map_yaml), "pose": [float(v) for v in pose],
               "steer": STEER, "speed": SPEED}  # fmt: skip
        self.proc = subprocess.Popen(
            [python, "-c", script, json.dumps(cfg)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "PYTHONPATH": ""},
        )  # fmt: skip
        self.info = self.answer("ready")

    def run(self, steps: int) -> dict[str, Any]:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": "run", "steps": steps}) + "\n")
        self.proc.stdin.flush()
        return self.answer("wall")


def run_ours(env, steps: int, seed: int, pose: np.ndarray, cars: int = 0) -> dict[str, Any]:
    """One timed episode of our single env (``cars`` = 0) or vector env (``cars`` cars)."""
    env.reset(seed=seed, options={"pose": pose})
    wall = cpu = 0.0
    collided = False
    for k in range(steps):
        action = np.array(slalom(k))
        if cars:
            action = np.tile(action, (cars, 1))
        w0, c0 = time.perf_counter(), time.process_time()
        _, _, _, _, info = env.step(action)
        cpu += time.process_time() - c0
        wall += time.perf_counter() - w0
        collided = collided or bool(np.any(info["collision"]))
    return {"wall": wall, "cpu": cpu, "steps": steps * max(cars, 1), "collided": collided}


def compare(
    grid: OccupancyMap,
    map_yaml: Path,
    python: str | None,
    path: str | None,
    *,
    steps: int = 1000,
    runs: int = 5,
    num_envs: int = 32,
    vector_steps: int = 300,
) -> dict[str, Any]:
    """Interleaved runs of f1tenth_gym (when ``python`` and ``path`` are given) and ours; prints
    the report and returns the medians (steps/s) and ratios."""
    pose = start_pose(grid, length=steps * 0.01 * SPEED + 2.0)
    print(f"workload: {WORKLOAD}; map {grid.name}, start pose {np.round(pose, 3).tolist()}, "
          f"{steps}-step episodes, {runs} runs after a warm-up, only env.step timed")  # fmt: skip
    peer = None
    if python and path:
        peer = _Peer(python, path, map_yaml, pose)
        print(f"f1tenth_gym: {peer.info['module']} (gymnasium {peer.info['gymnasium']})")
    else:
        print("f1tenth_gym: not measured (give --f1tenth-python and --f1tenth-path; see README)")
    single = gym.make("RacecarSim-v0", map=grid, **ENV_SETTINGS)
    vector = gym.make_vec(
        "RacecarSim-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
        map=grid, **ENV_SETTINGS,
    )  # fmt: skip
    rows: dict[str, list[dict[str, Any]]] = {"f1tenth_gym": [], "ours": [], "vector": []}
    try:
        for r in range(runs + 1):  # round 0 is the warm-up
            warm = r == 0
            n, nv = (200, 20) if warm else (steps, vector_steps)
            results = {
                "f1tenth_gym": peer.run(n) if peer else None,
                "ours": run_ours(single, n, r, pose),
                "vector": run_ours(vector, nv, r * num_envs, pose, cars=num_envs),
            }
            if not warm:
                for key, res in results.items():
                    if res is not None:
                        rows[key].append(res)
    finally:
        if peer:
            peer.close()
        vector.close()
    return _report(rows, num_envs)


def _report(rows: dict[str, list[dict[str, Any]]], num_envs: int) -> dict[str, Any]:
    def rate(res: dict[str, Any], clock: str) -> float:
        return res["steps"] / res[clock]

    out: dict[str, Any] = {}
    labels = {
        "f1tenth_gym": "f1tenth_gym (dev-dynamics), one env",
        "ours": "racecar-sim RacecarSim-v0, one env",
        "vector": f"racecar-sim vector env, {num_envs} cars (car-steps/s)",
    }
    peer_rows = rows["f1tenth_gym"]
    print("| simulator | steps/s (wall) | steps/s (CPU) | x f1tenth_gym (wall) | "
          "x f1tenth_gym (CPU) | collisions |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|")
    for key, res_list in rows.items():
        if not res_list:
            continue
        wall = statistics.median(rate(r, "wall") for r in res_list)
        cpu = statistics.median(rate(r, "cpu") for r in res_list)
        ratio_w = ratio_c = math.nan
        spread = ""
        if peer_rows:  # median of the per-round ratios (rounds share the machine's load)
            pairs = list(zip(res_list, peer_rows, strict=True))
            walls = [rate(a, "wall") / rate(b, "wall") for a, b in pairs]
            ratio_w = statistics.median(walls)
            ratio_c = statistics.median(rate(a, "cpu") / rate(b, "cpu") for a, b in pairs)
            spread = f" (rounds {min(walls):.2f}-{max(walls):.2f})"
        cpu_text = (
            f"{cpu:.0f}" if key != "vector" else f"({cpu:.0f}, up to {os.cpu_count()} threads)"
        )
        ratio_c_text = f"{ratio_c:.2f}" if key != "vector" else "-"
        hits = sum(r["collided"] for r in res_list)
        print(f"| {labels[key]} | {wall:.0f} | {cpu_text} | {ratio_w:.2f}{spread} | {ratio_c_text} | "
              f"{hits}/{len(res_list)} runs |")  # fmt: skip
        out[key] = {"wall": wall, "cpu": cpu, "x_wall": ratio_w, "x_cpu": ratio_c}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(f"load average {load:.1f} on {os.cpu_count()} CPUs after the run")
    return out


if __name__ == "__main__":  # pragma: no cover - run through scripts/bench_peers.py
    sys.exit("run: python scripts/bench_peers.py --only f1tenth ...")
