"""What the localization wrappers check before they run: the env they are given, their reset
options (``init``, ``init_spread``, ``init_pose``, read before the env is reset, so a refused
option changes nothing), and the filter's map against the world it is to localize in.

Each refusal is one line naming the wrapper and the option or argument. Frames and units: world
frame, poses [x m, y m, theta rad] of the rear axle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from mcl.filter.params import spread_sd
from mcl.wrappers.localization import INIT_MODES, RESET_OPTIONS
from racecar_sim.maps import OccupancyMap
from racecar_sim.settings.validation import check_options, check_poses, short

__all__ = [
    "MIN_FILTER_MAP_COVER",
    "FilterStart",
    "check_filter_map",
    "check_wrapped",
    "filter_start",
    "map_bounds",
]

MIN_FILTER_MAP_COVER = 0.5
"""Least share of the world map's free space that must be free on the filter map too: a filter
map of another place (or one shifted far off) localizes nothing; a filter map of the same place
edited since (boxes moved, a door closed) shares nearly all of it."""

_COVER_SAMPLES = 250_000  # world cells sampled (an even sub-grid) to measure the share

_KINDS = {  # what an env is, by what it has, and the wrapper that takes it
    "race": ("a PettingZoo race (RaceEnv)", "mcl.LocalizedRaceEnv"),
    "vector": ("a vector env", "mcl.LocalizedVectorEnv"),
    "single": ("a single env", "mcl.LocalizationWrapper"),
}


def _kind(env: Any) -> str | None:
    if isinstance(env, gym.vector.VectorEnv):
        return "vector"
    if isinstance(env, gym.Env):
        return "single"
    if hasattr(env, "possible_agents") and callable(getattr(env, "step", None)):
        return "race"
    return None


def check_wrapped(owner: str, env: Any, needs: str, description: str) -> None:
    """Refuse an env of the wrong kind for ``owner`` (``needs``: ``"single"``, ``"vector"`` or
    ``"race"``), saying what was given and which wrapper takes it.

    Raises:
        TypeError: ``"<owner> needs <description>; got <type>, <kind>: use <wrapper>"``.
    """
    kind = _kind(env)
    if kind == needs:
        return
    given = type(env).__name__
    if kind is None:
        raise TypeError(f"{owner} needs {description}; got {given}")
    what, wrapper = _KINDS[kind]
    raise TypeError(f"{owner} needs {description}; got {given}, {what}: use {wrapper}")


@dataclass(frozen=True)
class FilterStart:
    """How the filters of one reset start (the wrappers' reset options, checked).

    Attributes:
        init: ``"pose"`` or ``"global"``.
        spread: standard deviations (x m, y m, theta rad) or one number for all three, as given
            (checked), or None for the config's.
        centres: the ``init_pose`` given, (3,) or (N, 3) world poses, or None (the true starts).
        filter_seed: the ``filter_seed`` given (a non-negative integer: the filters' random
            generators are seeded from it instead of from the reset's seed), or None.
    """

    init: str
    spread: Any
    centres: np.ndarray | None
    filter_seed: int | None = None


def filter_start(
    owner: str,
    options: Any,
    default_init: str,
    filter_map: OccupancyMap,
    rows: int | None = None,
    one_for_all: bool = False,
) -> tuple[FilterStart, dict[str, Any]]:
    """The filter's reset options of ``options``, checked, and the other options (for the env).

    Args:
        owner: the wrapper, for messages.
        options: the ``options`` given to ``reset`` (a dict or None).
        default_init: the config's ``init``.
        filter_map: the map the filters hold: ``init_pose`` must lie on its free space.
        rows: None: ``init_pose`` is one pose (3,); else (``rows``, 3), one per car.
        one_for_all: with ``rows``, one pose (3,) for every car is taken too.

    Raises:
        ValueError: options not a dict; ``init`` not a mode; ``init_spread`` not one or three
            non-negative numbers within the config's bounds; ``init_pose`` not finite poses of the shape, or off the filter
            map's free space (off the map, in a wall or unknown cell); ``filter_seed`` not a
            non-negative integer.
    """
    options = check_options(f"{owner}.reset", options)
    mine = {k: options.pop(k) for k in RESET_OPTIONS if k in options}
    init = mine.get("init", default_init)
    if not isinstance(init, str) or init not in INIT_MODES:
        raise ValueError(
            f"{owner}.reset option init = {short(init)}; choose one of {list(INIT_MODES)}"
        )
    spread = mine.get("init_spread")
    if spread is not None:
        spread_sd(spread, f"{owner}.reset option init_spread")  # checked; passed on as given
    centres = mine.get("init_pose")
    if centres is not None:
        what = f"{owner}.reset option init_pose"
        single = rows is None or (one_for_all and np.ndim(centres) == 1)
        centres = check_poses(what, centres, None if single else rows)
        check_on_free_space(what, centres.reshape(-1, 3), filter_map)
    filter_seed = mine.get("filter_seed")
    if filter_seed is not None and (
        isinstance(filter_seed, bool)
        or not isinstance(filter_seed, int | np.integer)
        or filter_seed < 0
    ):
        raise ValueError(
            f"{owner}.reset option filter_seed = {short(filter_seed)} must be a non-negative integer"
        )
    seed = None if filter_seed is None else int(filter_seed)
    return FilterStart(init, spread, centres, seed), options


def map_bounds(occupancy_map: OccupancyMap) -> tuple[float, float, float, float]:
    """(x min, x max, y min, y max), metres: the world box around the map's image."""
    w, h = occupancy_map.extent
    corners = occupancy_map.map_to_world(np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]))
    return (float(corners[:, 0].min()), float(corners[:, 0].max()),
            float(corners[:, 1].min()), float(corners[:, 1].max()))  # fmt: skip


def check_on_free_space(what: str, poses: np.ndarray, occupancy_map: OccupancyMap) -> None:
    """Refuse poses (K, 3) whose position is not in a free cell of ``occupancy_map``.

    Raises:
        ValueError: naming ``what`` (and the row when K > 1), the pose and where it is.
    """
    free = occupancy_map.is_free(poses[:, :2])
    if free.all():
        return
    i = int(np.flatnonzero(~free)[0])
    row = f"[{i}]" if len(poses) > 1 else ""
    inside = bool(occupancy_map.in_bounds(occupancy_map.world_to_grid(poses[i, :2])))
    name = f"the filter map {occupancy_map.name!r}"
    if inside:
        where = f"in a wall or unknown cell of {name}"
    else:
        where = f"off {name} ({_box(occupancy_map)})"
    raise ValueError(f"{what}{row} = {short(poses[i].tolist(), 60)} is {where}")


def check_filter_map(owner: str, filter_map: OccupancyMap, world: OccupancyMap) -> None:
    """Refuse a filter map on which less than `MIN_FILTER_MAP_COVER` of the world map's
    free space is free (measured on an even sub-grid of at most 250 000 world cells).

    Raises:
        ValueError: naming ``owner`` (when not empty), the filter map, the share and the two
            maps' world boxes.
    """
    step = max(1, math.ceil(math.sqrt(world.occupied.size / _COVER_SAMPLES)))
    free = ~world.occupied[::step, ::step]
    rows, cols = np.nonzero(free)
    if len(rows) == 0:  # pragma: no cover - a map has free cells; the sub-grid missed them all
        return
    xy = world.grid_to_world(np.stack([rows * step, cols * step], axis=-1))
    share = float(filter_map.is_free(xy).mean())
    if share >= MIN_FILTER_MAP_COVER:
        return
    prefix = f"{owner}: " if owner else ""
    raise ValueError(
        f"{prefix}filter_map {filter_map.name!r} ({_box(filter_map)}) is free on {share:.0%} of "
        f"the free space of the world map {world.name!r} ({_box(world)}); at least "
        f"{MIN_FILTER_MAP_COVER:.0%} must be (the same place in the same world frame)"
    )


def _box(occupancy_map: OccupancyMap) -> str:
    x0, x1, y0, y1 = map_bounds(occupancy_map)
    return f"x {x0:.6g}..{x1:.6g} m, y {y0:.6g}..{y1:.6g} m"
