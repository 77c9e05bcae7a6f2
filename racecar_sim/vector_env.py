"""Many cars in one process: ``gymnasium.make_vec("RacecarSim-v0", num_envs=N,
vectorization_mode="vector_entry_point", **settings)``.

`RacecarVectorEnv` steps N independent cars on one map (they do not see or touch each other)
and casts all the lidar scans due in a step with one numba call spread over the cores. Each car is a
[`RacecarEnv`][racecar_sim.env.RacecarEnv] with its own physics and its own random generator, so car ``i``
gives exactly what a single env gives for the same seed and actions: observations, rewards,
terminations, truncations and infos equal those of Gymnasium's ``SyncVectorEnv`` over N single envs
(tested), only faster.

Gymnasium 1.x conventions: ``reset(seed=s)`` seeds car ``i`` with ``s + i`` (or takes a list of
seeds), ``options`` go to every car (``options["reset_mask"]`` resets only some), and autoreset is
in *next-step* mode (``metadata["autoreset_mode"]``): the step after a car's episode ends resets
that car, ignores its action and returns its first observation with reward 0. Infos are dicts of
arrays with ``_key`` masks, as ``SyncVectorEnv`` builds them. ``max_episode_steps`` truncates each
car's episode after that many steps (as ``gymnasium.make(..., max_episode_steps=...)``).
No rendering.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from racecar_sim.env import RacecarEnv
from racecar_sim.fleet import CarFleet
from racecar_sim.maps import OccupancyMap, resolve_map
from racecar_sim.raycast.kernels import PARALLEL_MIN_RAYS
from racecar_sim.raycast.scan import scans_serial_nogil, scans_shared
from racecar_sim.raycast.shared_work import run_shared
from racecar_sim.settings.config import EnvConfig, merge_settings
from racecar_sim.settings.validation import check_action, check_options, short

__all__ = ["PROBE_EVERY", "RacecarVectorEnv", "car_seeds"]

PROBE_EVERY = 25
"""With ``parallel=None``, the way not in use (threads or not) is timed again every this many casts."""
_TIMES_KEPT = 8  # recent cast timings kept per way
_CHUNKS_PER_WORKER = 4  # the cars of a threaded cast come in this many chunks per thread


def car_seeds(seed: int | list[int | None] | None, n: int) -> list[int | None]:
    """Each of ``n`` cars' reset seed: ``seed + i`` for an int, None for None, or the list given.

    Raises:
        ValueError: anything else (a float, a bool, a string, a negative int), or a list whose
            length is not ``n``.
    """
    if seed is None:
        return [None] * n

    def is_seed(s: object) -> bool:
        return isinstance(s, int | np.integer) and not isinstance(s, bool | np.bool_) and s >= 0

    if is_seed(seed):
        return [int(seed) + i for i in range(n)]
    if not isinstance(seed, list | tuple | np.ndarray) or not all(
        s is None or is_seed(s) for s in seed
    ):
        raise ValueError(
            f"reset: seed must be a non-negative int, None, or a list of {n} of them; "
            f"got {short(seed)}"
        )
    seeds = [None if s is None else int(s) for s in seed]
    if len(seeds) != n:
        raise ValueError(f"reset: {len(seeds)} seeds given for num_envs={n} cars")
    return seeds


class RacecarVectorEnv(VectorEnv):
    """N racecars stepped together, one parallel lidar cast per step (see the module doc).

    Args:
        num_envs: number of cars.
        map: as [`RacecarEnv`][racecar_sim.env.RacecarEnv] (one map, loaded once, shared by the cars).
        config: as [`RacecarEnv`][racecar_sim.env.RacecarEnv]; keyword ``settings`` override it.
        max_episode_steps: truncate each car's episode after this many steps (None: never).
        parallel: cast the scans on ``workers`` threads (True) or on the calling thread (False).
            None (default): from `PARALLEL_MIN_RAYS` rays per
            step, whichever of the two has cast faster by the wall clock lately: both are timed
            and the other one is tried again every `PROBE_EVERY` casts, because on a
            machine whose cores are busy with other programs a worker thread can wait
            milliseconds to run, and then threads make every step slower.
        workers: casting threads (default: the number of CPUs): this one and pool threads of
            `racecar_sim.raycast.shared_work`, each casting chunks of cars in a numba kernel
            that releases the GIL: no thread spins while waiting, and none waits for another to
            wake, so a busy machine slows the cast but does not stall it.
        render_mode: only None (no rendering).

    Raises:
        ValueError: ``num_envs`` < 1, a bad setting (named), a render mode.

    ## Version History
    * v0 (racecar-sim 0.1): N independent ``RacecarSim-v0`` cars; car ``i`` with the same seed
      and actions gives the same episode as the single env (tested).
    * 0.2: every setting of ``RacecarSim-v0`` (see its history) applies to each car; the random
      start table is built once per map and car size and shared by the cars.
    * 0.3: each car's steps, clock, scans and odometry come from one core of N cars' arrays
      ([`CarFleet`][racecar_sim.fleet.CarFleet], the one the single env steps through with one
      car); each car's env is a row of it (``envs[i].time``, ``last_scan``); episodes are
      unchanged.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": [],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        map: str | os.PathLike[str] | OccupancyMap | None = None,
        *,
        config: str | os.PathLike[str] | Mapping[str, Any] | EnvConfig | None = None,
        max_episode_steps: int | None = None,
        parallel: bool | None = None,
        workers: int | None = None,
        render_mode: str | None = None,
        **settings: Any,
    ) -> None:
        if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("RacecarVectorEnv does not render; use render_mode=None")
        if parallel is not None and not isinstance(parallel, bool):
            raise ValueError(f"parallel must be True, False or None, got {parallel!r}")
        if workers is not None and (
            not isinstance(workers, int) or isinstance(workers, bool) or workers < 1
        ):
            raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
        if max_episode_steps is not None and (
            not isinstance(max_episode_steps, int) or max_episode_steps < 1
        ):
            raise ValueError(
                f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}"
            )
        cfg = merge_settings(config, {"map": map, **settings})
        grid = resolve_map(cfg.map, cfg.max_map_cells)
        cfg = merge_settings(cfg, {"map": grid})
        extras = [
            n for n in ("scan_effects", "odom_bias", "obstacles", "imu") if getattr(cfg, n) is not None
        ]
        if cfg.odom_lead:
            extras.append("odom_lead")
        extras += ["scene"] if cfg.scene not in (None, "none") else []
        if extras:  # the batched cast and odometry below know the four-part noise only
            raise ValueError(
                f"RacecarVectorEnv does not support {', '.join(extras)} (set by a noise profile or "
                "given); use RacecarSim-v0 for these"
            )
        self.envs: list[RacecarEnv] = [RacecarEnv(config=cfg) for _ in range(num_envs)]
        first = self.envs[0]
        self.num_envs = num_envs
        self.render_mode = None
        self.max_episode_steps = max_episode_steps
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, num_envs)
        self.action_space = batch_space(first.action_space, num_envs)
        self.map = grid
        self.dt = first.dt
        n = first.lidar_params.n_beams
        self._n_beams = n
        self.parallel = parallel
        self._auto_parallel = num_envs * n >= PARALLEL_MIN_RAYS
        # Recent wall-clock seconds per cast car, for the serial [0] and threaded [1] casts.
        self._cast_times: tuple[list[float], list[float]] = ([], [])
        self._casts = 0
        lidar = first.lidar
        self._field, self._geometry, self._cos_a, self._sin_a, self._noise = lidar.kernel_inputs
        self._penalty = float(cfg.collision_penalty)
        self._terminate = bool(cfg.terminate_on_collision)
        self._autoreset = np.zeros(num_envs, dtype=np.bool_)
        self._never_reset = np.ones(num_envs, dtype=np.bool_)  # cars with no state yet
        self._workers = max(1, int(workers if workers is not None else (os.cpu_count() or 1)))
        self.fleet = CarFleet(self.envs, cfg, lidar.period, first.odometry, n)
        """The cars' core ([`CarFleet`][racecar_sim.fleet.CarFleet]): their clocks, poses, last
        scans and odometry on arrays, the step they take; each car is a row of it."""
        for i, env in enumerate(self.envs):
            env.join(self.fleet, i)

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset the cars (seeds ``seed + i``, or a list); ``options`` as the single env's.

        ``options["reset_mask"]`` (bool (N,)) resets only those cars; the others keep their state
        and report their last observation.
        """
        n = self.num_envs
        seeds = car_seeds(seed, n)
        options = check_options("RacecarVectorEnv.reset", options)
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(n, dtype=np.bool_)
        else:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"reset options['reset_mask'] must be a bool array of shape ({n},) with a True"
                )
        infos: dict[str, Any] = {}
        for i, env in enumerate(self.envs):
            if mask[i]:  # the car's reset writes its row of the core: scan, odometry, clock
                _, info = env.reset(seed=seeds[i], options=options or None)
                self._add_info(infos, info, i)
        self._never_reset &= ~mask  # after every car's reset: a refused one leaves its car unset
        self._autoreset[mask] = False
        fleet = self.fleet  # the others report their last observation
        return {"scan": fleet.scans.copy(), "odom": fleet.odom.copy()}, infos

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every car by its row of ``actions`` (N, 2) = [steer rad, speed m/s], clipped.

        Raises:
            ValueError: ``actions`` is not an (N, 2) array of finite numbers.
        """
        n = self.num_envs
        if self._never_reset.any():
            raise ResetNeeded(
                f"call reset() before step(): car(s) {np.flatnonzero(self._never_reset).tolist()[:8]} "
                "have no state yet"
            )
        fleet = self.fleet
        acts = fleet.clip(check_action(actions, (n, 2), "actions"))

        # Next-step autoreset: a car whose episode ended restarts (its row of the core with it).
        reset_now = np.flatnonzero(self._autoreset).tolist()
        for i in reset_now:
            self.envs[i].reset()
        stepped = np.flatnonzero(~self._autoreset)
        fresh = np.zeros(n, dtype=np.bool_)
        collided = np.zeros(n, dtype=np.bool_)
        # The core: command, physics (free steps in one kernel call), clocks; then the scans due.
        collided[stepped], due = fleet.step(stepped, fleet.command(stepped.tolist(), acts))
        fresh[due] = True
        self._cast(due)
        fleet.odometry(stepped.tolist())  # the odometry's draws, after the scan's

        poses, twist, scans = fleet.poses.copy(), fleet.twists.copy(), fleet.scans.copy()
        odom, times = fleet.odom.copy(), fleet.clocks.times.copy()
        progress = twist[:, 0] * self.dt
        penalty = np.where(collided, -self._penalty, 0.0)
        rewards = progress + penalty
        terminated = collided & self._terminate
        if self.max_episode_steps is not None:
            truncated = fleet.clocks.steps >= self.max_episode_steps
        else:
            truncated = np.zeros(n, dtype=np.bool_)
        for i in reset_now:  # the first observation (the core's row), reward 0
            fresh[i] = True
            rewards[i] = progress[i] = penalty[i] = 0.0
            terminated[i] = truncated[i] = False
        ones = np.ones(n, dtype=np.bool_)
        infos = {
            "pose": poses, "_pose": ones, "twist": twist, "_twist": ones.copy(),
            "collision": collided, "_collision": ones.copy(), "time": times, "_time": ones.copy(),
            "new_scan": fresh, "_new_scan": ones.copy(),
            "rewards": {
                "progress": progress, "_progress": ones.copy(),
                "collision": penalty, "_collision": ones.copy(),
            },
            "_rewards": ones.copy(),
        }  # fmt: skip
        self._autoreset = terminated | truncated
        return {"scan": scans, "odom": odom}, rewards, terminated, truncated, infos

    # ------------------------------------------------------------------ internals
    def _cast(self, due: np.ndarray) -> None:
        """Cast the scans of cars ``due`` (ascending) at their poses in the core and keep them
        there.

        Each car draws its scan's seed from its own generator, as its
        [`measure()`][racecar_sim.sensors.lidar.Lidar.measure] would. In parallel, this thread and
        ``workers - 1`` pool threads take chunks of cars from one atomic counter
        (`racecar_sim.raycast.shared_work`): a thread that the OS runs late takes fewer
        chunks, and one that has not started when they run out is not waited for.
        """
        k, m = len(due), self._n_beams
        if k == 0:
            return
        fleet = self.fleet
        seeds = fleet.scan_seeds(due.tolist())
        sub = fleet.poses[due]
        out = np.empty((k, m), dtype=np.float32)
        ranges = np.empty((k, m))
        status = np.zeros(k, dtype=np.int64)

        parallel = self._choose_parallel() if self.parallel is None else self.parallel
        workers = self._workers if parallel else 1
        start = time.perf_counter()
        args = (self._field, sub, self._geometry, self._cos_a, self._sin_a, seeds, self._noise,
                ranges, out, status)  # fmt: skip
        if workers > 1 and k > 1:
            size = max(1, -(-k // (_CHUNKS_PER_WORKER * workers)))
            run_shared(scans_shared, (*args, size), workers)
        else:
            scans_serial_nogil(*args)
        if self.parallel is None:
            times = self._cast_times[int(workers > 1 and k > 1)]
            times.append((time.perf_counter() - start) / k)
            del times[:-_TIMES_KEPT]
        if status.any():  # pragma: no cover - physics poses are finite and on the map
            raise RuntimeError(f"lidar cast failed for cars {due[status != 0]}")
        fleet.scanned(due, out)

    def _choose_parallel(self) -> bool:
        """Threads or not for the next cast (``parallel=None``): the faster lately, probing."""
        if not self._auto_parallel or self._workers < 2:
            return False
        self._casts += 1
        serial, threaded = self._cast_times
        if len(threaded) < 3:  # a few casts each way first
            return True
        if len(serial) < 3:
            return False
        faster = statistics.median(threaded) < statistics.median(serial)
        # Every PROBE_EVERY casts, two casts the other way keep its timing current.
        if self._casts % PROBE_EVERY in (0, 1):
            return not faster
        return faster

