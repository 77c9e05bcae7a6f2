"""Test a lap policy: laps, lap times, wall contact and progress, with MCL in the loop.

A policy is any ``policy(obs) -> action`` on :class:`~mcl.agents.lap_env.LapTask` observations
(e.g. :func:`mcl.agents.ppo.load_policy`). Test episodes start at the loop's start, never end at a
wall (the car stays in contact and every such step is counted) and last ``seconds``.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mcl.agents.lap_env import LapTaskConfig, make_lap_env

__all__ = [
    "EpisodeResult",
    "evaluate_policy",
    "learning_curve",
    "summary_table",
    "tested_on",
    "write_results",
]

Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class EpisodeResult:
    """One test episode.

    Attributes:
        policy: the policy's name. tested_on: the pose its observations were built from in the
            test (``truth``, or ``estimate (N particles)``).
        seed: reset seed. seconds: simulated seconds driven.
        laps: completed laps. lap_times: seconds of each (the first from a standing start).
        progress_per_min: metres along the loop per minute (truth).
        collision_steps: steps with wall contact. contacts: separate wall contacts (runs of them).
        mean_error, max_error: metres, the filter's position error (NaN without MCL).
    """

    policy: str
    tested_on: str
    seed: int
    seconds: float
    laps: int
    lap_times: tuple[float, ...]
    progress_per_min: float
    collision_steps: int
    contacts: int
    mean_error: float
    max_error: float


def tested_on(task: LapTaskConfig) -> str:
    """How a test builds the pose: ``"truth"``, ``"no pose"`` or ``"estimate (N particles)"``
    (beams per particle added when not the default)."""
    if task.pose_source != "estimate":
        return "no pose" if task.pose_source == "none" else "truth"
    beams = (
        "" if task.filter_beams == LapTaskConfig.filter_beams else f" x {task.filter_beams} beams"
    )
    return f"estimate ({task.n_particles} particles{beams})"


def evaluate_policy(
    policy: Policy,
    name: str,
    task: LapTaskConfig,
    seeds: Sequence[int],
    seconds: float = 60.0,
    *,
    on_frame: Callable[[np.ndarray], None] | None = None,
    frame_every: int = 4,
) -> list[EpisodeResult]:
    """Drive ``policy`` for ``seconds`` per seed on ``task`` made a test (start at the loop's
    start, no end at walls); ``on_frame(rgb)`` gets a rendered frame every ``frame_every`` steps
    of the first seed."""
    test = replace(
        task, terminate_on_collision=False, episode_seconds=seconds, start_s=task.start_s or 0.0
    )
    results = []
    for i, seed in enumerate(seeds):
        render = on_frame is not None and i == 0
        env = make_lap_env(test, render_mode="rgb_array" if render else None)
        obs, info = env.reset(seed=int(seed))
        errors: list[float] = []
        contacts, touching, steps = 0, False, 0
        while True:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            steps += 1
            if "localization" in info:
                errors.append(float(info["localization"]["position_error"]))
            contacts += bool(info["collision"]) and not touching
            touching = bool(info["collision"])
            if render and steps % frame_every == 0:
                on_frame(env.render())
            if terminated or truncated:
                break
        lap = info["lap"]
        t = float(info["time"])
        results.append(
            EpisodeResult(
                policy=name,
                tested_on=tested_on(task),
                seed=int(seed),
                seconds=t,
                laps=int(lap["laps"]),
                lap_times=tuple(round(x, 3) for x in lap["lap_times"]),
                progress_per_min=float(lap["progress"]) * 60.0 / t,
                collision_steps=int(lap["collisions"]),
                contacts=contacts,
                mean_error=float(np.mean(errors)) if errors else math.nan,
                max_error=float(np.max(errors)) if errors else math.nan,
            )
        )
        env.close()
    return results


def summary_table(results: Sequence[EpisodeResult]) -> str:
    """Markdown, one row per policy and test: laps, first lap (from a standing start) and
    flying laps (the later ones), wall contacts, progress per minute, localization error; totals
    or means over the seeds."""
    head = (
        "| policy (trained on) | tested on | episodes | laps | lap time (s) | flying lap (s) "
        "| wall contacts | steps in contact | progress (m/min) | MCL error (m) |"
    )
    lines = [head, "|" + "---|" * 10]
    keys = list(dict.fromkeys((r.policy, r.tested_on) for r in results))
    for name, test in keys:
        group = [r for r in results if (r.policy, r.tested_on) == (name, test)]
        firsts = [r.lap_times[0] for r in group if r.lap_times]
        flying = [x for r in group for x in r.lap_times[1:]]

        def fmt(values: Sequence[float], digits: int = 2) -> str:
            return f"{np.mean(values):.{digits}f}" if len(values) else "–"

        lines.append(
            f"| {name} | {test} | {len(group)} | "
            f"{sum(r.laps for r in group)} | {fmt(firsts)} | {fmt(flying)} | "
            f"{sum(r.contacts for r in group)} | {sum(r.collision_steps for r in group)} | "
            f"{fmt([r.progress_per_min for r in group], 1)} | "
            f"{fmt([r.mean_error for r in group], 3)} |"
        )
    return "\n".join(lines)


def write_results(results: Sequence[EpisodeResult], out_dir: str | os.PathLike[str]) -> list[Path]:
    """eval.csv (one row per episode) and eval.md (:func:`summary_table`) in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, md_path = out / "eval.csv", out / "eval.md"
    with csv_path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, list(EpisodeResult.__dataclass_fields__))
        writer.writeheader()
        for r in results:
            row: dict[str, Any] = asdict(r)
            row["lap_times"] = " ".join(f"{x:g}" for x in r.lap_times)
            writer.writerow(row)
    md_path.write_text(summary_table(results) + "\n", encoding="utf-8")
    return [csv_path, md_path]


def learning_curve(
    curves: dict[str, str | os.PathLike[str]], path: str | os.PathLike[str], window: int = 10
) -> Path:
    """Plot progress per training episode against timesteps (running mean over ``window``
    episodes) for each ``name -> learning.csv``; returns the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mcl.experiments.plots import save_figure

    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    for name, csv_path in curves.items():
        with Path(csv_path).open(encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        if not rows:
            continue
        steps = np.array([float(r["timesteps"]) for r in rows])
        ret = np.array([float(r["return"]) for r in rows])
        k = max(1, min(window, len(ret)))
        smooth = np.convolve(ret, np.ones(k) / k, mode="valid")
        ax.plot(steps[k - 1 :], smooth, label=name)
    ax.set_xlabel("training timesteps (all envs)")
    ax.set_ylabel(f"episode return (m of progress - penalties), mean of {window}")
    ax.grid(alpha=0.3)
    ax.legend()
    return save_figure(fig, path)
