"""Plays the API misuse cases of :mod:`tests.fuzz.api_cases` in the fuzz worker, judging every
call as it goes.

A call that must be refused (``bad``, or a step the env's state says needs a reset) must raise a
``ValueError`` or ``ResetNeeded`` of one short line; a call that must be taken must not raise; an
accepted call must give observations of the right keys and shapes, finite and in range. Anything
else (a ``TypeError``, ``AttributeError``, a broadcasting error) leaves the runner as it is and is
a finding. A case that was refused somewhere re-raises its first refusal at the end, so the
campaign counts it as a clean error.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from tests.fuzz.harness import MAX_MESSAGE
from tests.fuzz.mutations import decode

__all__ = ["action_value", "poses", "run_localization_api", "run_race_api"]

_BEAMS = 30
_CONFIG = {"filter": {"n_particles": 100}}


def action_value(spec: dict[str, Any]) -> Any:
    """One action value from its JSON form (tests.fuzz.api_cases.VALUES)."""
    if "text" in spec:
        return spec["text"]
    if "bytes" in spec:
        return spec["bytes"].encode()
    if "dict" in spec:
        return dict(spec["dict"])
    if "tuple" in spec:
        return tuple(decode(spec["tuple"]))
    if "list" in spec:
        return decode(spec["list"])
    if "none" in spec:
        return None
    if "number" in spec:
        return spec["number"]
    if "masked" in spec:
        return np.ma.array(spec["masked"], mask=spec["mask"])
    return np.array(decode(spec["array"]), dtype=spec["dtype"])


def poses(how: str, occupancy_map: Any, n: int | None, free: np.ndarray) -> Any:
    """A pose option of kind ``how`` (tests.fuzz.api_cases._POSES): one pose (3,) when ``n`` is
    None, else (n, 3); ``free`` are free places (k >= n, 3) to draw "free" and "same" from."""
    rows = 1 if n is None else n
    if how == "free":
        out = free[:rows].tolist()
    elif how == "same":
        out = [free[0].tolist()] * rows
    elif how == "wall":
        rc = np.argwhere(occupancy_map.occupied)[len(np.argwhere(occupancy_map.occupied)) // 2]
        out = [[*occupancy_map.grid_to_world(rc).tolist(), 0.0]] * rows
    else:
        base = free[:rows].tolist()
        if how in ("nan", "inf"):
            base[-1][1] = float(how)
        elif how == "far":
            base[-1][:2] = [5000.0, 5000.0]
        elif how == "huge":
            base[-1][0] = 1e300
        elif how == "short":
            base = [p[:2] for p in base]
        elif how == "bools":
            base[-1][0] = True
        elif how == "nested_text":
            base = [[str(v) for v in p] for p in base]
        elif how == "dict":
            return {f"car_{i}": p for i, p in enumerate(base)}
        elif how == "text":
            return "grid"
        out = base
    return out[0] if n is None else out


def _free_places(occupancy_map: Any, k: int, seed: int = 0) -> np.ndarray:
    """``k`` poses at the centres of free cells well clear of walls, far apart along the map."""
    cells = np.argwhere(occupancy_map.distance >= 0.6)
    if len(cells) == 0:
        cells = np.argwhere(~occupancy_map.occupied)
    pick = cells[np.linspace(0, len(cells) - 1, k).astype(int)]
    xy = occupancy_map.grid_to_world(pick)
    return np.column_stack([xy, np.zeros(k)])


class _Judge:
    """Each call's outcome against what it must be; the refusals seen."""

    def __init__(self) -> None:
        self.refusals: list[Exception] = []

    def call(
        self, what: str, bad: bool | None, must_reset: bool | None, fn: Any, *args: Any, **kw: Any
    ) -> Any:
        """``fn(*args, **kw)``; None when it was refused (clearly, as it had to be or could be)."""
        from gymnasium.error import ResetNeeded

        try:
            out = fn(*args, **kw)
        except (ValueError, ResetNeeded) as exc:
            message = str(exc)
            assert message.strip() and "\n" not in message and len(message) <= MAX_MESSAGE, (
                f"{what}: not one short line: {message[:300]!r}"
            )
            if isinstance(exc, ResetNeeded):
                assert must_reset is not False, f"{what}: ResetNeeded without a reason: {message}"
            else:
                assert bad is not False or must_reset, f"{what}: refused a valid call: {message}"
                assert not (must_reset and bad is False), f"{what}: not ResetNeeded: {message}"
            self.refusals.append(exc)
            return None
        assert not bad, f"{what}: accepted although it must be refused"
        assert not must_reset, f"{what}: accepted although the env needs a reset"
        return out

    def end(self) -> None:
        if self.refusals:
            raise self.refusals[0]


def _check_scan(obs: dict[str, Any], max_range: float, what: str) -> None:
    scan = np.asarray(obs["scan"])
    assert scan.shape[-1] == _BEAMS, f"{what}: scan shape {scan.shape}"
    assert np.isfinite(scan).all() and (scan >= 0).all(), f"{what}: scan not finite and >= 0"
    assert (scan <= max_range + 1e-6).all(), f"{what}: scan beyond max_range"
    assert np.isfinite(obs["odom"]).all(), f"{what}: odometry not finite"


def _race_actions(spec: dict[str, Any], agents: list[str], possible: list[str]) -> Any:
    how = spec["how"]
    valid = {a: np.array([0.1, 1.0]) for a in agents}
    if how == "none":
        return None
    if how == "list":
        return [[0.1, 1.0]] * len(agents)
    if how == "array":
        return np.zeros((len(agents), 2))
    if how == "text":
        return "car_0"
    if how == "empty":
        return {}
    if how == "value" and agents:
        return {**valid, agents[-1]: action_value(spec["value"])}
    if how == "extra":
        return {**valid, f"car_{len(possible)}": [0.0, 0.0]}
    if how == "missing":
        return dict(list(valid.items())[:-1])
    if how == "int_key":
        return {**valid, 0: [0.0, 0.0]}
    if how == "upper":
        return {a.upper(): v for a, v in valid.items()}
    return valid


def _race_options(spec: dict[str, Any], env: Any, n: int) -> Any:
    how = spec["how"]
    if how == "none":
        return None
    if how == "list":
        return [1, 2]
    if how == "text":
        return "poses"
    if how == "int_key":
        return {1: 2}
    if how == "unknown":
        return {"speed": 1.0}
    if how == "poses_none":
        return {"poses": None}
    if how == "empty":
        return {}
    return {"poses": poses(spec["pose"], env.map, n, _free_places(env.map, n))}


def _check_race_step(out: Any, alive: list[str], max_range: float, what: str) -> None:
    obs, rew, term, trunc, infos = out
    for d in (obs, rew, term, trunc, infos):
        assert set(d) == set(alive), f"{what}: keys {sorted(d)[:5]} != alive {alive[:5]}"
    for a in alive:
        _check_scan(obs[a], max_range, f"{what} {a}")
        assert math.isfinite(rew[a]), f"{what}: reward of {a} not finite"


def run_race_api(case: dict[str, Any], tmp: Path) -> None:
    from racecar_sim.race.env import RaceEnv

    judge = _Judge()
    n_cars = case["n_cars"]
    bad_n = not (isinstance(n_cars, int) and not isinstance(n_cars, bool) and 1 <= n_cars <= 100)
    env = judge.call("RaceEnv()", bad_n, False, RaceEnv, case["map"], n_cars=n_cars,
                     n_beams=_BEAMS, max_episode_steps=case["max_steps"])  # fmt: skip
    if env is None:
        return judge.end()
    max_range = env.lidar_params.max_range
    ready = False
    for op in case["ops"]:
        if op["op"] == "reset":
            spec = op["options"]
            seed = op["seed"]
            bad_seed = True if seed in (-1, 2.5, "a") or seed is True else None
            bad_seed = bad_seed if seed not in (0, 1, 7, None) else False
            options = _race_options(spec, env, n_cars)
            out = judge.call(f"reset({seed!r}, {spec})", spec["bad"] or bad_seed or None, False,
                             env.reset, seed=seed, options=options)  # fmt: skip
            ready = out is not None
            if ready:
                assert set(out[0]) == set(env.possible_agents) == set(env.agents), "reset keys"
                for a in env.agents:
                    _check_scan(out[0][a], max_range, f"reset {a}")
            continue
        steps = 5 if op["op"] == "run_out" else 1
        spec = op.get("actions", {"how": "valid", "bad": False})
        for _ in range(steps):
            alive = list(env.agents)
            must_reset = not ready or not alive
            actions = _race_actions(spec, alive, env.possible_agents)
            out = judge.call(f"step({spec})", spec["bad"], must_reset, env.step, actions)
            if out is None:
                break
            _check_race_step(out, alive, max_range, f"step({spec})")
            if op["op"] == "run_out" and not env.agents:
                break
    return judge.end()


# ---------------------------------------------------------------------- localization wrappers
def _inner(kind: str, case: dict[str, Any]) -> Any:
    import gymnasium as gym

    from racecar_sim.env import RacecarEnv
    from racecar_sim.race.env import RaceEnv

    n, steps = case["n_cars"], case["max_steps"]
    if kind == "single":
        env = RacecarEnv("corridor", n_beams=_BEAMS)
        return env if steps is None else gym.wrappers.TimeLimit(env, steps)
    if kind == "vector":
        return gym.make_vec("RacecarSim-v0", num_envs=n, vectorization_mode="vector_entry_point",
                            map="corridor", n_beams=_BEAMS, max_episode_steps=steps)  # fmt: skip
    if kind == "race":
        return RaceEnv("corridor", n_cars=n, n_beams=_BEAMS, max_episode_steps=steps)
    return None


def _filter_map(how: str | None, world: Any) -> Any:
    from racecar_sim.maps import OccupancyMap

    if how is None:
        return None
    if how == "same":
        return world
    if how == "far":
        return OccupancyMap(np.zeros((3, 3), bool), 0.05, (5000.0, 5000.0, 0.0), name="far")
    ox, oy, _ = world.origin  # shifted by 80 % of its width: a fifth of the floor shared
    return OccupancyMap(world.occupied, world.resolution, (ox + 0.8 * world.extent[0], oy, 0.0),
                        name="shifted")  # fmt: skip


def _wrap(case: dict[str, Any], inner: Any) -> Any:
    from mcl.wrappers.race import LocalizedRaceEnv
    from mcl.wrappers.single import LocalizationWrapper
    from mcl.wrappers.vector import LocalizedVectorEnv

    wrapper = case["wrapper"]
    if wrapper == "single":
        world = getattr(getattr(inner, "unwrapped", None), "map", None)
        fmap = _filter_map(case.get("filter_map"), world) if world is not None else None
        return LocalizationWrapper(inner, _CONFIG, filter_map=fmap, clock=lambda: 0.0)
    if wrapper == "vector":
        return LocalizedVectorEnv(inner, _CONFIG, clock=lambda: 0.0)
    return LocalizedRaceEnv(inner, _CONFIG, agents=case.get("agents"), clock=lambda: 0.0)


def _loc_options(spec: dict[str, Any], env: Any, wrapper: str, n: int) -> Any:
    how = spec["how"]
    if how in ("none", "list", "text", "int_key"):
        return {"none": None, "list": [1, 2], "text": "init", "int_key": {1: 2}}[how]
    out: dict[str, Any] = {k: decode(spec[k]) for k in ("init", "init_spread", "reset_mask")
                           if k in spec}  # fmt: skip
    if spec.get("init_pose", "none") != "none":
        rows = None if wrapper == "single" or spec["one_pose"] else n
        out["init_pose"] = poses(spec["init_pose"], env.map, rows, _free_places(env.map, n))
    return out


_REPORTED = ("position_error", "heading_error", "n_eff", "position_sd", "heading_sd")


def _check_report(loc: dict[str, Any], what: str) -> None:
    for key in _REPORTED:
        if key in loc:
            assert np.isfinite(loc[key]).all(), f"{what}: localization {key} not finite"


def _check_loc(out: Any, env: Any, wrapper: str, what: str) -> None:
    """The wrapper's observation and report after an accepted reset or step: scans, estimates
    and the numbers of info["localization"], finite."""
    obs, infos = out[0], out[-1]
    if wrapper == "race":
        for a, o in obs.items():
            _check_scan(o, 30.0, f"{what} {a}")
            if a in env.filters:
                assert np.isfinite(o["pose_estimate"]).all(), f"{what}: {a} estimate not finite"
                _check_report(infos[a]["localization"], f"{what} {a}")
        return
    _check_scan(obs, 30.0, what)
    est = np.asarray(obs["pose_estimate"])
    loc = infos["localization"]
    if wrapper == "vector":
        est = est[[pf is not None for pf in env.filters]]
        loc = {k: np.asarray(loc[k])[loc[f"_{k}"]] for k in _REPORTED if k in loc}  # reported
    assert np.isfinite(est).all(), f"{what}: estimate not finite: {est.tolist()}"
    _check_report(loc, what)


def run_localization_api(case: dict[str, Any], tmp: Path) -> None:
    judge = _Judge()
    wrapper, n = case["wrapper"], case["n_cars"]
    inner = _inner(case["wraps"], case)
    wrong_wrap = case["wraps"] != wrapper
    if wrong_wrap:  # a TypeError naming the wrapper (the case's clear_types), nothing else
        try:
            _wrap(case, inner)
        except TypeError as exc:
            assert str(exc).startswith(f"{case['owner']} needs"), f"TypeError: {exc}"
            raise
        raise AssertionError(f"{case['owner']} wrapped a {case['wraps']} env")
    agents = case.get("agents")
    bad_agents = agents is not None and not (
        isinstance(agents, list) and set(agents) <= {f"car_{i}" for i in range(n)}
        and len(set(agents)) == len(agents)
    )  # fmt: skip
    bad_map = case.get("filter_map") in ("far", "shifted")
    env = judge.call("wrap", bad_agents or bad_map, False, _wrap, case, inner)
    if env is None:
        return judge.end()
    ready: bool | None = False
    owner = type(env).__name__
    for op in case["ops"]:
        if op["op"] == "reset":
            spec = op["options"]
            options = _loc_options(spec, env, wrapper, n)
            bad = spec["bad"]
            mask = spec.get("reset_mask")
            if mask is not None and not (  # a bool per car, one True at least
                isinstance(mask, list) and len(mask) == n and any(mask)
                and all(isinstance(v, bool) for v in mask)
            ):  # fmt: skip
                bad = True
            out = judge.call(f"reset({spec})", bad, False, env.reset, seed=op["seed"],
                             options=options)  # fmt: skip
            if out is not None:
                # a vector env is ready once every car was reset (reset_mask may leave some out)
                ready = wrapper != "vector" or all(pf is not None for pf in env.filters)
                _check_loc(out, env, wrapper, f"reset({spec})")
            elif not str(judge.refusals[-1]).startswith(f"{owner}.reset"):
                ready = None if wrapper == "vector" else False  # the env's reset refused
            continue
        spec = op["actions"]
        if wrapper == "race":
            alive = list(env.agents)
            must_reset = None if ready is None else (not ready or not alive)
            actions = _race_actions(spec, alive, env.possible_agents)
        else:
            must_reset = None if ready is None else not ready
            one = np.array([0.1, 1.0]) if spec["how"] == "valid" else None
            if spec["how"] == "value":
                one = action_value(spec["value"])
            elif spec["how"] in ("text", "dict"):
                one = {"text": "go", "dict": {"steer": 0.1}}[spec["how"]]
            actions = [one] * n if wrapper == "vector" else one  # a row per car
        out = judge.call(f"step({spec})", spec["bad"], must_reset, env.step, actions)
        if out is not None:
            _check_loc(out, env, wrapper, f"step({spec})")
    return judge.end()
