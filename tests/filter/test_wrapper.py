"""Tests of mcl.LocalizationWrapper and its CSV error log (mcl.wrappers.error_log)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl import LocalizationConfig, LocalizationWrapper, ParticleFilter
from mcl.filter.params import ParticleFilterParams
from mcl.wrappers.error_log import HEADER, ErrorLogWriter, count_rows, read_error_log
from mcl.wrappers.localization import as_localization_config, filter_rng
from racecar_sim.env import RacecarEnv
from racecar_sim.render import ESTIMATE_COLOUR, PARTICLE_COLOUR

REPO = Path(__file__).resolve().parents[2]
FEW_BEAMS = 61
SMALL = {"filter": {"n_particles": 200, "init_spread": (0.1, 0.1, 0.05)}}
START = np.array([6.0, 1.0, 0.3])  # world pose in the room map's free space
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably|different from the unwrapped"
    "|Not able to test alternative render).*:UserWarning"
)


def make(room, config=SMALL, render_mode=None, **kwargs) -> LocalizationWrapper:
    settings_ = {"n_beams": FEW_BEAMS, "terminate_on_collision": False}
    settings_.update(kwargs.pop("env", {}))
    env = gym.make("RacecarSim-v0", map=room, render_mode=render_mode, **settings_)
    return LocalizationWrapper(env, config, **kwargs)


def drive(env: LocalizationWrapper, n: int, seed: int = 0, options=None) -> list[tuple]:
    """Reset and drive ``n`` steps in a gentle left arc; returns (obs, info) per step."""
    obs, info = env.reset(seed=seed, options={"pose": START, **(options or {})})
    out = [(obs, info)]
    for _ in range(n):
        obs, _, _, _, info = env.step(np.array([0.15, 1.0], dtype=np.float32))
        out.append((obs, info))
    return out


# ---------------------------------------------------------------------- Gymnasium API
def test_check_env_passes_on_the_wrapped_env(room) -> None:
    # A fixed clock: check_env wants identical infos for identical seeds, wall time is not.
    env = make(room, render_mode="rgb_array", clock=lambda: 0.0)
    check_env(env, skip_render_check=False)
    assert "pose_estimate" in env.observation_space.spaces
    for key in ("scan", "odom"):
        assert env.observation_space[key] == env.env.observation_space[key]
    env.close()


def test_observation_and_info_carry_the_estimate_and_its_error(room) -> None:
    env = make(room)
    for obs, info in drive(env, 10):
        assert env.observation_space.contains(obs)
        loc = info["localization"]
        est, truth = obs["pose_estimate"], info["pose"]
        np.testing.assert_array_equal(loc["estimate"], est)
        assert loc["position_error"] == pytest.approx(math.dist(est[:2], truth[:2]))
        d = est[2] - truth[2]
        assert loc["heading_error"] == pytest.approx(math.atan2(math.sin(d), math.cos(d)))
        assert -math.pi <= loc["heading_error"] < math.pi
        assert 1.0 <= loc["n_eff"] <= 200.0
        assert loc["update_s"] > 0.0
    env.close()


def test_filter_tracks_the_car(room) -> None:
    env = make(room)
    steps = drive(env, 80)
    errors = [info["localization"]["position_error"] for _, info in steps]
    moved = math.dist(steps[0][1]["pose"][:2], steps[-1][1]["pose"][:2])
    assert moved > 1.0  # the car really drove
    assert max(errors[-20:]) < 0.15
    env.close()


def test_wrapper_rejects_a_non_racecar_env() -> None:
    with pytest.raises(TypeError, match="RacecarSim-v0"):
        LocalizationWrapper(gym.make("CartPole-v1"))


def test_bad_settings_are_named(room) -> None:
    with pytest.raises(ValueError, match="init"):
        LocalizationConfig(init="somewhere")
    with pytest.raises(ValueError, match="filter"):
        LocalizationConfig(filter={"n_particles": 0})
    with pytest.raises(ValueError, match="unknown LocalizationConfig"):
        make(room, config={"particles": 5})
    env = make(room)
    with pytest.raises(ValueError, match="init"):
        env.reset(seed=0, options={"pose": START, "init": "nowhere"})


def test_step_before_reset_names_reset(room) -> None:
    with pytest.raises(ResetNeeded, match="reset"):
        make(room).step(np.zeros(2, dtype=np.float32))


# ---------------------------------------------------------------------- filter in the loop
class SpyFilter(ParticleFilter):
    """A ParticleFilter that records which initialisation ran and how many corrections."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.calls: list[str] = []

    def initialize(self, pose, spread=None) -> None:
        self.calls.append("pose")
        self.init_args = (np.asarray(pose).copy(), spread)
        super().initialize(pose, spread)

    def initialize_global(self) -> None:
        self.calls.append("global")
        super().initialize_global()


def test_init_modes_and_reset_options(room) -> None:
    env = make(room, filter_factory=SpyFilter)
    _, info = env.reset(seed=1, options={"pose": START})
    assert env.filter.calls == ["pose"]
    np.testing.assert_allclose(env.filter.init_args[0], info["pose"])
    env.reset(seed=1, options={"pose": START, "init": "global"})
    assert env.filter.calls == ["global"]
    guess = START + np.array([0.5, -0.3, 0.1])
    env.reset(seed=1, options={"pose": START, "init_pose": guess, "init_spread": 0.2})
    np.testing.assert_allclose(env.filter.init_args[0], guess)
    assert env.filter.init_args[1] == 0.2
    env.close()
    global_env = make(room, config={**SMALL, "init": "global"}, filter_factory=SpyFilter)
    global_env.reset(seed=1, options={"pose": START})
    assert global_env.filter.calls == ["global"]


def test_corrects_only_on_fresh_scans(room) -> None:
    # lidar at 10 Hz with 40 Hz control: a fresh scan every 4th step (and at reset).
    env = make(room, env={"lidar_rate": 10.0})
    steps = drive(env, 12)
    fresh = [info["new_scan"] for _, info in steps]
    assert sum(fresh) == 4
    assert [info["localization"]["corrected"] for _, info in steps] == fresh
    assert env.filter.n_updates == sum(fresh)
    env.close()


def test_max_range_beams_reach_the_filter_at_its_max_range(room) -> None:
    env = make(room, env={"max_range": 3.0})
    env.reset(seed=0, options={"pose": START})
    seen = []
    sm = env.filter.sensor_model
    original = sm.log_evaluate
    sm.log_evaluate = lambda particles, scan: (
        seen.append(np.array(scan)) or original(particles, scan)
    )
    obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    sm.log_evaluate = original
    scan = obs["scan"].astype(np.float64)
    no_return = scan >= 3.0
    assert no_return.any() and (~no_return).any()
    np.testing.assert_array_equal(seen[0][no_return], sm.max_range)
    np.testing.assert_array_equal(seen[0][~no_return], scan[~no_return])


# ---------------------------------------------------------------------- randomness
def test_filter_leaves_the_env_noise_alone(room) -> None:
    """Same seed and actions: the wrapped env sees exactly the bare env's poses, scans, odometry."""
    bare = RacecarEnv(room, n_beams=FEW_BEAMS, terminate_on_collision=False)
    wrapped = make(room)
    obs_b, info_b = bare.reset(seed=5, options={"pose": START})
    obs_w, info_w = wrapped.reset(seed=5, options={"pose": START})
    for _ in range(20):
        for key in ("scan", "odom"):
            np.testing.assert_array_equal(obs_w[key], obs_b[key])
        np.testing.assert_array_equal(info_w["pose"], info_b["pose"])
        action = np.array([0.2, 1.5], dtype=np.float32)
        obs_b, _, _, _, info_b = bare.step(action)
        obs_w, _, _, _, info_w = wrapped.step(action)


def test_same_seed_same_truth_and_noise_whatever_the_filter(room) -> None:
    a = drive(make(room, {**SMALL, "motion": {"scheme": "uniform", "coefficients": 0.3}}), 15)
    b = drive(make(room, {**SMALL, "motion": {"scheme": "gaussian", "coefficients": 0.01}}), 15)
    for (obs_a, info_a), (obs_b, info_b) in zip(a, b, strict=True):
        np.testing.assert_array_equal(info_a["pose"], info_b["pose"])
        np.testing.assert_array_equal(obs_a["scan"], obs_b["scan"])
    assert any(
        not np.array_equal(oa["pose_estimate"], ob["pose_estimate"])
        for (oa, _), (ob, _) in zip(a, b, strict=True)
    )


def test_filter_is_reproducible_from_the_seed(room) -> None:
    first = drive(make(room), 10, seed=3)
    again = drive(make(room), 10, seed=3)
    other = drive(make(room), 10, seed=4)
    est = [o["pose_estimate"] for o, _ in first]
    np.testing.assert_array_equal(est, [o["pose_estimate"] for o, _ in again])
    assert not np.array_equal(est, [o["pose_estimate"] for o, _ in other])


def test_filter_seed_redraws_the_filter_on_the_same_drive(room) -> None:
    plain = drive(make(room), 10, seed=3)
    redrawn = drive(make(room), 10, seed=3, options={"filter_seed": 1003})
    again = drive(make(room), 10, seed=3, options={"filter_seed": 1003})
    as_seed = drive(make(room), 10, seed=3, options={"filter_seed": 3})
    for (obs_a, info_a), (obs_b, info_b) in zip(plain, redrawn, strict=True):
        np.testing.assert_array_equal(info_a["pose"], info_b["pose"])  # the same drive
        np.testing.assert_array_equal(obs_a["scan"], obs_b["scan"])
        np.testing.assert_array_equal(obs_a["odom"], obs_b["odom"])
    est = [o["pose_estimate"] for o, _ in redrawn]
    assert not np.array_equal(est, [o["pose_estimate"] for o, _ in plain])
    np.testing.assert_array_equal(est, [o["pose_estimate"] for o, _ in again])
    # the reset's own seed as filter_seed is the draw without the option
    np.testing.assert_array_equal(
        [o["pose_estimate"] for o, _ in as_seed], [o["pose_estimate"] for o, _ in plain]
    )


def test_filter_stream_is_not_the_env_stream() -> None:
    env_rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(7)))
    assert not np.array_equal(filter_rng(7).random(8), env_rng.random(8))
    np.testing.assert_array_equal(filter_rng(7).random(8), filter_rng(7).random(8))


# ---------------------------------------------------------------------- rendering
def test_render_overlays_particles_and_estimate(room) -> None:
    # a cloud wide enough to show around the estimate's marker (a tight one hides beneath it)
    wide = {"filter": {"n_particles": 200, "init_spread": (0.5, 0.5, 0.2)}}
    env = make(room, config=wide, render_mode="rgb_array")
    env.reset(seed=0, options={"pose": START})
    plain = env.env.render()
    img = env.render()
    assert img.shape == plain.shape and img.dtype == np.uint8
    changed = np.any(img != plain, axis=2)
    assert changed.any()
    colours = {tuple(c) for c in img[changed]}
    assert tuple(ESTIMATE_COLOUR) in colours
    assert tuple(PARTICLE_COLOUR) in colours
    no_render = make(room)
    no_render.reset(seed=0, options={"pose": START})
    with pytest.warns(UserWarning, match="render_mode"):
        assert no_render.render() is None


# ---------------------------------------------------------------------- CSV log
def test_log_has_the_header_and_one_row_per_step(room, tmp_path) -> None:
    path = tmp_path / "sub" / "log.csv"
    env = make(room, log_path=path)
    steps = drive(env, 25)
    env.close()
    lines = path.read_text().splitlines()
    assert lines[0] == (
        "step,time,x_true,y_true,theta_true,x_est,y_est,theta_est,position_error,"
        "heading_error,n_eff,update_s,lost"
    )
    assert len(lines) == 1 + 25
    log = read_error_log(path)
    assert not log.truncated
    np.testing.assert_array_equal(log.step, np.arange(1, 26))
    infos = [info for _, info in steps[1:]]
    np.testing.assert_allclose(log.time, [i["time"] for i in infos])
    np.testing.assert_allclose(log.true_poses, [i["pose"] for i in infos], atol=1e-8)
    np.testing.assert_allclose(log.estimates, [o["pose_estimate"] for o, _ in steps[1:]], atol=1e-8)
    for name in ("position_error", "heading_error", "n_eff", "update_s"):
        expected = [i["localization"][name] for i in infos]
        np.testing.assert_allclose(getattr(log, name), expected, rtol=1e-8, atol=1e-12)


def test_exception_inside_the_loop_keeps_every_row(room, tmp_path) -> None:
    path = tmp_path / "log.csv"
    env = make(room, log_path=path)
    env.reset(seed=0, options={"pose": START})
    with pytest.raises(ValueError, match="action"):
        for k in range(100):
            env.step(np.array([0.0, 1.0]) if k < 17 else np.array([np.nan, 1.0]))
    # No close(): the rows must already be on disk.
    assert count_rows(path) == 17
    np.testing.assert_array_equal(read_error_log(path).step, np.arange(1, 18))
    env.close()  # only now: an open log left to the garbage collector warns in a later test


_KILLED_RUN = textwrap.dedent(
    """
    import sys
    import numpy as np, gymnasium as gym
    import racecar_sim
    from mcl import LocalizationWrapper
    env = LocalizationWrapper(
        gym.make("RacecarSim-v0", map="corridor", n_beams=31, terminate_on_collision=False),
        {{"filter": {{"n_particles": 50}}}},
        log_path=sys.argv[1],
    )
    env.reset(seed=0, options={{"pose": [6.0, 1.0, 0.3]}})
    k = 0
    while True:  # until killed; tell the parent each step that returned
        env.step(np.array([0.3, 0.5], dtype=np.float32))
        k += 1
        print(k, flush=True)
    """
)


def test_killed_run_leaves_a_readable_log(tmp_path) -> None:
    """SIGKILL mid-run: the CSV holds every step that had returned, and reads back cleanly."""
    path = tmp_path / "killed.csv"
    script = tmp_path / "run.py"
    script.write_text(_KILLED_RUN.format())
    proc = subprocess.Popen(
        [sys.executable, str(script), str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=REPO,
        text=True,
    )
    try:
        done = 0
        for line in proc.stdout:  # blocks until the child reports a finished step
            done = int(line)
            if done >= 30:
                break
        assert done >= 30, proc.stderr.read()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    log = read_error_log(path)
    assert len(log) >= done
    np.testing.assert_array_equal(log.step, np.arange(1, len(log) + 1))
    assert np.isfinite(log.position_error).all()


_finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    rows=st.lists(st.tuples(*[_finite] * 8), min_size=0, max_size=6),
    cut=st.integers(min_value=0, max_value=10_000),
)
def test_log_survives_being_cut_anywhere(tmp_path_factory, rows, cut) -> None:
    """Writing then cutting the file at any byte keeps exactly the complete rows, values intact."""
    path = tmp_path_factory.mktemp("cut") / "log.csv"
    with ErrorLogWriter(path) as log:
        for k, r in enumerate(rows, start=1):
            log.write(k, abs(r[0]), r[1:4], r[4:7], abs(r[7]), 0.1, 10.0, 1e-3)
    data = path.read_bytes()
    header_len = len(",".join(HEADER)) + 1
    cut = header_len + cut % (len(data) - header_len + 1)
    path.write_bytes(data[:cut])
    complete = data[:cut].count(b"\n") - 1
    log = read_error_log(path)
    assert len(log) == complete == count_rows(path)
    assert log.truncated == (cut < len(data) and not data[:cut].endswith(b"\n"))
    for k in range(complete):
        np.testing.assert_allclose(log.true_poses[k], rows[k][1:4], rtol=1e-9, atol=1e-12)


def test_reader_names_what_is_wrong(tmp_path) -> None:
    with pytest.raises(ValueError, match="not found"):
        read_error_log(tmp_path / "missing.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("step,time\n1,2\n")
    with pytest.raises(ValueError, match="header"):
        read_error_log(bad)
    assert count_rows(bad) == 0
    bad.write_text(",".join(HEADER) + "\n1,2,3\n")
    with pytest.raises(ValueError, match="row 1 has 3 fields"):
        read_error_log(bad)


def test_config_loads_from_yaml_with_nested_sections(tmp_path) -> None:
    from racecar_sim.settings.config import from_yaml

    path = tmp_path / "mcl.yaml"
    path.write_text(
        "localization:\n"
        "  init: global\n"
        "  motion: {scheme: uniform, coefficients: [0.1, 0.05, 0.02]}\n"
        "  filter: {n_particles: 321, init_spread: [0.3, 0.3, 0.1]}\n"
        "  sensor: {sigma_hit: 5.0}\n"
    )
    config = from_yaml(LocalizationConfig, path, section="localization")
    assert config.init == "global"
    assert config.motion.scheme == "uniform" and config.motion.coefficients == (0.1, 0.05, 0.02)
    assert config.filter.n_particles == 321 and config.filter.init_spread == (0.3, 0.3, 0.1)
    assert config.sensor.sigma_hit == 5.0
    path.write_text("localization:\n  motion: {scheme: wobbly}\n")
    with pytest.raises(ValueError, match="motion"):
        from_yaml(LocalizationConfig, path, section="localization")


def test_a_partial_filter_section_keeps_the_configs_own_defaults() -> None:
    # a mapping of a few filter fields (YAML, --filter, experiment scripts) must not bring back
    # the bare ParticleFilterParams class defaults for the others (its 0.5 m start cloud)
    default = LocalizationConfig()
    partial = as_localization_config({"filter": {"n_particles": 321}})
    assert partial.filter == replace(default.filter, n_particles=321)
    assert (
        partial.filter.init_spread
        == default.filter.init_spread
        != ParticleFilterParams().init_spread
    )


# ---------------------------------------------------------------------- misuse
def test_reset_options_of_the_wrong_kind_are_refused_before_the_env_resets(room) -> None:
    env = make(room)
    env.reset(seed=0, options={"pose": START})
    env.step(np.array([0.0, 1.0]))
    pose, filter_before = env.unwrapped.pose.copy(), env.filter
    refused = [
        ([1, 2], r"^LocalizationWrapper.reset: options must be a dict.*list"),
        ({"init_pose": "abc"}, r"^LocalizationWrapper.reset option init_pose must be three .*str"),
        ({"init_pose": {"x": 6.0}}, r"option init_pose must be three .*dict"),
        ({"init_pose": [6.0, float("nan"), 0.0]}, r"option init_pose must be three .*nan"),
        ({"init_spread": "wide"}, r"option init_spread must be one or three"),
        ({"init_spread": 1e12}, r"option init_spread must be one or three numbers in \[0, 10000\]"),
        ({"init": ["pose"]}, r"option init = \['pose'\]; choose one of"),
        ({"filter_seed": -1}, r"option filter_seed = -1 must be a non-negative integer"),
        ({"filter_seed": 2.5}, r"option filter_seed = 2.5 must be a non-negative integer"),
        ({"filter_seed": True}, r"option filter_seed = True must be a non-negative integer"),
        ({"filter_seed": "7"}, r"option filter_seed = '7' must be a non-negative integer"),
    ]
    for options, message in refused:
        with pytest.raises(ValueError, match=message):
            env.reset(options=options)
        # nothing was reset: the car and its filter are as they were
        np.testing.assert_array_equal(env.unwrapped.pose, pose)
        assert env.filter is filter_before
    env.step(np.array([0.0, 1.0]))  # still running


def test_an_init_pose_off_the_filter_map_or_in_a_wall_is_refused_naming_it(room) -> None:
    env = make(room)
    with pytest.raises(
        ValueError, match=r"init_pose = \[5000.0, 5000.0, 0.0\] is off the filter map 'room'"
    ):
        env.reset(seed=0, options={"pose": START, "init_pose": [5000.0, 5000.0, 0.0]})
    wall = room.grid_to_world(np.argwhere(room.occupied)[0])  # a wall cell's centre
    with pytest.raises(ValueError, match="is in a wall or unknown cell of the filter map 'room'"):
        env.reset(seed=0, options={"pose": START, "init_pose": [*wall, 0.0]})
    env.reset(
        seed=0, options={"pose": START, "init_pose": START + np.array([0.2, 0.0, 0.0])}
    )  # taken


def test_a_filter_map_that_does_not_cover_the_world_is_refused_naming_it(room) -> None:
    from racecar_sim.maps import OccupancyMap

    far = OccupancyMap(np.zeros((3, 3), bool), 0.05, (5000.0, 5000.0, 0.0), name="far")
    with pytest.raises(
        ValueError,
        match=r"filter_map 'far' .* is free on 0% of the free space of the world map 'room'",
    ):
        make(room, filter_map=far)
    # The room shifted by 70 % of its width leaves about a third of the world's floor: refused;
    # the room with one more box (an edited world) covers nearly all of it: taken.
    ox, oy, _ = room.origin
    shifted = OccupancyMap(room.occupied, room.resolution, (ox + 0.7 * room.extent[0], oy, 0.0),
                           name="shifted")  # fmt: skip
    with pytest.raises(ValueError, match="filter_map 'shifted'"):
        make(room, filter_map=shifted)
    edited = room.occupied.copy()
    edited[40:60, 100:120] = True
    make(room, filter_map=OccupancyMap(edited, room.resolution, room.origin, name="edited"))


def test_wrapping_a_race_or_a_vector_env_names_the_wrapper_that_takes_it(room) -> None:
    from racecar_sim.race.env import RaceEnv
    from racecar_sim.vector_env import RacecarVectorEnv

    with pytest.raises(
        TypeError, match=r"got RaceEnv, a PettingZoo race .*use mcl.LocalizedRaceEnv"
    ):
        LocalizationWrapper(RaceEnv(room, n_cars=2, n_beams=FEW_BEAMS))
    with pytest.raises(
        TypeError, match=r"got RacecarVectorEnv, a vector env: use mcl.LocalizedVectorEnv"
    ):
        LocalizationWrapper(RacecarVectorEnv(2, map=room, n_beams=FEW_BEAMS))


def test_a_masked_action_is_refused_through_the_wrapper(room) -> None:
    env = make(room)
    env.reset(seed=0, options={"pose": START})
    with pytest.raises(ValueError, match="masked"):
        env.step(np.ma.array([0.0, 3.0], mask=[False, True]))
