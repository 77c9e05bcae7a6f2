"""The single-track car against f1tenth_gym's, and what it costs: ``racecar-sim bench dynamics``.

Four parts (``--only`` picks one), each printing a Markdown table with its workload:

* ``skidpad``: steady circles at fixed steer (0.2 and 0.35 rad) for 1-7 m/s, 10 s from rest at
  dt 0.01 s (5 ms substeps): radius, yaw rate, lateral acceleration and slip angle of the centre
  of gravity, ours (``single_track``, [`CarParams.f1tenth()`][CarParams.f1tenth]) against f1tenth_gym's model
  ([`mcl.bench.peer_dynamics`][mcl.bench.peer_dynamics], its own venv), and the first speed where each car's radius
  departs by over 5 % from the kinematic one (``sqrt((L / tan(steer))^2 + lr^2)``).
* ``openloop``: the same command sequences (steps and sines of steer and speed, up to 7 m/s, 5 s
  at dt 0.01 s) through both models: the state differences after 5 s and the largest lateral
  acceleration f1tenth_gym's car reached.
* ``stepsize``: the open-loop manoeuvres within the grip at substeps of 10, 5, 2.5 and 1.25 ms,
  each against the same at 0.156 ms: the largest differences in position, heading and slip angle.
* ``speed``: steps per second of our single env and vector env (``--num-envs`` cars) with each
  car model, on f1tenth_gym's workload ([`mcl.bench.peer_f1tenth.WORKLOAD`][mcl.bench.peer_f1tenth.WORKLOAD]), rounds
  interleaved model by model; the cost is the median of the per-round ratios of time per step.

Without ``--f1tenth-python`` / ``--f1tenth-path`` the skidpad and open-loop parts show ours only.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from mcl.bench import STATA
from racecar_sim.car.free_steps import advance
from racecar_sim.car.models.manoeuvres import drive, skidpad
from racecar_sim.settings.config import CarParams

__all__ = ["OPEN_LOOP", "main", "open_loop", "skidpad_table", "speed_cost"]

G = 9.81
DT = 0.01  # s, control step of the skidpad and the open-loop drives
SUBSTEPS = 2  # 5 ms substeps, ours and theirs
STEERS = (0.2, 0.35)
SPEEDS = (1, 2, 3, 4, 5, 6, 7)
DEPARTS = 0.05  # a radius this much off the kinematic one has departed from it


def _t(n: int = 500) -> np.ndarray:
    return np.arange(n) * DT


OPEN_LOOP: dict[str, Any] = {
    "steer steps +-0.1 rad every 1 s, 3 m/s": lambda t: np.c_[
        np.where(t < 0.5, 0.0, np.where((t - 0.5) % 2 < 1, 0.1, -0.1)), np.full_like(t, 3.0)],
    "speed steps 2-4-6-4 m/s, steer 0.03 rad": lambda t: np.c_[
        np.full_like(t, 0.03), np.select([t < 1.25, t < 2.5, t < 3.75], [2.0, 4.0, 6.0], 4.0)],
    "steer sine 0.06 rad 0.5 Hz, 5 m/s": lambda t: np.c_[
        0.06 * np.sin(math.pi * t), np.full_like(t, 5.0)],
    "steer sine 0.03 rad 1 Hz, 7 m/s": lambda t: np.c_[
        0.03 * np.sin(2 * math.pi * t), np.full_like(t, 7.0)],
    "speed sine 4 +- 3 m/s 0.4 Hz, steer 0.03 rad": lambda t: np.c_[
        np.full_like(t, 0.03), 4.0 + 3.0 * np.sin(0.8 * math.pi * t)],
    "steer sine 0.15 rad 0.5 Hz, 5 m/s (near the grip)": lambda t: np.c_[
        0.15 * np.sin(math.pi * t), np.full_like(t, 5.0)],
    "steer sine 0.3 rad 0.5 Hz, 6 m/s (beyond the grip)": lambda t: np.c_[
        0.3 * np.sin(math.pi * t), np.full_like(t, 6.0)],
}  # fmt: skip
"""Open-loop manoeuvres: name -> commands (K, 2) [steer rad, speed m/s] at times ``t`` (s)."""


def _ours(car: CarParams, model: str, commands: np.ndarray) -> np.ndarray:
    """Our rows as the peer's: [x, y (centre of gravity), steer, v, yaw, yaw rate, slip]."""
    rows = drive(car, model, commands, DT, substep=DT / SUBSTEPS)
    x, y, yaw = rows[:, 0], rows[:, 1], rows[:, 2]
    lr = car.cg_to_rear
    return np.c_[x + lr * np.cos(yaw), y + lr * np.sin(yaw), rows[:, 3], rows[:, 7], yaw,
                 rows[:, 6], rows[:, 5]]  # fmt: skip


def _kinematic_radius(car: CarParams, steer: float) -> float:
    rear = car.wheelbase / math.tan(steer)
    return math.hypot(rear, car.cg_to_rear)


def _departs(radii: dict[int, float], kinematic: float) -> str:
    for v in SPEEDS:
        if abs(radii[v] / kinematic - 1) > DEPARTS:
            return f"{v} m/s"
    return f"above {SPEEDS[-1]} m/s"


def skidpad_table(car: CarParams, peer=None) -> dict[str, Any]:
    """Print the skidpad table (module docstring); returns rows keyed by (steer, speed)."""
    limit = car.friction * G
    print(f"skidpad: fixed steer, 10 s from rest, dt {DT} s in {SUBSTEPS} substeps; F1TENTH "
          f"parameters (mu {car.friction}, mu g {limit:.2f} m/s^2); centre of gravity")  # fmt: skip
    print("| steer rad | speed m/s | R ours m | R f1tenth_gym m | R ours / theirs | "
          "yaw rate ours / theirs rad/s | a_y ours / theirs m/s^2 | slip ours / theirs rad | "
          "note |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---|---|---|---|")
    out: dict[Any, Any] = {}
    for steer in STEERS:
        ours_r, theirs_r = {}, {}
        for v in SPEEDS:
            c = skidpad(car, "single_track", steer, float(v), dt=DT, substep=DT / SUBSTEPS)
            ours_r[v] = c.radius
            row = {"ours": c}
            note = ""
            if peer is not None:
                th = peer.drive(np.tile([steer, float(v)], (1000, 1)), DT, SUBSTEPS)[-1]
                t_v, t_r, t_beta = th[3], th[5], th[6]
                theirs_r[v] = t_v / t_r
                row["theirs"] = {"radius": t_v / t_r, "yaw_rate": t_r, "lateral_accel": t_v * t_r,
                                 "slip_angle": t_beta}  # fmt: skip
                ratio = c.radius / theirs_r[v]
                if t_v * t_r < 0.5 * limit:
                    note = f"theirs under mu g / 2: radii {'agree' if abs(ratio - 1) <= 0.1 else 'DIFFER'}"
                else:
                    note = (f"theirs at {t_v * t_r / limit:.1f} mu g (linear tires); ours "
                            f"{'is held' if c.lateral_accel <= 1.01 * limit else 'is OVER mu g'} "
                            f"at {c.lateral_accel / limit:.2f} mu g")  # fmt: skip
                print(f"| {steer} | {v} | {c.radius:.3f} | {theirs_r[v]:.3f} | {ratio:.2f} | "
                      f"{c.yaw_rate:.2f} / {t_r:.2f} | {c.lateral_accel:.2f} / {t_v * t_r:.2f} | "
                      f"{c.slip_angle:.3f} / {t_beta:.3f} | {note} |")  # fmt: skip
            else:
                print(f"| {steer} | {v} | {c.radius:.3f} | - | - | {c.yaw_rate:.2f} / - | "
                      f"{c.lateral_accel:.2f} / - | {c.slip_angle:.3f} / - | |")  # fmt: skip
            out[(steer, v)] = row
        kin = _kinematic_radius(car, steer)
        theirs = f"; f1tenth_gym's at {_departs(theirs_r, kin)}" if theirs_r else ""
        print(f"\nsteer {steer} rad: kinematic radius {kin:.3f} m; ours departs by over "
              f"{DEPARTS:.0%} at {_departs(ours_r, kin)}{theirs}\n")  # fmt: skip
    return out


def open_loop(car: CarParams, peer=None) -> dict[str, dict[str, float]]:
    """Print the open-loop table (module docstring); returns the differences per manoeuvre."""
    limit = car.friction * G
    print(f"open loop: 5 s, dt {DT} s in {SUBSTEPS} substeps, both cars from rest, the same "
          "actuator inputs (steering rate <= 3.2 rad/s, |accel| <= 9.51 m/s^2); differences "
          "after 5 s (ours - theirs), centre of gravity")  # fmt: skip
    print("| manoeuvre | theirs peak v r | position m | heading rad | speed m/s | "
          "yaw rate rad/s | slip rad | largest position gap m |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    out = {}
    for name, make in OPEN_LOOP.items():
        commands = make(_t())
        ours = _ours(car, "single_track", commands)
        if peer is None:
            print(f"| {name} | - | - | - | - | - | - | - |")
            continue
        theirs = peer.drive(commands, DT, SUBSTEPS)
        gap = np.hypot(ours[:, 0] - theirs[:, 0], ours[:, 1] - theirs[:, 1])
        d = ours[-1] - theirs[-1]
        peak = float(np.max(np.abs(theirs[:, 3] * theirs[:, 5])))
        row = {"peak_ay": peak, "position": float(gap[-1]), "heading": float(d[4]),
               "speed": float(d[3]), "yaw_rate": float(d[5]), "slip": float(d[6]),
               "largest_gap": float(gap.max())}  # fmt: skip
        out[name] = row
        print(f"| {name} | {peak / limit:.2f} mu g | {row['position']:.3f} | {row['heading']:+.3f}"
              f" | {row['speed']:+.3f} | {row['yaw_rate']:+.3f} | {row['slip']:+.4f} | "
              f"{row['largest_gap']:.3f} |")  # fmt: skip
    return out


STEP_SIZES = (0.01, 0.005, 0.0025, 0.00125)
"""Substeps (s) of the step-size part, each against a reference at 1/8 of the smallest."""


def step_size_error(car: CarParams) -> dict[str, dict[float, tuple[float, float, float]]]:
    """Print the step-size table: the open-loop manoeuvres within the grip at each substep of
    `STEP_SIZES` against the same at a substep of 1/8 of the smallest (dt 0.02 s, 5 s);
    largest differences over the run in position (m), heading and slip angle (rad)."""
    reference_h = STEP_SIZES[-1] / 8
    print(f"step size: single_track, F1TENTH parameters, 5 s at dt 0.02 s; the largest difference "
          f"over the run against a {reference_h * 1e3:.3f} ms substep")  # fmt: skip
    print("| manoeuvre | " + " | ".join(f"{h * 1e3:g} ms: position m / heading rad / slip rad"
                                       for h in STEP_SIZES) + " |")  # fmt: skip
    print("|---|" + "---:|" * len(STEP_SIZES))
    out: dict[str, dict[float, tuple[float, float, float]]] = {}
    t = np.arange(250) * 0.02
    for name in list(OPEN_LOOP)[:4]:  # the car keeps its grip (the others slide or half spin)
        commands = OPEN_LOOP[name](t)
        ref = drive(car, "single_track", commands, 0.02, substep=reference_h)
        cells, out[name] = [], {}
        for h in STEP_SIZES:
            d = drive(car, "single_track", commands, 0.02, substep=h) - ref
            err = (float(np.hypot(d[:, 0], d[:, 1]).max()), float(abs(d[:, 2]).max()),
                   float(abs(d[:, 5]).max()))  # fmt: skip
            out[name][h] = err
            cells.append(f"{err[0]:.1e} / {err[1]:.1e} / {err[2]:.1e}")
        print(f"| {name} | " + " | ".join(cells) + " |")
    return out


def speed_cost(map_yaml: Path, steps: int, vector_steps: int, runs: int, num_envs: int) -> dict:
    """Print steps/s of each model (single env, vector env) on f1tenth_gym's workload, rounds
    interleaved; returns the medians and the median per-round cost (time per step ratio, by the
    wall clock and by process CPU time, which a shared machine's load disturbs less)."""
    import gymnasium as gym

    from mcl.bench.peer_f1tenth import ENV_SETTINGS, SPEED, WORKLOAD, run_ours, start_pose
    from racecar_sim.maps import load_map

    grid = load_map(map_yaml)
    pose = start_pose(grid, length=steps * 0.01 * SPEED + 2.0)
    print(f"speed: {WORKLOAD}; map {grid.name}, {steps}-step episodes (vector env: "
          f"{num_envs} cars x {vector_steps} steps), {runs} rounds after a warm-up, each round "
          "both models in turn; only env.step timed")  # fmt: skip
    envs = {}
    for model in ("kinematic", "single_track"):
        envs[model] = (
            gym.make("RacecarSim-v0", map=grid, car_model=model, **ENV_SETTINGS),
            gym.make_vec("RacecarSim-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                         map=grid, car_model=model, **ENV_SETTINGS),
        )  # fmt: skip
    rates: dict[tuple[str, str], list[float]] = {}
    try:
        for r in range(runs + 1):
            n, nv = (100, 10) if r == 0 else (steps, vector_steps)
            order = ("kinematic", "single_track") if r % 2 else ("single_track", "kinematic")
            for model in order:
                single, vector = envs[model]
                a = run_ours(single, n, r, pose)
                b = run_ours(vector, nv, r * num_envs, pose, cars=num_envs)
                if r:
                    for kind, res in (("single", a), ("vector", b)):
                        rates.setdefault((model, kind), []).append(res["steps"] / res["wall"])
                        rates.setdefault((model, kind, "cpu"), []).append(res["steps"] / res["cpu"])
    finally:
        for _, vector in envs.values():
            vector.close()
    print("| env | kinematic steps/s | single_track steps/s | single_track time per step / "
          "kinematic, wall (median, rounds) | the same by CPU time (median, rounds) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|")
    out = {}
    for kind, label in (
        ("single", "one env"),
        ("vector", f"vector env, {num_envs} cars (car-steps/s)"),
    ):
        kin, st = rates[("kinematic", kind)], rates[("single_track", kind)]
        ratios = [k / s for k, s in zip(kin, st, strict=True)]
        cpu = [k / s for k, s in zip(rates[("kinematic", kind, "cpu")],
                                     rates[("single_track", kind, "cpu")], strict=True)]  # fmt: skip
        cost, cost_cpu = statistics.median(ratios), statistics.median(cpu)
        out[kind] = {"kinematic": statistics.median(kin), "single_track": statistics.median(st),
                     "cost": cost, "cost_cpu": cost_cpu}  # fmt: skip
        print(f"| {label} | {out[kind]['kinematic']:.0f} | {out[kind]['single_track']:.0f} | "
              f"{cost:.3f} ({min(ratios):.3f}-{max(ratios):.3f}) | "
              f"{cost_cpu:.3f} ({min(cpu):.3f}-{max(cpu):.3f}) |")  # fmt: skip
    out["physics"] = _physics_cost(runs)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(f"load average {load:.1f} on {os.cpu_count()} CPUs after the run")
    return out


@nb.njit(cache=True)
def _drive_free(const, state, commands, dt, twist):  # pragma: no cover - numba
    for k in range(commands.shape[0]):
        advance(const, state, commands[k, 0], commands[k, 1], 2, dt / 2, dt, twist)


def _physics_cost(runs: int, steps: int = 20_000) -> dict[str, float]:
    """Print microseconds per free physics step (dt 0.01 s, two substeps, no walls near) of each
    model, in one numba loop, rounds interleaved; returns the medians and the median per-round
    ratio."""
    import time

    from racecar_sim.car.free_steps import STATE_FIELDS, free_constants

    car = CarParams()
    t = np.arange(steps) * DT
    commands = np.c_[0.3 * np.cos(math.pi * t), np.full_like(t, 3.0)]
    times: dict[str, list[float]] = {"kinematic": [], "single_track": []}
    for r in range(runs + 1):
        for model in ("kinematic", "single_track") if r % 2 else ("single_track", "kinematic"):
            const = free_constants(car, None, 0.0, model)
            state, twist = np.zeros(len(STATE_FIELDS)), np.zeros(3)
            t0 = time.perf_counter()
            _drive_free(const, state, commands, DT, twist)
            if r:
                times[model].append((time.perf_counter() - t0) / steps * 1e6)
    ratio = statistics.median(s / k for k, s in zip(times["kinematic"], times["single_track"],
                                                     strict=True))  # fmt: skip
    kin, st = statistics.median(times["kinematic"]), statistics.median(times["single_track"])
    print(f"\nthe car model alone (one free physics step of dt {DT} s in 2 substeps, in a numba "
          f"loop, 3 m/s slalom): kinematic {kin:.2f} us, single_track {st:.2f} us, "
          f"{ratio:.2f}x (median of {runs} rounds)")  # fmt: skip
    return {"kinematic_us": kin, "single_track_us": st, "ratio": ratio}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--only", choices=("skidpad", "openloop", "stepsize", "speed"),
                        help="one part only")  # fmt: skip
    parser.add_argument("--f1tenth-python", help="python of a venv with f1tenth_gym installed")
    parser.add_argument("--f1tenth-path", help="the f1tenth_gym checkout (branch dev-dynamics)")
    parser.add_argument("--map", type=Path, default=STATA,
                        help="map YAML of the speed part (default: Stata)")  # fmt: skip
    parser.add_argument("--sim-steps", type=int, default=1000, help="steps per single-env run")
    parser.add_argument("--vector-steps", type=int, default=200, help="steps per vector-env run")
    parser.add_argument("--runs", type=int, default=5, help="rounds of the speed part")
    parser.add_argument("--num-envs", type=int, default=32, help="cars in the vector env")
    parser.add_argument("--quick", action="store_true", help="a short speed part (2 rounds)")
    args = parser.parse_args(argv)
    for name in ("sim_steps", "vector_steps", "runs", "num_envs"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1")
    if bool(args.f1tenth_python) != bool(args.f1tenth_path):
        parser.error("give both --f1tenth-python and --f1tenth-path")
    for flag, value in (("--f1tenth-python", args.f1tenth_python),
                        ("--f1tenth-path", args.f1tenth_path)):  # fmt: skip
        if value and not Path(value).exists():
            parser.error(f"{flag} {value} does not exist")
    parts = [args.only] if args.only else ["skidpad", "openloop", "stepsize", "speed"]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{os.cpu_count()} CPUs, load average {load:.1f} before the run")
    car = CarParams.f1tenth()
    peer = None
    if args.f1tenth_python and {"skidpad", "openloop"} & set(parts):
        from mcl.bench.peer_dynamics import PeerDynamics

        peer = PeerDynamics(args.f1tenth_python, args.f1tenth_path)
        print(f"f1tenth_gym: {peer.info['module']}, its parameters {peer.params}")
    elif {"skidpad", "openloop"} & set(parts):
        print("f1tenth_gym: not measured (give --f1tenth-python and --f1tenth-path)")
    try:
        if "skidpad" in parts:
            print("\n== skidpad ==")
            skidpad_table(car, peer)
        if "openloop" in parts:
            print("\n== open loop ==")
            open_loop(car, peer)
    finally:
        if peer is not None:
            peer.close()
    if "stepsize" in parts:
        print("\n== step size ==")
        step_size_error(car)
    if "speed" in parts:
        print("\n== speed ==")
        map_yaml = args.map
        if not map_yaml.is_file():
            from racecar_sim.maps import bundled

            print(
                f"map {map_yaml} not found (the Stata map lives in ../shared/maps): basement_loop"
            )
            map_yaml = bundled("basement_loop")
        runs = 2 if args.quick else args.runs
        speed_cost(map_yaml, args.sim_steps, args.vector_steps, runs, args.num_envs)
    return 0


if __name__ == "__main__":  # pragma: no cover - run through scripts/bench_dynamics.py
    sys.exit(main())
