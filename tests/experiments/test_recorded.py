"""Recorded drives: a replay through localize_recorded is the online LocalizationWrapper run bit
for bit (estimates and lost flags, the flag's recovery included), and a drive survives save/load
unchanged."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.experiments.recorded import RecordedDrive, localize_recorded, record_drive
from mcl.experiments.runs import make_driver
from mcl.wrappers.localization import LocalizationConfig, as_localization_config
from mcl.wrappers.single import LocalizationWrapper
from racecar_sim.env import RacecarEnv
from racecar_sim.maps import resolve_map

CONFIG = LocalizationConfig().with_particles(300)
# a flag that asks for 99 % of the beams: in the cluttered honest world it goes up at once, and
# bursts of uniform poses search the map (drawn from the filter's own generator)
SEARCHING = as_localization_config({
    "filter": {"n_particles": 300},
    "lost": {"raise_below": 0.99, "clear_above": 0.995, "raise_after_s": 0.0, "recover": True},
})  # fmt: skip
HONEST = {"noise_profile": "mit_racecar", "scene": "cluttered", "lidar_rate": 20.0}  # scans every other step


def _online(world: str, seed: int, steps: int, env: dict, config: LocalizationConfig,
            filter_map: str | None = None):  # fmt: skip
    """Position errors, estimates and lost flags of a LocalizationWrapper run as run_one drives it."""
    sim = RacecarEnv(resolve_map(world), terminate_on_collision=False, **env)
    wrapped = LocalizationWrapper(sim, config, filter_map=filter_map)
    driver = make_driver("wall", sim, seed)
    obs, info = wrapped.reset(seed=seed)
    errors, estimates = [info["localization"]["position_error"]], [obs["pose_estimate"]]
    lost = [info["localization"]["lost"]]
    for _ in range(steps):
        obs, _, _, _, info = wrapped.step(driver(obs, info))
        errors.append(info["localization"]["position_error"])
        estimates.append(obs["pose_estimate"])
        lost.append(info["localization"]["lost"])
    wrapped.close()
    return np.array(errors), np.stack(estimates), np.array(lost)


@pytest.mark.parametrize(
    ("env", "config", "filter_map"),
    [
        ({}, CONFIG, None),  # ideal sensors, a scan every step
        (HONEST, CONFIG, None),
        (HONEST, SEARCHING, None),
    ],
    ids=["ideal", "honest-20Hz", "lost-and-searching"],
)
def test_replay_is_the_online_wrapper_bit_for_bit(env, config, filter_map):
    seed, steps = 3, 60
    errors, estimates, lost = _online("basement_loop", seed, steps, env, config, filter_map)
    drive = record_drive(
        "basement_loop", seed=seed, duration=steps * 0.025, filter_map=filter_map,
        noise_profile=env.get("noise_profile"), scene=env.get("scene"),
        env={k: v for k, v in env.items() if k not in ("noise_profile", "scene")},
    )  # fmt: skip
    assert drive.n_steps == steps
    if "lidar_rate" in env:  # the replay must skip the steps without a fresh scan
        assert 0 < np.count_nonzero(drive.fresh) < len(drive.fresh)
    run = localize_recorded(drive, config)
    np.testing.assert_array_equal(run.estimate, estimates)
    np.testing.assert_array_equal(run.lost, lost)
    # the errors of equal estimates: numpy's hypot (vectorised) and math.hypot (the wrapper's)
    # may differ in the last bit
    np.testing.assert_allclose(run.position_error, errors, rtol=1e-15, atol=0.0)
    if config is CONFIG:
        assert errors[-1] < 0.5 and not lost.any()  # a filter that tracks, not two equal failures
    else:  # the flag and its search ran: the replay must have run them too
        assert lost.any()


def test_replay_seed_changes_the_filter_not_the_drive():
    drive = record_drive("basement_loop", seed=1, duration=1.0)
    a = localize_recorded(drive, CONFIG)
    b = localize_recorded(drive, CONFIG, seed=2)
    assert not np.array_equal(a.estimate, b.estimate)
    np.testing.assert_array_equal(a.position_error, localize_recorded(drive, CONFIG).position_error)


def test_save_load_round_trip(tmp_path):
    drive = record_drive("office", seed=5, duration=0.5, filter_map="basement_loop",
                         env={"lidar_rate": 20.0})  # fmt: skip
    path = drive.save(tmp_path / "drive")
    assert path.suffix == ".npz"
    back = RecordedDrive.load(path)
    for name in ("time", "dt_steps", "truth", "odom", "fresh", "scans", "beam_angles"):
        np.testing.assert_array_equal(getattr(back, name), getattr(drive, name))
        assert getattr(back, name).dtype == getattr(drive, name).dtype
    assert (back.mount_offset, back.max_range, back.dt) == (drive.mount_offset, drive.max_range,
                                                            drive.dt)  # fmt: skip
    assert (back.world_map, back.filter_map) == ("office", "basement_loop")
    assert back.settings["seed"] == 5 and back.settings["env"] == {"lidar_rate": 20.0}


def test_load_refuses_other_files(tmp_path):
    path = tmp_path / "x.npz"
    np.savez(path, a=np.zeros(2))
    with pytest.raises(ValueError, match="not a recorded drive"):
        RecordedDrive.load(path)


def test_shapes_are_checked():
    drive = record_drive("office", seed=0, duration=0.2)
    with pytest.raises(ValueError, match="scans"):
        RecordedDrive(**{**_fields(drive), "scans": drive.scans[:-1]})
    with pytest.raises(ValueError, match="truth"):
        RecordedDrive(**{**_fields(drive), "truth": drive.truth[:, :2]})


def _fields(drive: RecordedDrive) -> dict:
    names = ("time", "dt_steps", "truth", "odom", "fresh", "scans", "beam_angles", "mount_offset",
             "max_range", "dt", "world_map", "filter_map", "settings")  # fmt: skip
    return {n: getattr(drive, n) for n in names}


def test_a_recorded_kidnap_is_the_kidnap_of_the_run_with_that_seed(tmp_path):
    """``record_drive(kidnap_at=...)`` carries the car once, at that time, at least 2 m, to the
    pose the kidnap scenario of a run with the same seed draws (`racecar-sim lost-flag`'s)."""
    from mcl.experiments.runs import RunSpec, run_one

    drive = record_drive("basement_loop", seed=3, duration=2.0, kidnap_at=1.0)
    steps = np.linalg.norm(np.diff(drive.truth[:, :2], axis=0), axis=1)
    jumps = np.flatnonzero(steps > 1.0)  # the car moves centimetres a step on its own
    assert jumps.size == 1 and steps[jumps[0]] >= 2.0
    assert drive.time[jumps[0]] == pytest.approx(1.0, abs=drive.dt)
    assert drive.settings["kidnap_at"] == pytest.approx(1.0, abs=drive.dt)
    np.testing.assert_allclose(drive.truth[jumps[0] + 1, :2], drive.settings["kidnap_to"][:2], atol=0.1)
    spec = RunSpec(map="basement_loop", scenario="kidnap", seed=3, duration=1.5, n_particles=100,
                   scenario_settings=(("kidnap_time", 1.0),))  # fmt: skip
    run = run_one(spec, tmp_path / "kidnap.csv")
    assert run.outcome["kidnap_to"] == drive.settings["kidnap_to"]
    # without a kidnap the settings say so, and no step jumps
    plain = record_drive("basement_loop", seed=3, duration=2.0)
    assert plain.settings["kidnap_at"] is None and plain.settings["kidnap_to"] is None
    assert np.linalg.norm(np.diff(plain.truth[:, :2], axis=0), axis=1).max() < 1.0


@pytest.mark.parametrize("kidnap_at", [-1.0, 0.0, math.nan, 2.0, 5.0])
def test_a_kidnap_outside_the_drive_is_refused_naming_kidnap_at(kidnap_at: float) -> None:
    with pytest.raises(ValueError, match=r"record_drive\.kidnap_at"):
        record_drive("basement_loop", seed=3, duration=2.0, kidnap_at=kidnap_at)
