"""A race of scripted cars only, counted: ``RacecarRace-v0`` with car 0 driven like its opponents.

[run_scripted_race][racecar_sim.race.scripted_race.run_scripted_race] races ``opponents`` racing
drivers ([RacingDriver][racecar_sim.race.racing_driver.RacingDriver]) at ``RacecarRace-v0``'s speeds
(2.0, 2.4, ... m/s, slowest on pole) and car 0 by the same driver at the next speed, starting last,
for ``seconds``; contacts do not end the race (``terminate_on_collision=False``), so every touch is
counted. The result holds each car's speed, laps and progress, the contacts (a contact is a pair of
cars, or a car and a wall, that starts touching), and the passes: a pass counts when one car's rear
axle gets a car length ahead of another's along the track, laps included (a car lapping a slower one
passes it too), so two cars side by side do not count passes back and forth.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from racecar_sim.race.racing_driver import RacingDriver
from racecar_sim.race.single import RacecarRaceEnv

__all__ = ["ScriptedRaceResult", "run_scripted_race"]

_GRID_GAP = 0.3  # metres between cars on the grid (start_grid's default)
_GRID_DRAWS = 50  # places tried for the grid


@dataclass(frozen=True)
class ScriptedRaceResult:
    """One scripted race (see the module doc); per-car tuples are by car index, car 0 first.

    Attributes:
        map: the map's name.
        opponents: scripted opponents (the race has ``opponents + 1`` cars).
        seed: the race's seed.
        seconds: simulated seconds raced.
        speeds: each car's top speed, m/s.
        laps: each car's completed laps.
        progress: each car's metres along the centerline since its start.
        car_contacts: contacts between two cars.
        wall_contacts: contacts between a car and a wall.
        passes: passes between cars (laps included).
    """

    map: str
    opponents: int
    seed: int
    seconds: float
    speeds: tuple[float, ...]
    laps: tuple[int, ...]
    progress: tuple[float, ...]
    car_contacts: int
    wall_contacts: int
    passes: int


def run_scripted_race(
    map: str,
    opponents: int,
    seed: int,
    seconds: float = 60.0,
    *,
    speeds: Sequence[float] | None = None,
    drawn: bool = True,
    speed_spread: float = 0.1,
    **settings: Any,
) -> ScriptedRaceResult:
    """Race ``opponents`` racing drivers and car 0 on ``map`` for ``seconds`` (module doc).

    Args:
        map: a map with a track (a bundled loop map).
        opponents: scripted opponents.
        seed: the race's seed (with ``drawn``, also where the grid stands and the speeds).
        seconds: simulated seconds.
        speeds: m/s per car, car 0 first (default: car 0 at ``2.0 + 0.4 opponents``, the
            opponents at ``RacecarRace-v0``'s 2.0, 2.4, ...).
        drawn: the grid stands behind a point of the track drawn from ``seed`` (kept off the
            half-lap point, where race order wraps), and each car's speed is drawn within
            ``speed_spread`` m/s of its default (not of given ``speeds``); without it the grid
            stands behind the start line, as in ``RacecarRace-v0``.
        speed_spread: m/s either side of the default speeds (keep it under 0.2: the default speeds
            are 0.4 m/s apart, so the cars stay in the same order of speed).
        settings: ``RacecarRace-v0`` settings (e.g. ``n_beams``).
    """
    rng = np.random.default_rng(seed)
    if speeds is None:
        speeds = np.array([2.0 + 0.4 * opponents, *(2.0 + 0.4 * k for k in range(opponents))])
        if drawn:
            speeds += rng.uniform(-speed_spread, speed_spread, len(speeds))
    speeds = np.asarray(speeds, dtype=np.float64)
    if speeds.shape != (opponents + 1,):
        raise ValueError(f"speeds: {opponents + 1} needed (car 0 first), got {speeds.shape}")
    env = RacecarRaceEnv(map, opponents=opponents, opponent_speeds=speeds[1:].tolist(),
                         terminate_on_collision=False, **settings)  # fmt: skip
    if env.traffic is None:
        raise ValueError(f"map {map!r}: a scripted race needs a track")
    n = opponents + 1
    agent = RacingDriver(env.traffic, 0, speed=float(speeds[0]))
    counter = env.race.laps
    assert counter is not None
    length, car_length = env.track.length, env.car_params.length
    pairs = np.triu_indices(n, 1)
    options = {"poses": _drawn_grid(env, rng)} if drawn else None
    obs, info = env.reset(seed=seed, options=options)
    settled = np.floor((counter.u[pairs[0]] - counter.u[pairs[1]]) / length)
    touching: set[tuple[str, str]] = set()
    car_contacts = wall_contacts = passes = 0
    try:
        for _ in range(max(1, round(seconds / env.race.dt))):
            obs, _, _, _, info = env.step(agent(obs, info["pose"]))
            now: set[tuple[str, str]] = set()
            for name, car_info in env.car_infos.items():
                now.update(tuple(sorted((name, other))) for other in car_info["contacts"])
            new = now - touching
            wall_contacts += sum(1 for pair in new if "wall" in pair)
            car_contacts += sum(1 for pair in new if "wall" not in pair)
            touching = now
            ahead = counter.u[pairs[0]] - counter.u[pairs[1]]
            k = np.floor(ahead / length)
            clear = (ahead - k * length >= car_length) & ((k + 1) * length - ahead >= car_length)
            changed = clear & (k != settled)
            passes += int(np.abs(k - settled)[changed].sum())
            settled = np.where(changed, k, settled)
    finally:
        env.close()
    infos = env.car_infos
    agents = [f"car_{i}" for i in range(n)]
    return ScriptedRaceResult(
        map=str(map),
        opponents=opponents,
        seed=seed,
        seconds=float(seconds),
        speeds=tuple(round(float(v), 3) for v in speeds),
        laps=tuple(int(infos[a]["lap"]) for a in agents),
        progress=tuple(round(float(infos[a]["progress"]), 2) for a in agents),
        car_contacts=car_contacts,
        wall_contacts=wall_contacts,
        passes=passes,
    )


def _drawn_grid(env: RacecarRaceEnv, rng: np.random.Generator) -> np.ndarray:
    """(N, 3) poses: the env's grid behind a drawn point of the track, clear of the half-lap
    point (where race order wraps)."""
    track, car = env.track, env.car_params
    assert track is not None
    span = len(env.grid_order) * (car.length + _GRID_GAP) + 1.0  # metres the grid covers
    for _ in range(_GRID_DRAWS):
        at = rng.uniform(0.0, track.length - span)
        if at >= track.length / 2:
            at += span
        try:
            return env.grid_at(at)
        except ValueError:  # no room for the grid there
            continue
    raise ValueError(f"no room for a grid of {len(env.grid_order)} cars in {_GRID_DRAWS} draws")


def speed_order(result: ScriptedRaceResult) -> list[int]:
    """The cars of ``result`` from the slowest to the fastest."""
    return sorted(range(len(result.speeds)), key=lambda i: result.speeds[i])


def ordered_share(result: ScriptedRaceResult) -> float:
    """The share of pairs of cars in which the faster one covered more metres (1: the race
    finished in order of speed)."""
    order = speed_order(result)
    progress = [result.progress[i] for i in order]
    pairs = [(a, b) for a in range(len(order)) for b in range(a + 1, len(order))]
    return sum(progress[b] > progress[a] for a, b in pairs) / max(len(pairs), 1)


def matrix_table(results: list[ScriptedRaceResult]) -> str:
    """A Markdown table of races grouped by map and opponents: contacts, passes, laps and
    metres per car from the slowest to the fastest (means over the races), and the share of
    pairs finishing in order of speed."""
    rows = [
        "| map | opponents | races | car contacts | wall contacts | passes per race (min-max) "
        "| laps per car, slowest to fastest | metres per car, slowest to fastest "
        "| pairs in speed order |",
        "|---|---:|---:|---:|---:|---|---|---|---:|",
    ]
    groups: dict[tuple[str, int], list[ScriptedRaceResult]] = {}
    for r in results:
        groups.setdefault((r.map, r.opponents), []).append(r)
    for (name, k), group in groups.items():
        laps = np.mean([[r.laps[i] for i in speed_order(r)] for r in group], axis=0)
        metres = np.mean([[r.progress[i] for i in speed_order(r)] for r in group], axis=0)
        passes = [r.passes for r in group]
        share = np.mean([ordered_share(r) for r in group])
        rows.append(
            f"| {name} | {k} | {len(group)} | {sum(r.car_contacts for r in group)} "
            f"| {sum(r.wall_contacts for r in group)} "
            f"| {np.mean(passes):.1f} ({min(passes)}-{max(passes)}) "
            f"| {' / '.join(f'{v:.1f}' for v in laps)} "
            f"| {' / '.join(f'{v:.0f}' for v in metres)} | {100 * share:.0f}% |"
        )
    return "\n".join(rows)
