"""f1tenth_gym's single-track model driven on command sequences, in its own venv (subprocess).

f1tenth_gym (branch ``dev-dynamics``, not on PyPI, needs ``gymnasium==0.29.1``) runs as a
subprocess of the peer's Python, as in [`mcl.bench.peer_f1tenth`][mcl.bench.peer_f1tenth]. `PEER_SCRIPT` calls
only its public pieces: ``F110Env.f1tenth_vehicle_params()`` (its default parameters),
``vehicle_dynamics_st`` (its CommonRoad single-track model) and ``RK4Integrator`` (its default
integrator). None of its code is copied here.

Both cars get the same inputs: each command [steer rad, speed m/s] is held for ``dt`` seconds,
split into ``substeps``; every substep the steering velocity and the acceleration are what reach
the command within the limits (``clip((target - now) / h, -limit, limit)``, limits ``sv_max`` 3.2
rad/s and ``a_max`` 9.51 m/s²), which is how our actuators follow a command. Their env's two-step
steering buffer and its proportional speed controller are not used: this compares the models, not
the two envs' actuators.
"""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np

from mcl.bench.peer_process import PeerProcess

__all__ = ["PEER_SCRIPT", "PeerDynamics"]

PEER_SCRIPT = r"""
import json, sys
cfg = json.loads(sys.argv[1])
sys.path.insert(0, cfg["path"])
import numpy as np
import f1tenth_gym
from f1tenth_gym.envs.f110_env import F110Env
from f1tenth_gym.envs.dynamic_models import vehicle_dynamics_st
from f1tenth_gym.envs.integrator import RK4Integrator
params = F110Env.f1tenth_vehicle_params()
rk4 = RK4Integrator()
print(json.dumps({"ready": True, "module": f1tenth_gym.__file__, "params": params}), flush=True)
for line in sys.stdin:
    job = json.loads(line)
    if job["op"] != "drive":
        break
    sub = int(job["substeps"])
    h = float(job["dt"]) / sub
    x = np.zeros(7)  # x, y (centre of gravity), steer, v, yaw, yaw rate, slip angle
    out = [x.tolist()]
    for steer, speed in job["commands"]:
        for _ in range(sub):
            sv = min(max((steer - x[2]) / h, params["sv_min"]), params["sv_max"])
            acc = min(max((speed - x[3]) / h, -params["a_max"]), params["a_max"])
            x = rk4.integrate(f=vehicle_dynamics_st, x=x, u=np.array([sv, acc]), dt=h,
                              params=params)
        out.append(x.tolist())
    print(json.dumps({"states": out}), flush=True)
"""
"""Run by the peer's Python (``-c``): answers each ``{"op": "drive", "commands": [[steer, speed],
...], "dt": s, "substeps": n}`` line with ``{"states": [[x, y, steer, v, yaw, yaw rate, slip],
...]}`` (the start first, then one row per command)."""


class PeerDynamics(PeerProcess):
    """The f1tenth_gym subprocess of `PEER_SCRIPT` (``python``: its venv's interpreter,
    ``path``: its checkout)."""

    def __init__(self, python: str, path: str) -> None:
        self.proc = subprocess.Popen(
            [python, "-c", PEER_SCRIPT, json.dumps({"path": path})],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "PYTHONPATH": ""},
        )  # fmt: skip
        self.info = self.answer("ready")
        self.params: dict[str, float] = self.info["params"]

    def drive(self, commands: np.ndarray, dt: float, substeps: int) -> np.ndarray:
        """(K + 1, 7) their states after each command of ``commands`` (K, 2), the start first."""
        assert self.proc.stdin is not None
        job = {"op": "drive", "commands": np.asarray(commands, float).tolist(), "dt": dt,
               "substeps": substeps}  # fmt: skip
        self.proc.stdin.write(json.dumps(job) + "\n")
        self.proc.stdin.flush()
        return np.array(self.answer("states")["states"])
