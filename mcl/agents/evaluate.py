"""Test a lap policy: laps, lap times, wall contact and progress, with MCL in the loop, and
against opponents: car contacts and overtakes.

A policy is any ``policy(obs) -> action`` on [`LapTask`][mcl.agents.lap_env.LapTask] observations
(e.g. [`mcl.agents.ppo.load_policy()`][mcl.agents.ppo.load_policy]). Test episodes start at the loop's start (in a race: the
agent last on the grid behind the start line), never end at a contact (the car stays in contact
and every such step is counted) and last ``seconds``. A race's counts are
[`RaceTally`][mcl.agents.race_tally.RaceTally]'s.
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

from mcl.agents.lap_env import LapTaskConfig
from mcl.agents.task_env import make_task_env
from racecar_sim.file_guard import claim_folder, writable

__all__ = [
    "EpisodeResult",
    "evaluate_policy",
    "learning_curve",
    "race_table",
    "summary_table",
    "tested_on",
    "write_results",
]

Policy = Callable[[np.ndarray], np.ndarray]

_RACE_FIELDS = {  # EpisodeResult field <- key of info["race"]
    **{k: k for k in ("opponents", "wall_contacts", "car_contacts", "overtakes", "overtaken")},
    "start_rank": "start_rank",
    "final_rank": "rank",
}


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
        opponents: scripted cars in the race (0: alone). In a race also (else 0): wall_contacts,
            car_contacts (separate contacts with a wall / another car), overtakes, overtaken
            (rank gains and losses), start_rank, final_rank (1 = leading).
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
    opponents: int = 0
    wall_contacts: int = 0
    car_contacts: int = 0
    overtakes: int = 0
    overtaken: int = 0
    start_rank: int = 0
    final_rank: int = 0


def tested_on(task: LapTaskConfig) -> str:
    """How a test builds the pose: ``"truth"``, ``"no pose"`` or ``"estimate (N particles)"``
    (beams per particle added when not the default), then the car model when not kinematic and
    the opponents when there are any, e.g. ``"truth, single_track, 3 opponents"``."""
    if task.pose_source != "estimate":
        name = "no pose" if task.pose_source == "none" else "truth"
    else:
        beams = (
            ""
            if task.filter_beams == LapTaskConfig.filter_beams
            else f" x {task.filter_beams} beams"
        )
        name = f"estimate ({task.n_particles} particles{beams})"
    return name + describe_world(task)


def describe_world(task: LapTaskConfig) -> str:
    """``", single_track"`` / ``", 3 opponents"`` for what differs from the lone kinematic car."""
    text = "" if task.car_model == "kinematic" else f", {task.car_model}"
    if task.opponents:
        text += f", {task.opponents} opponent{'s' if task.opponents > 1 else ''}"
    return text


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
        env = make_task_env(test, render_mode="rgb_array" if render else None)
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
        race = info.get("race", {})
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
                **{field: int(race[key]) for field, key in _RACE_FIELDS.items() if key in race},
            )
        )
        env.close()
    return results


def _groups(results: Sequence[EpisodeResult]) -> list[list[EpisodeResult]]:
    """The results grouped by (policy, test), in order of first appearance."""
    keys = list(dict.fromkeys((r.policy, r.tested_on) for r in results))
    return [[r for r in results if (r.policy, r.tested_on) == key] for key in keys]


def _mean(values: Sequence[float], digits: int = 2) -> str:
    """The mean of the finite values, or a dash when there are none (e.g. no MCL)."""
    finite = [v for v in values if math.isfinite(v)]
    return f"{np.mean(finite):.{digits}f}" if finite else "–"


def _lap_columns(group: Sequence[EpisodeResult]) -> str:
    """``laps | lap time | flying lap`` of a group: total laps, mean first lap (from a standing
    start), mean of the later (flying) laps."""
    firsts = [r.lap_times[0] for r in group if r.lap_times]
    flying = [x for r in group for x in r.lap_times[1:]]
    return f"{sum(r.laps for r in group)} | {_mean(firsts)} | {_mean(flying)}"


def summary_table(results: Sequence[EpisodeResult]) -> str:
    """Markdown, one row per policy and test: laps, first lap (from a standing start) and
    flying laps (the later ones), wall contacts, progress per minute, localization error; totals
    or means over the seeds."""
    head = (
        "| policy (trained on) | tested on | episodes | laps | lap time (s) | flying lap (s) "
        "| wall contacts | steps in contact | progress (m/min) | MCL error (m) |"
    )
    lines = [head, "|" + "---|" * 10]
    for group in _groups(results):
        r0 = group[0]
        lines.append(
            f"| {r0.policy} | {r0.tested_on} | {len(group)} | {_lap_columns(group)} | "
            f"{sum(r.contacts for r in group)} | {sum(r.collision_steps for r in group)} | "
            f"{_mean([r.progress_per_min for r in group], 1)} | "
            f"{_mean([r.mean_error for r in group], 3)} |"
        )
    return "\n".join(lines)


def race_table(results: Sequence[EpisodeResult]) -> str:
    """Markdown, one row per policy and race test: laps, lap times, wall and car contacts
    (separate contacts), overtakes and times overtaken (totals over the episodes), the start
    rank and the mean final rank, progress per minute."""
    head = (
        "| policy (trained on) | tested on | episodes | laps | lap time (s) | flying lap (s) "
        "| wall contacts | car contacts | overtakes | overtaken | start rank | final rank (mean) "
        "| progress (m/min) |"
    )
    lines = [head, "|" + "---|" * 13]
    for group in _groups([r for r in results if r.opponents]):
        r0 = group[0]
        lines.append(
            f"| {r0.policy} | {r0.tested_on} | {len(group)} | {_lap_columns(group)} | "
            f"{sum(r.wall_contacts for r in group)} | {sum(r.car_contacts for r in group)} | "
            f"{sum(r.overtakes for r in group)} | {sum(r.overtaken for r in group)} | "
            f"{r0.start_rank} | {_mean([r.final_rank for r in group], 1)} | "
            f"{_mean([r.progress_per_min for r in group], 1)} |"
        )
    return "\n".join(lines)


def write_results(results: Sequence[EpisodeResult], out_dir: str | os.PathLike[str]) -> list[Path]:
    """eval.csv (one row per episode) and eval.md (`summary_table()` of the tests alone,
    `race_table()` of those with opponents) in ``out_dir``."""
    out = Path(out_dir)
    claim_folder(out)
    csv_path, md_path = out / "eval.csv", out / "eval.md"
    with writable(csv_path).open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, list(EpisodeResult.__dataclass_fields__))
        writer.writeheader()
        for r in results:
            row: dict[str, Any] = asdict(r)
            row["lap_times"] = " ".join(f"{x:g}" for x in r.lap_times)
            writer.writerow(row)
    alone = [r for r in results if not r.opponents]
    text = summary_table(alone) + "\n" if alone else ""
    if len(alone) < len(results):
        text += (
            ("\n" if text else "")
            + "Races (contacts by kind, overtakes = rank gains):\n\n"
            + race_table(results)
            + "\n"
        )
    writable(md_path).write_text(text, encoding="utf-8")
    return [csv_path, md_path]


def learning_curve(
    curves: dict[str, str | os.PathLike[str]], path: str | os.PathLike[str], window: int = 10
) -> Path:
    """Plot progress per training episode against timesteps (running mean over ``window``
    episodes) for each ``name -> learning.csv``; returns the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from racecar_sim.file_guard import writable

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
    out = writable(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)  # as mcl.experiments.plots
    plt.close(fig)
    return out
