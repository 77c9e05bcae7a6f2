"""Named noise profiles: loading, selection through gym.make, precedence, errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import racecar_sim  # noqa: F401
from racecar_sim.sensors.noise_profiles import load_profile, profile_document, profile_names
from racecar_sim.sensors.scan_effects import OdometryBias, ScanEffects
from racecar_sim.settings.config import EnvConfig, merge_settings


def test_bundled_profiles():
    assert {"ideal", "mit_racecar"} <= set(profile_names())
    assert load_profile("ideal") == {}
    doc = profile_document("mit_racecar")
    # documented origin and the table-6.2 fit travel with the numbers
    assert doc["source"]["bags"] and "stata_basement" in doc["description"]
    em = doc["fit"]["beam_model_em"]
    assert sum(em[k] for k in ("z_hit", "z_short", "z_max", "z_rand")) == pytest.approx(1, abs=1e-3)


def test_gym_make_with_the_profile_uses_its_settings():
    env = gym.make("RacecarSim-v0", noise_profile="mit_racecar")
    u = env.unwrapped
    settings = load_profile("mit_racecar")
    assert isinstance(u.scan_effects, ScanEffects)
    assert u.scan_effects.hit_sigma == settings["scan_effects"]["hit_sigma"]
    assert isinstance(u.odom_bias, OdometryBias)
    assert u.lidar_params.max_range == settings["max_range"]
    obs, _info = env.reset(seed=0)
    assert obs["scan"].shape == (u.lidar_params.n_beams,)
    assert (obs["scan"] <= settings["max_range"]).all()
    env.close()


def test_explicit_settings_override_the_profile():
    cfg = merge_settings(None, {"noise_profile": "mit_racecar", "max_range": 12.0})
    assert cfg.max_range == 12.0
    assert cfg.scan_effects is not None  # the rest of the profile still applies
    assert merge_settings(None, {"noise_profile": "ideal"}).scan_effects is None


def test_same_seed_same_scans_with_the_profile():
    scans = []
    for _ in range(2):
        env = gym.make("RacecarSim-v0", noise_profile="mit_racecar")
        obs, _ = env.reset(seed=4)
        for _ in range(5):
            obs, *_ = env.step(np.array([0.1, 1.0]))
        scans.append(obs["scan"])
    assert np.array_equal(scans[0], scans[1])


def test_unknown_profile_is_a_one_line_error_naming_the_choices():
    with pytest.raises(ValueError, match="mit_racecar") as err:
        EnvConfig(noise_profile="nope") if False else merge_settings(None, {"noise_profile": "nope"})
    assert "\n" not in str(err.value)
