"""Our filter against nav2's amcl on the same recorded drives: ``racecar-sim bench peers --only amcl``.

Workload: the car follows the right wall for 60 s in a world that is not the filter's map (the
Stata floor as edited later, ``basement_fixed_aligned.yaml``, against ``stata_basement.yaml``),
seeds 0..N-1 (``--seeds``), in three worlds ([WORLDS][mcl.bench.amcl_bench.WORLDS]): the honest
world (``mit_racecar`` lidar and odometry) with the ``cluttered`` scene and with the ``clean``
one, and the ideal world (the simulator's own sensor settings, no scene); and on request the two
honest worlds with a kidnap (``cluttered_kidnap``, ``clean_kidnap``: at 10 s the car is carried to
a random free pose at least 2 m away without telling the filters, the kidnap `racecar-sim
lost-flag` makes in its kidnap drive of the same seed). Each drive is recorded
once ([record_drive][mcl.experiments.recorded.record_drive]) and fed to our filter (default
[LocalizationConfig][mcl.wrappers.localization.LocalizationConfig], through
[localize_recorded][mcl.experiments.recorded.localize_recorded]) and to amcl twice
([mcl.bench.peer_amcl][]): nav2's defaults, and the same with the recovery on (alpha_slow 0.001,
alpha_fast 0.1). All three start around the true start pose (standard deviations 0.25 m, 0.25 m,
0.1 rad).

Per seed: mean position error and the percentage of the time it exceeds 1 m (in a kidnap world,
the seconds from the kidnap until the error is under 0.5 m for 2 s); per world and filter: the
median of the means and the runs lost (more than 2 % of the time over 1 m), and in the kidnap
worlds how many kidnapped cars each filter found within 15 s. Printed as
markdown and written to ``--out`` (``amcl_results.csv``, ``amcl_results.md``; recorded drives are
kept in ``--out/drives`` and reused when the same drive is asked again; the rows already in
``amcl_results.csv`` are kept and a filter runs on a drive only when its row of that world and
seed is missing, so a run cut short continues where it stopped).

``--amcl-rerun ours`` (any of [FILTERS][mcl.bench.amcl_bench.FILTERS]) drops the named filters'
rows of the worlds and seeds asked and runs only those filters again, on the recorded drives,
keeping the others' rows: after a change of our defaults, ``racecar-sim bench peers --only amcl
--amcl-worlds cluttered clean --amcl-rerun ours --out DIR`` reruns ours alone (amcl's
subprocesses are not even started). Deleting a filter's rows from ``amcl_results.csv`` by hand
does the same; a rerun cut short continues when called again without ``--amcl-rerun``.
"""

from __future__ import annotations

import csv
import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from mcl.bench import shared_dir
from mcl.experiments.lost_flag import time_to_find
from mcl.experiments.recorded import LocalizedRun, RecordedDrive, localize_recorded, record_drive
from mcl.wrappers.localization import LocalizationConfig

__all__ = [
    "FILTERS",
    "LOST_SHARE",
    "WORLDS",
    "MixedMaps",
    "World",
    "calibrated",
    "lost",
    "read_rows",
    "results_md",
    "run_benchmark",
    "summary_md",
]

LOST_SHARE = 0.02
"""A run is lost when its error exceeds 1 m more than this share of the time."""
KIDNAP_AT = 10.0
"""Seconds after the reset at which the kidnap worlds' car is carried away (as `lost-flag`'s)."""
FOUND_WITHIN_S = 15.0
"""A kidnapped car counts as found when the error is under 0.5 m for ``FOUND_HOLD_S`` within this
many seconds of the kidnap (the lost flag's target)."""
FOUND_HOLD_S = 2.0
"""Seconds the error must stay under 0.5 m for a kidnapped car to count as found (as `lost-flag`)."""
FILTERS: tuple[str, ...] = ("ours", "amcl", "amcl_recovery")
"""The filters compared: our default filter, amcl with nav2's defaults, amcl with recovery on."""


@dataclass(frozen=True)
class World:
    """Where the drives happen: the world map (a ``../shared/maps`` file), scene, noise profile,
    and the seconds after the reset at which the car is kidnapped (None: never; the kidnap of
    `racecar-sim lost-flag`'s drive of the same seed,
    [record_drive][mcl.experiments.recorded.record_drive]'s ``kidnap_at``)."""

    world_map: str
    scene: str | None
    noise_profile: str | None
    kidnap_at: float | None = None


WORLDS: dict[str, World] = {
    "cluttered": World("basement_fixed_aligned.yaml", "cluttered", "mit_racecar"),
    "clean": World("basement_fixed_aligned.yaml", "clean", "mit_racecar"),
    "ideal": World("basement_fixed_aligned.yaml", None, None),
    "cluttered_kidnap": World("basement_fixed_aligned.yaml", "cluttered", "mit_racecar", KIDNAP_AT),
    "clean_kidnap": World("basement_fixed_aligned.yaml", "clean", "mit_racecar", KIDNAP_AT),
}
"""The worlds by name; the filters all hold ``stata_basement.yaml``."""
FILTER_MAP = "stata_basement.yaml"
"""The map the filters hold unless told another (a ``../shared/maps`` file)."""
MAP_NOTE = "filter_map.txt"
"""The file in ``--out`` naming the map its rows were made on."""


class MixedMaps(ValueError):
    """``--out`` holds rows of filters on another map than the one asked for."""


def lost(errors: np.ndarray) -> bool:
    """Whether a run is lost (errors in metres over 1 m more than [LOST_SHARE][mcl.bench.amcl_bench.LOST_SHARE] of the steps)."""
    return float(np.mean(np.asarray(errors) > 1.0)) > LOST_SHARE


def _row(world: str, seed: int, name: str, run: LocalizedRun, cpu_s: float,
         drive: RecordedDrive) -> dict[str, Any]:  # fmt: skip
    e = run.position_error
    at = (drive.settings or {}).get("kidnap_at")
    found = None if at is None else time_to_find(drive.time, e, at, FOUND_HOLD_S)
    return {
        "world": world, "seed": seed, "filter": name,
        "mean_error_m": float(e.mean()), "p95_error_m": float(np.percentile(e, 95)),
        "max_error_m": float(e.max()), "pct_over_1m": 100.0 * float(np.mean(e > 1.0)),
        "lost": lost(e), "cpu_s": cpu_s, "found_s": found,
    }  # fmt: skip


def _drive(out: Path, world: str, seed: int, duration: float, maps: Path) -> RecordedDrive:
    """The recorded drive of ``world`` and ``seed``: from ``out/drives`` when made before with the
    same settings, else recorded and saved there."""
    spec = WORLDS[world]
    path = out / "drives" / f"{world}_seed{seed}_{duration:g}s.npz"
    if path.is_file():
        drive = RecordedDrive.load(path)
        s = drive.settings or {}
        made = (s.get("scene"), s.get("noise_profile"), s.get("seed"), s.get("duration"))
        if made == (spec.scene, spec.noise_profile, seed, duration) and (
            s.get("kidnap_at") is None
        ) == (spec.kidnap_at is None):
            return drive
    drive = record_drive(
        str(maps / spec.world_map), filter_map=str(maps / FILTER_MAP), scene=spec.scene,
        noise_profile=spec.noise_profile, driver="wall", seed=seed, duration=duration,
        kidnap_at=spec.kidnap_at,
    )  # fmt: skip
    drive.save(path)
    return drive


def calibrated(drive: RecordedDrive, config: LocalizationConfig) -> RecordedDrive:
    """``drive`` with its odometry as our filter's calibration (``config.filter.odometry_bias``)
    undoes it, for amcl, which has no such setting: both filters get the same calibration; the
    drive itself when the calibration is zero."""
    bias = config.filter.odometry_bias
    if bias.is_zero:
        return drive
    return replace(drive, odom=bias.unbiased(np.asarray(drive.odom, dtype=np.float64)))


def run_benchmark(
    python: str,
    worlds: Sequence[str],
    seeds: int,
    duration: float,
    out: Path,
    config: LocalizationConfig | None = None,
    echo: Callable[[str], None] = print,
    rerun: Sequence[str] = (),
    filter_map: Path | None = None,
) -> list[dict[str, Any]]:
    """Record the drives, run the three filters, write ``out/amcl_results.{csv,md}`` as rows come
    in; returns the rows (one per world, seed and filter).

    A filter runs on a drive only when ``amcl_results.csv`` has no row of that world, seed and
    filter; ``rerun`` (names from [FILTERS][mcl.bench.amcl_bench.FILTERS]) first drops those
    filters' rows of ``worlds`` and seeds 0..``seeds``-1, so they run again on the recorded drives
    while the other filters' rows stay. amcl's subprocesses start only when an amcl row is missing.
    A calibration in ``config`` (``filter.odometry_bias``) is given to amcl too
    ([calibrated][mcl.bench.amcl_bench.calibrated]). ``filter_map`` (a map YAML; None:
    ``../shared/maps/stata_basement.yaml``) is the map all three filters hold, e.g. one updated
    from earlier drives ([update_from_drives][mcl.mapping.update.update_from_drives]); ``out``
    remembers it in ``filter_map.txt`` and its rows are never mixed with another map's.

    Raises:
        ValueError: an unknown filter in ``rerun``.
        MixedMaps: ``out`` holds rows made on another map.
    """
    from mcl.bench.amcl_inputs import amcl_grid
    from mcl.bench.peer_amcl import NAV2_DEFAULTS, WITH_RECOVERY, AmclParams, AmclPeer
    from racecar_sim.maps import load_map

    unknown = sorted(set(rerun) - set(FILTERS))
    if unknown:
        raise ValueError(f"rerun: unknown filters {unknown}; the filters are {list(FILTERS)}")
    maps = shared_dir() / "maps"
    config = config or LocalizationConfig()
    map_path = (Path(filter_map) if filter_map is not None else maps / FILTER_MAP).resolve()
    _check_same_map(out, map_path, maps / FILTER_MAP)
    map_name = map_path.name
    filter_map = load_map(map_path)
    out.mkdir(parents=True, exist_ok=True)
    (out / MAP_NOTE).write_text(f"{map_path}\n")
    params: dict[str, AmclParams] = {"amcl": NAV2_DEFAULTS, "amcl_recovery": WITH_RECOVERY}
    peers: dict[str, AmclPeer] = {}

    def peer(name: str) -> AmclPeer:  # started on first use: a rerun of ours alone needs none
        if name not in peers:
            peers[name] = AmclPeer(python, amcl_grid(filter_map), params[name], out / "work")
        return peers[name]

    rows: list[dict[str, Any]] = []
    waiting: list[tuple[str, int, list[str], RecordedDrive]] = []

    def collect() -> None:
        world, seed, names, drive = waiting.pop(0)
        for name in names:
            run, cpu = peers[name].collect()
            rows.append(_row(world, seed, name, run, cpu, drive))
        _write(out, rows, seeds, duration, worlds, map_name)
        mine = {r["filter"]: r for r in rows if (r["world"], r["seed"]) == (world, seed)}
        echo(f"{world} seed {seed}: " + ", ".join(
            f"{n} {mine[n]['mean_error_m']:.3f} m ({mine[n]['pct_over_1m']:.1f} % > 1 m)"
            for n in FILTERS if n in mine))  # fmt: skip

    rows += [  # every world and seed stays in the file, but for the rows asked to run again
        r for r in read_rows(out / "amcl_results.csv")
        if not (r["filter"] in rerun and r["world"] in worlds and r["seed"] < seeds)
    ]  # fmt: skip
    have = {(r["world"], r["seed"], r["filter"]) for r in rows}
    if rows:
        echo(f"kept {len(rows)} rows (world, seed, filter) from {out / 'amcl_results.csv'}")
    try:
        for seed in range(seeds):  # seeds outside: a run cut short still covers every world
            for world in worlds:
                todo = [n for n in FILTERS if (world, seed, n) not in have]
                if not todo:
                    continue
                drive = _drive(out, world, seed, duration, maps)
                names = [n for n in todo if n in params]
                for name in names:
                    peer(name).submit(calibrated(drive, config), seed, config.filter.init_spread)
                if "ours" in todo:
                    t0 = time.process_time()
                    ours = localize_recorded(drive, config, filter_map, seed)
                    rows.append(_row(world, seed, "ours", ours, time.process_time() - t0, drive))
                waiting.append((world, seed, names, drive))
                if len(waiting) > 1:  # amcl works on this drive while the next one is recorded
                    collect()
        while waiting:
            collect()
        if rows:  # the report of the rows kept, when nothing was left to run
            _write(out, rows, seeds, duration, worlds, map_name)
    finally:
        for p in peers.values():
            p.close()
    return rows


def _check_same_map(out: Path, map_path: Path, default: Path) -> None:
    """Stop when ``out`` holds rows of filters on a map other than ``map_path`` (a folder with
    rows and no ``filter_map.txt`` was made on ``default``)."""
    if not read_rows(out / "amcl_results.csv"):
        return
    note = out / MAP_NOTE
    held = Path(note.read_text().strip()) if note.is_file() else default.resolve()
    if held != map_path:
        raise MixedMaps(f"{out} holds rows of filters on {held}; give another folder for the "
                         f"filters on {map_path}")  # fmt: skip


def read_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of an ``amcl_results.csv`` written before (none when it is absent)."""
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["seed"] = int(r["seed"])
        r["lost"] = r["lost"] == "True"
        for key in ("mean_error_m", "p95_error_m", "max_error_m", "pct_over_1m", "cpu_s"):
            r[key] = float(r[key])
        found = r.get("found_s") or None  # none for a drive without a kidnap (and older files)
        r["found_s"] = None if found is None else float(found)
    return rows


def _write(out: Path, rows: list[dict[str, Any]], seeds: int, duration: float,
           worlds: Sequence[str], map_name: str = FILTER_MAP) -> None:  # fmt: skip
    with open(out / "amcl_results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out / "amcl_results.md").write_text(results_md(rows, seeds, duration, worlds, map_name))


def per_seed_md(rows: list[dict[str, Any]], world: str) -> str:
    """The per-seed table of ``world``: mean error (m) and % of time over 1 m of each filter; in a
    kidnap world, mean error and seconds from the kidnap until the car was found ("never")."""
    kidnap = WORLDS[world].kidnap_at is not None
    second = "found after (s)" if kidnap else "> 1 m (%)"
    head = "| seed | " + " | ".join(f"{n} mean (m) | {n} {second}" for n in FILTERS) + " |"
    lines = [head, "|" + "---|" * (1 + 2 * len(FILTERS))]
    by = {(r["seed"], r["filter"]): r for r in rows if r["world"] == world}
    for seed in sorted({s for s, _ in by}):
        cells = []
        for n in FILTERS:
            r = by.get((seed, n))
            if r is None:
                cells += ["–", "–"]
                continue
            if kidnap:
                found = r["found_s"]
                second = "never" if found is None or math.isnan(found) else f"{found:.2f}"
            else:
                second = f"{r['pct_over_1m']:.1f}"
            cells += [f"{r['mean_error_m']:.3f}", second]
        lines.append(f"| {seed} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def summary_md(rows: list[dict[str, Any]]) -> str:
    """Per world and filter: runs, median of the mean errors, runs lost, mean % over 1 m."""
    lines = ["| world | filter | runs | median of means (m) | runs lost (> 2 % over 1 m) | "
             "mean time over 1 m (%) | median CPU s per run |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for world in dict.fromkeys(r["world"] for r in rows):
        for n in FILTERS:
            mine = [r for r in rows if r["world"] == world and r["filter"] == n]
            if not mine:
                continue
            lines.append(
                f"| {world} | {n} | {len(mine)} | "
                f"{statistics.median(r['mean_error_m'] for r in mine):.3f} | "
                f"{sum(r['lost'] for r in mine)}/{len(mine)} | "
                f"{statistics.fmean(r['pct_over_1m'] for r in mine):.1f} | "
                f"{statistics.median(r['cpu_s'] for r in mine):.1f} |"
            )
    return "\n".join(lines)


def kidnaps_md(rows: list[dict[str, Any]]) -> str:
    """Per kidnap world and filter: kidnaps, how many were found within
    [FOUND_WITHIN_S][mcl.bench.amcl_bench.FOUND_WITHIN_S] (error under 0.5 m for
    [FOUND_HOLD_S][mcl.bench.amcl_bench.FOUND_HOLD_S]), and the median and longest time to find
    of those; empty when ``rows`` hold no kidnap world."""
    lines = [f"| world | filter | kidnaps | found within {FOUND_WITHIN_S:g} s | median time to "
             "find (s) | longest (s) |", "|---|---|---|---|---|---|"]  # fmt: skip
    for world in dict.fromkeys(r["world"] for r in rows):
        if WORLDS[world].kidnap_at is None:
            continue
        for n in FILTERS:
            times = [math.nan if r["found_s"] is None else r["found_s"]
                     for r in rows if r["world"] == world and r["filter"] == n]  # fmt: skip
            found = [t for t in times if t <= FOUND_WITHIN_S]  # NaN (never) compares False
            if not times:
                continue
            middle = f"{statistics.median(found):.2f} | {max(found):.2f}" if found else "– | –"
            lines.append(f"| {world} | {n} | {len(times)} | {len(found)}/{len(times)} | {middle} |")
    return "\n".join(lines) if len(lines) > 2 else ""


def results_md(rows: list[dict[str, Any]], seeds: int, duration: float,
               worlds: Sequence[str] | None = None, map_name: str = FILTER_MAP) -> str:  # fmt: skip
    """The whole report of seeds 0..``seeds``-1 in ``worlds`` (None: all), the filters holding
    the map file ``map_name``: workload, summary, per-seed tables."""
    rows = [r for r in rows if r["seed"] < seeds and (worlds is None or r["world"] in worlds)]
    rows.sort(key=lambda r: (list(WORLDS).index(r["world"]), r["seed"], FILTERS.index(r["filter"])))
    parts = [
        "# Our filter vs nav2 amcl on the same drives",
        "",
        f"Wall follower, {duration:g} s per drive, seeds 0..{seeds - 1}, world "
        f"basement_fixed_aligned.yaml, filters on {map_name}, all started around the true "
        "start pose (sd 0.25 m, 0.25 m, 0.1 rad). ours: default LocalizationConfig; amcl: nav2 "
        "defaults, beam model (the bindings' only one); amcl_recovery: the same with "
        "recovery_alpha_slow 0.001, recovery_alpha_fast 0.1. cluttered / clean: mit_racecar "
        "noise profile with that scene; ideal: no profile, no scene; cluttered_kidnap / "
        f"clean_kidnap: as cluttered / clean, the car carried at {KIDNAP_AT:g} s to a random free "
        "pose 2 m or more away (racecar-sim lost-flag's kidnap of the same seed), found when "
        f"under 0.5 m for {FOUND_HOLD_S:g} s.",
        "",
        "## Summary",
        "",
        summary_md(rows),
    ]
    kidnaps = kidnaps_md(rows)
    if kidnaps:
        parts += ["", f"## Kidnaps (the car carried away at {KIDNAP_AT:g} s)", "", kidnaps]
    for world in dict.fromkeys(r["world"] for r in rows):
        parts += ["", f"## {world}: per seed", "", per_seed_md(rows, world)]
    return "\n".join(parts) + "\n"
