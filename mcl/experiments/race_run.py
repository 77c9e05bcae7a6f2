"""A race of N cars on a map's track, every car driven by one of the project's drivers, with an
optional particle filter per car: what ``racecar-sim race`` runs.

[`run_race`][mcl.experiments.race_run.run_race] builds a
[`racecar_sim.RaceEnv`][racecar_sim.race.env.RaceEnv] (cars keep racing after a contact:
``terminate_on_collision=False``; contacts are counted), wraps it in
``mcl.wrappers.race.LocalizedRaceEnv`` when ``localize`` (each car
then drives on its own MCL estimate, started around its true start pose), puts the cars on the
track's start grid in the order ``grid`` asks for, builds each car's driver with
[make_driver][mcl.experiments.race_drivers.make_driver] and steps the race for ``duration`` seconds,
or until the first car completes ``laps`` laps. With ``racing`` drivers the race keeps a
[Traffic][racecar_sim.race.traffic.Traffic] picture of every car on the track (from the true
poses, ``RaceEnv.poses``), reset after the race's reset and updated after every step, as
``RacecarRace-v0`` does; the racing drivers read it. The result has, per car: its finishing
position (race order by distance covered along the centerline, ``racecar_sim.world.laps``), laps,
lap times, overtakes and times overtaken (rank gains and losses in race order), wall and car
contacts (separate contacts; all four counted by
[RaceTally][mcl.agents.race_tally.RaceTally]) and, localized, the mean and largest position
error of its filter.

Grid orders: ``slowest-first`` (the default: the faster cars come up behind the slower ones and
have to pass, for drivers that can: ``racing``), ``fastest-first`` (the fastest car on pole, so
that cars that do not know each other do not run into a slower car ahead at the start),
``listed`` (car 0 on pole, then car 1, ...). With a ``racing`` driver in the race the grid stands
single file on the centerline, as ``RacecarRace-v0``'s (a staggered grid of cars at different
speeds leaves in two lanes); otherwise staggered.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mcl.agents.race_tally import RaceTally
from mcl.experiments.race_drivers import DriverSpec, drive_pose, knows_the_others, make_driver

__all__ = [
    "GRID_ORDERS",
    "CarResult",
    "RaceResult",
    "RaceSetup",
    "RaceSpec",
    "RaceState",
    "grid_order",
    "run_race",
    "setup_race",
    "start_poses",
]

GRID_ORDERS: tuple[str, ...] = ("slowest-first", "fastest-first", "listed")
"""How the cars stand on the start grid (module doc)."""


@dataclass(frozen=True)
class RaceSpec:
    """One race.

    Attributes:
        map: a bundled map name or a map YAML path.
        drivers: one per car (its length is the number of cars).
        speeds: m/s, one per car: the wall follower's speed on a straight, pure pursuit's speed,
            the most a policy is given.
        duration: simulated seconds at most.
        laps: end the race when the first car completes this many laps (None: run ``duration``).
        track: a centerline CSV (None: the map's own, for the bundled loop maps).
        grid: one of [`GRID_ORDERS`][mcl.experiments.race_run.GRID_ORDERS].
        localize: a particle filter per car; the cars drive on their estimates.
        particles: particles per filter.
        seed: the race's seed (car ``i`` gets ``seed + i``).
        env: extra ``RacecarSim-v0`` settings (name, value), for every car.
    """

    map: str
    drivers: tuple[DriverSpec, ...]
    speeds: tuple[float, ...]
    duration: float = 60.0
    laps: int | None = None
    track: str | None = None
    grid: str = "slowest-first"
    localize: bool = False
    particles: int = 1000
    seed: int = 0
    env: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if len(self.speeds) != len(self.drivers):
            raise ValueError(f"{len(self.speeds)} speeds for {len(self.drivers)} cars")
        if self.grid not in GRID_ORDERS:
            raise ValueError(f"grid {self.grid!r}: one of {', '.join(GRID_ORDERS)}")

    @property
    def n_cars(self) -> int:
        """Cars in the race."""
        return len(self.drivers)


@dataclass
class CarResult:
    """One car's race (module doc); errors in metres (NaN without a filter)."""

    car: int
    driver: str
    speed: float
    grid_slot: int
    position: int = 0
    laps: int = 0
    lap_times: tuple[float, ...] = ()
    progress: float = 0.0
    overtakes: int = 0
    overtaken: int = 0
    wall_contacts: int = 0
    car_contacts: int = 0
    mean_error: float = math.nan
    max_error: float = math.nan

    @property
    def best_lap(self) -> float:
        """Seconds of the fastest completed lap (NaN before a lap is completed)."""
        return min(self.lap_times) if self.lap_times else math.nan


@dataclass
class RaceResult:
    """What [`run_race`][mcl.experiments.race_run.run_race] gives: the cars by finishing position,
    the simulated seconds raced, the steps, the wall-clock seconds, the track's length (m)."""

    cars: list[CarResult]
    seconds: float
    steps: int
    wall_time: float
    track_length: float
    spec: RaceSpec


@dataclass
class RaceState:
    """The race after a step, for a frame: time (s), each car's info and, localized, its
    estimate [x, y, theta] and a subsample of its particles (N, 3)."""

    time: float
    infos: dict[str, dict[str, Any]]
    estimates: dict[str, np.ndarray] = field(default_factory=dict)
    particles: dict[str, np.ndarray] = field(default_factory=dict)


def grid_order(speeds: tuple[float, ...], order: str) -> list[int]:
    """The cars from pole backwards (``order``: one of
    [`GRID_ORDERS`][mcl.experiments.race_run.GRID_ORDERS]; ties keep the listed order)."""
    cars = list(range(len(speeds)))
    if order == "fastest-first":
        return sorted(cars, key=lambda i: -speeds[i])
    if order == "slowest-first":
        return sorted(cars, key=lambda i: speeds[i])
    return cars


@dataclass
class RaceSetup:
    """A race ready to start: the env stepped (the race, or its LocalizedRaceEnv), the
    [`racecar_sim.RaceEnv`][racecar_sim.race.env.RaceEnv] itself, each car's driver and, with a
    ``racing`` driver, the [Traffic][racecar_sim.race.traffic.Traffic] picture it reads (else
    None)."""

    env: Any
    race: Any
    drivers: list[Any]
    traffic: Any = None


def setup_race(spec: RaceSpec, render: bool = False) -> RaceSetup:
    """Build the race of ``spec`` (``render``: frames for a video) and its drivers.

    Raises:
        ValueError: the map has no track, or a setting the race refuses.
        DriverError: a driver that cannot be built
            ([make_driver][mcl.experiments.race_drivers.make_driver]).
    """
    from racecar_sim.race.env import RaceEnv

    settings = {**dict(spec.env), "terminate_on_collision": False}
    race = RaceEnv(
        spec.map,
        n_cars=spec.n_cars,
        track=spec.track,
        render_mode="rgb_array" if render else None,
        **settings,
    )
    if race.track is None:
        raise ValueError(
            f"{spec.map}: a race needs a track: a bundled loop map (basement_loop, office) or a "
            "centerline CSV"
        )
    traffic = None
    if knows_the_others(spec.drivers):
        from racecar_sim.race.traffic import Traffic
        from racecar_sim.world.track import with_widths

        traffic = Traffic(with_widths(race.track, race.map), spec.n_cars, race.car_params)
    drivers = [
        make_driver(d, race, i, v, traffic)
        for i, (d, v) in enumerate(zip(spec.drivers, spec.speeds, strict=True))
    ]
    if not spec.localize:
        return RaceSetup(race, race, drivers, traffic)
    from mcl.filter.sensor_model import SensorModelParams
    from mcl.wrappers.localization import LocalizationConfig
    from mcl.wrappers.race import LocalizedRaceEnv

    config = LocalizationConfig(sensor=SensorModelParams(beam_skip=True))
    env = LocalizedRaceEnv(race, config.with_particles(spec.particles))
    return RaceSetup(env, race, drivers, traffic)


def start_poses(race: Any, spec: RaceSpec) -> np.ndarray:
    """(N, 3) rear-axle world poses of the cars on ``race``'s start grid in the spec's order
    (single file with a ``racing`` driver in the race, else staggered; module doc).

    Raises:
        ValueError: more cars than the track holds, or a slot without room for a car.
    """
    from racecar_sim.race.grid import start_grid

    stagger = {"stagger": 0.0} if knows_the_others(spec.drivers) else {}
    is_free = race.cars[0].physics.pose_is_free
    slots = start_grid(race.track, spec.n_cars, race.car_params, is_free, **stagger)
    poses = np.empty_like(slots)
    for slot, car in enumerate(grid_order(spec.speeds, spec.grid)):
        poses[car] = slots[slot]
    return poses


def run_race(
    spec: RaceSpec,
    setup: RaceSetup | None = None,
    *,
    on_frame: Callable[[np.ndarray, RaceState], None] | None = None,
    frame_every: int = 1,
    on_step: Callable[[Any, dict, dict], None] | None = None,
    progress: bool = False,
) -> RaceResult:
    """Race (module doc), on ``setup`` (default:
    [`setup_race`][mcl.experiments.race_run.setup_race], rendering when there is an ``on_frame``).
    ``on_frame(rgb frame, state)`` gets the race's ``render()`` after the reset and every
    ``frame_every`` steps; ``on_step(env, obs, infos)`` is called after the reset and every step.

    Raises:
        ValueError: as [`setup_race`][mcl.experiments.race_run.setup_race] and
            [`start_poses`][mcl.experiments.race_run.start_poses].
    """
    if setup is None:
        setup = setup_race(spec, render=on_frame is not None)
    env, race, drivers, traffic = setup.env, setup.race, setup.drivers, setup.traffic
    order = grid_order(spec.speeds, spec.grid)
    agents = list(race.possible_agents)
    for driver in drivers:
        reset = getattr(driver, "reset", None)
        if callable(reset):
            reset()
    obs, infos = env.reset(seed=spec.seed, options={"poses": start_poses(race, spec)})
    if traffic is not None:
        traffic.reset(race.poses)
    tallies = {a: RaceTally() for a in agents}
    for a in agents:
        tallies[a].begin(infos[a])
    errors: dict[str, list[float]] = {a: [] for a in agents}

    def observe(step: int) -> None:
        for a in agents:
            loc = infos[a].get("localization")
            if loc is not None:
                errors[a].append(float(loc["position_error"]))
        if on_step is not None:
            on_step(env, obs, infos)
        if on_frame is not None and step % frame_every == 0:
            on_frame(env.render(), _state(env, infos, spec.localize))

    observe(0)
    n_steps = max(1, round(spec.duration / race.dt))
    steps = range(1, n_steps + 1)
    if progress:
        from tqdm import tqdm

        steps = tqdm(steps, desc="race", unit="step", leave=False)
    t0 = time.perf_counter()
    done = 0
    for step in steps:
        actions = {
            a: drivers[i](obs[a], drive_pose(obs[a], infos[a], spec.localize))
            for i, a in enumerate(agents)
        }
        obs, _, _, _, infos = env.step(actions)
        if traffic is not None:
            traffic.update(race.poses, race.world.time)
        done = step
        for a in agents:
            tallies[a].update(infos[a])
        observe(step)
        if spec.laps is not None and max(infos[a]["lap"] for a in agents) >= spec.laps:
            break
    wall = time.perf_counter() - t0
    cars = []
    for i, a in enumerate(agents):
        info, counts = infos[a], tallies[a].counts()
        err = np.asarray(errors[a])
        cars.append(
            CarResult(
                car=i,
                driver=spec.drivers[i].name,
                speed=spec.speeds[i],
                grid_slot=order.index(i) + 1,
                position=int(info["rank"]),
                laps=int(info["lap"]),
                lap_times=tuple(float(t) for t in info["lap_times"]),
                progress=float(info["progress"]),
                overtakes=counts["overtakes"],
                overtaken=counts["overtaken"],
                wall_contacts=counts["wall_contacts"],
                car_contacts=counts["car_contacts"],
                mean_error=float(err.mean()) if err.size else math.nan,
                max_error=float(err.max()) if err.size else math.nan,
            )
        )
    cars.sort(key=lambda c: c.position)
    return RaceResult(cars, done * race.dt, done, wall, float(race.track.length), spec)


def _state(env: Any, infos: dict[str, dict[str, Any]], localized: bool) -> RaceState:
    state = RaceState(time=float(next(iter(infos.values()))["time"]), infos=infos)
    if localized:
        for agent, pf in env.filters.items():
            state.estimates[agent] = pf.estimate()
            stride = max(1, len(pf.particles) // 300)
            state.particles[agent] = pf.particles[::stride]
    return state
