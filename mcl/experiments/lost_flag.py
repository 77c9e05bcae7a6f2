"""The lost-flag experiment: is ``info["localization"]["lost"]`` right, and does the filter find the
car again after a kidnap?

Per world (map, filter map, env settings), two kinds of drives with the wall follower and the
filter's settings as given (the defaults unless changed): ``tracking`` drives (the filter starts
around the truth; in the honest world it loses the car by itself now and then) and ``kidnap``
drives (the car is teleported at ``kidnap_time`` to a random free pose at least 2 m away,
[`KidnapScenario`][mcl.experiments.scenarios.KidnapScenario]). Every step's ``lost`` column of the error
log is judged as a classifier against the truth ``position_error > 1 m``:

- precision: share of the lost steps that were more than 1 m off;
- recall: share of the steps more than 1 m off that were flagged lost;
- false alarms: share of the steps less than 0.3 m off that were flagged lost;
- time to flag (kidnap): seconds from the kidnap to the first lost step;
- time to recover (kidnap): seconds from the kidnap until the error is below 0.5 m and stays
  there for ``hold_s`` (or to the end of the run).

Output folder: ``config.json``, ``logs/<run_id>.csv`` (+ ``.json``: the scenario's outcome),
``results.md`` (the table, and one line per kidnap run).
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from mcl.experiments.recovery import run_recovery_safely
from mcl.experiments.runner import run_pending
from mcl.experiments.runs import RunResult, RunSpec
from mcl.wrappers.error_log import ErrorLog, read_error_log
from mcl.wrappers.localization import LocalizationConfig
from racecar_sim.file_guard import writable

__all__ = [
    "BAD_M",
    "GOOD_M",
    "RECOVERED_M",
    "LostFlagConfig",
    "World",
    "default_worlds",
    "kidnap_times",
    "run_lost_flag",
    "step_scores",
    "time_to_find",
]

BAD_M = 1.0
"""Metres of position error from which the filter has lost the car (the truth the flag is judged by)."""
GOOD_M = 0.3
"""Metres of position error below which a raised flag is a false alarm."""
RECOVERED_M = 0.5
"""Metres of position error under which a kidnapped filter counts as having found the car again."""


@dataclass(frozen=True)
class World:
    """One world of the experiment.

    Attributes:
        name: the table's label.
        map: the world the car drives in (bundled name or YAML path).
        filter_map: the map the filter holds (None: ``map``).
        env: RacecarEnv settings as (name, value) pairs (noise profile, scene).
        tracking: run tracking drives here (the kidnap drives always run).
    """

    name: str
    map: str
    filter_map: str | None = None
    env: tuple[tuple[str, str], ...] = ()
    tracking: bool = True


def default_worlds(
    shared: str | os.PathLike[str] = "../shared", filter_map: str | os.PathLike[str] | None = None
) -> tuple[World, ...]:
    """The honest world (cluttered and clean scenes, ``mit_racecar`` noise, the Stata map out of
    date in the filter) from ``shared``, and the bundled ``basement_loop`` (ideal; kidnaps only).
    ``filter_map``: the map the honest world's filter holds instead of ``stata_basement.yaml``
    (one brought up to date by ``racecar-sim update-map``, in the same world frame)."""
    maps = Path(shared) / "maps"
    world = str(maps / "basement_fixed_aligned.yaml")
    held = str(maps / "stata_basement.yaml") if filter_map is None else str(filter_map)
    honest = (("noise_profile", "mit_racecar"),)
    return (
        World("cluttered", world, held, (*honest, ("scene", "cluttered"))),
        World("clean", world, held, (*honest, ("scene", "clean"))),
        World("basement_loop", "basement_loop", tracking=False),
    )


@dataclass(frozen=True)
class LostFlagConfig:
    """The experiment (module docstring).

    Attributes:
        worlds: the worlds.
        seeds: tracking seeds (0, 1, ...). kidnap_seeds: kidnap seeds per world.
        duration: seconds of a tracking drive.
        kidnap_time: seconds after reset at which the car is kidnapped.
        after_kidnap: seconds driven after the kidnap.
        hold_s: seconds the error must stay under 0.5 m for the car to count as found again.
        localization: the filter's settings (defaults: the library's).
        filter_seed_offset: the filter of the drive with seed ``s`` is seeded by ``s +
            filter_seed_offset`` (0: by ``s``, as the env): the same drives with another draw of
            the filter's random numbers ([RunSpec][mcl.experiments.runs.RunSpec]'s
            ``filter_seed``).
    """

    worlds: tuple[World, ...] = field(default_factory=default_worlds)
    seeds: int = 10
    kidnap_seeds: int = 5
    duration: float = 60.0
    kidnap_time: float = 10.0
    after_kidnap: float = 20.0
    hold_s: float = 2.0
    localization: LocalizationConfig = field(default_factory=LocalizationConfig)
    filter_seed_offset: int = 0

    def runs(self) -> list[RunSpec]:
        """Every drive: per world its tracking seeds, then its kidnap seeds."""
        loc = self.localization
        off = self.filter_seed_offset

        def draw(seed: int) -> dict[str, int | None]:
            return {"seed": seed, "filter_seed": seed + off if off else None}

        out = []
        for w in self.worlds:
            common = dict(
                map=w.map, filter_map=w.filter_map, env=w.env, config=loc, motion=loc.motion,
                n_particles=loc.filter.n_particles,
            )  # fmt: skip
            if w.tracking:
                out += [RunSpec(scenario="tracking", **draw(s), duration=self.duration,
                                series=f"{w.name}_tracking", **common) for s in range(self.seeds)]  # fmt: skip
            out += [
                RunSpec(scenario="kidnap", **draw(s), duration=self.kidnap_time + self.after_kidnap,
                        series=f"{w.name}_kidnap",
                        scenario_settings=(("kidnap_time", self.kidnap_time),), **common)
                for s in range(self.kidnap_seeds)
            ]  # fmt: skip
        return out


def step_scores(log: ErrorLog) -> dict[str, int]:
    """Counts of steps for the classifier's figures: ``lost``, ``bad`` (> 1 m), ``lost_bad``,
    ``good`` (< 0.3 m), ``lost_good``, ``steps``."""
    err, lost = log.position_error, np.asarray(log.lost, dtype=np.bool_)
    bad, good = err > BAD_M, err < GOOD_M
    return {
        "steps": int(err.size),
        "lost": int(lost.sum()),
        "bad": int(bad.sum()),
        "lost_bad": int((lost & bad).sum()),
        "good": int(good.sum()),
        "lost_good": int((lost & good).sum()),
    }


def kidnap_times(log: ErrorLog, kidnap_at: float, hold_s: float) -> tuple[float, float]:
    """(seconds from the kidnap to the first lost step, seconds from the kidnap until the error is
    under [RECOVERED_M][mcl.experiments.lost_flag.RECOVERED_M] for ``hold_s`` or to the end);
    NaN for what never happened."""
    t, lost = log.time, np.asarray(log.lost, dtype=np.bool_)
    flagged = np.flatnonzero((t > kidnap_at + 1e-9) & lost)
    to_flag = float(t[flagged[0]] - kidnap_at) if flagged.size else math.nan
    return to_flag, time_to_find(t, log.position_error, kidnap_at, hold_s)


def time_to_find(time: np.ndarray, error: np.ndarray, kidnap_at: float, hold_s: float) -> float:
    """Seconds from ``kidnap_at`` until the position error (metres, one per step of ``time``,
    seconds) is under [RECOVERED_M][mcl.experiments.lost_flag.RECOVERED_M] and stays there for
    ``hold_s`` seconds or to the end of the drive; NaN when that never happens."""
    t, err = np.asarray(time, dtype=np.float64), np.asarray(error, dtype=np.float64)
    # the row at kidnap_at is the step before the teleport
    idx = np.flatnonzero((t > kidnap_at + 1e-9) & (err < RECOVERED_M))
    if not idx.size:
        return math.nan
    # the last step of each run of steps below: a step counts when its run lasts hold_s or ends the log
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts, ends = np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]]
    ok = (t[ends] - t[starts] >= hold_s - 1e-9) | (ends == t.size - 1)
    return float(t[starts[np.argmax(ok)]] - kidnap_at) if ok.any() else math.nan


def _ratio(a: int, b: int) -> str:
    return "–" if b == 0 else f"{a / b:.3f}"


def _times(values: list[float], limit: float) -> str:
    v = np.asarray(values, dtype=np.float64)
    done = v[np.isfinite(v) & (v <= limit)]
    if v.size == 0:
        return "–"
    if done.size == 0:
        return f"0/{v.size}"
    return f"{done.size}/{v.size}; median {np.median(done):.2f} s, max {np.max(done):.2f} s"


def _table(config: LostFlagConfig, results: list[RunResult]) -> str:
    lines = [
        "| world | drives | steps | mean error (m) | > 1 m | precision | recall | false alarms "
        "(err < 0.3 m) | flagged within 2 s | under 0.5 m within 15 s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    per_run = ["", "| run | kidnapped at (s) | time to flag (s) | time to recover (s) |",
               "|---|---:|---:|---:|"]  # fmt: skip
    groups: dict[str, list[RunResult]] = {}
    for r in results:
        groups.setdefault(r.spec.series, []).append(r)
    for series, runs in groups.items():
        totals = dict.fromkeys(("steps", "lost", "bad", "lost_bad", "good", "lost_good"), 0)
        errors, flags, recovers, failed = [], [], [], 0
        for r in runs:
            if r.status == "failed" or not r.log_path.is_file():
                failed += 1
                continue
            log = read_error_log(r.log_path)
            for k, v in step_scores(log).items():
                totals[k] += v
            errors.append(float(np.mean(log.position_error)))
            if r.spec.scenario == "kidnap":
                at = float(r.outcome.get("lost_at", math.nan))
                f, rec = (
                    kidnap_times(log, at, config.hold_s) if math.isfinite(at) else (math.nan,) * 2
                )
                flags.append(f)
                recovers.append(rec)
                per_run.append(f"| {r.spec.run_id} | {at:.2f} | {f:.2f} | {rec:.2f} |")
        kidnap = runs[0].spec.scenario == "kidnap"
        lines.append(
            f"| {series} | {len(runs) - failed}{f' ({failed} failed)' if failed else ''} | "
            f"{totals['steps']} | {np.mean(errors) if errors else math.nan:.3f} | "
            f"{_ratio(totals['bad'], totals['steps'])} | {_ratio(totals['lost_bad'], totals['lost'])} | "
            f"{_ratio(totals['lost_bad'], totals['bad'])} | "
            f"{_ratio(totals['lost_good'], totals['good'])} | "
            f"{_times(flags, 2.0) if kidnap else '–'} | {_times(recovers, 15.0) if kidnap else '–'} |"
        )
    return "\n".join(lines + per_run) + "\n"


def run_lost_flag(
    config: LostFlagConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
    stream: TextIO | None = None,
) -> str:
    """Run every drive of ``config`` into ``out_dir`` and write ``results.md``; returns its table."""
    out = Path(out_dir)

    def reuse(spec: RunSpec, path: Path) -> RunResult | None:
        outcome = path.with_suffix(".json")
        if not (outcome.is_file() and path.is_file()) or len(read_error_log(path)) != spec.n_steps:
            return None
        return RunResult(spec=spec, status="skipped", stats=None, log_path=path,
                         outcome=json.loads(outcome.read_text(encoding="utf-8")))  # fmt: skip

    results = run_pending(
        config, config.runs(), out, workers=workers, resume=resume, reuse=reuse,
        progress=progress, stream=stream if stream is not None else sys.stderr,
        runner=run_recovery_safely,
    )  # fmt: skip
    table = _table(config, results)
    writable(out / "results.md").write_text(table, encoding="utf-8")
    return table
