"""The wrapper's step hooks (mcl.wrappers.hooks): what a hook is called with, when, in which order,
and that a hook changes nothing of the drive."""

from __future__ import annotations

import math
from types import MappingProxyType

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import racecar_sim  # noqa: F401  (registers RacecarSim-v0)
from mcl import LocalizationWrapper
from mcl.wrappers.hooks import StepRecord
from tests.conftest import room_map

SMALL = {"filter": {"n_particles": 150, "init_spread": (0.1, 0.1, 0.05)}}
START = np.array([6.0, 1.0, 0.3])  # world pose in the room map's free space
ACTION = np.array([0.15, 1.0], dtype=np.float32)
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably|different from the unwrapped"
    "|Not able to test alternative render).*:UserWarning"
)


def make(room, **kwargs) -> LocalizationWrapper:
    # 100 Hz steps and a 40 Hz lidar: some steps carry no fresh scan
    env = gym.make("RacecarSim-v0", map=room, n_beams=61, terminate_on_collision=False, dt=0.01)
    return LocalizationWrapper(env, SMALL, clock=lambda: 0.0, **kwargs)


class Keep:
    """A hook that keeps a copy of what it is called with (and the record itself)."""

    def __init__(self) -> None:
        self.records: list[StepRecord] = []
        self.copies: list[dict] = []

    def __call__(self, record: StepRecord) -> None:
        self.records.append(record)
        self.copies.append(
            {
                "particles": np.array(record.particles),
                "weights": np.array(record.weights),
                "estimate": np.array(record.estimate),
            }
        )


def drive(env: LocalizationWrapper, n: int, seed: int = 0) -> list[tuple[dict, dict]]:
    out = [env.reset(seed=seed, options={"pose": START})]
    for _ in range(n):
        obs, _, _, _, info = env.step(ACTION)
        out.append((obs, info))
    return out


def test_a_hook_gets_one_record_per_reset_and_step_with_that_step_s_values(room) -> None:
    keep = Keep()
    env = make(room, on_step=keep)
    steps = drive(env, 12)
    dt = env.unwrapped.dt
    assert dt == pytest.approx(0.01)
    assert [r.step for r in keep.records] == list(range(13))
    for record, copy, (obs, info) in zip(keep.records, keep.copies, steps, strict=True):
        loc = info["localization"]
        np.testing.assert_array_equal(record.estimate, loc["estimate"])
        np.testing.assert_array_equal(record.estimate, obs["pose_estimate"])
        np.testing.assert_array_equal(record.truth, info["pose"])
        np.testing.assert_array_equal(record.scan, obs["scan"])
        np.testing.assert_array_equal(record.odom, obs["odom"])
        assert record.time == info["time"]
        assert record.info["localization"] is loc
        # the particles and weights are the filter's after this step's update: the estimate is
        # their weighted mean, the covariance theirs
        p, w = copy["particles"], copy["weights"]
        assert p.shape == (150, 3) and w.shape == (150,) and w.sum() == pytest.approx(1.0)
        np.testing.assert_allclose(np.average(p[:, :2], axis=0, weights=w), record.estimate[:2])
        heading = math.atan2(np.sum(w * np.sin(p[:, 2])), np.sum(w * np.cos(p[:, 2])))
        assert record.estimate[2] == pytest.approx(heading, abs=1e-9)
        cov_xy = np.cov(p[:, :2].T, aweights=w, bias=True)
        np.testing.assert_allclose(record.covariance[:2, :2], cov_xy, atol=1e-12)
    times = [r.time for r in keep.records]
    np.testing.assert_allclose(np.diff(times), dt)  # one record per step, dt apart
    assert times[0] == 0.0
    fresh = [r.new_scan for r in keep.records]
    assert fresh[0] is True  # the reset's scan always corrects
    assert fresh[1:] == [bool(info["new_scan"]) for _, info in steps[1:]]
    assert True in fresh[1:] and False in fresh[1:]  # 40 Hz scans over 100 Hz steps
    env.close()


def test_the_record_is_read_only(room) -> None:
    keep = Keep()
    env = make(room, on_step=keep)
    drive(env, 2)
    record = keep.records[-1]
    for name in ("truth", "estimate", "covariance", "particles", "weights", "scan", "odom"):
        array = getattr(record, name)
        assert not array.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0.0
    assert isinstance(record.info, MappingProxyType)
    with pytest.raises(TypeError):
        record.info["pose"] = None  # type: ignore[index]
    with pytest.raises(AttributeError):
        record.step = 5  # type: ignore[misc]
    env.close()


def test_hooks_are_called_in_order_and_can_be_added_and_removed(room) -> None:
    calls: list[tuple[str, int]] = []

    def first(record: StepRecord) -> None:
        calls.append(("first", record.step))

    def second(record: StepRecord) -> None:
        calls.append(("second", record.step))

    def third(record: StepRecord) -> None:
        calls.append(("third", record.step))

    env = make(room, on_step=[first, second])
    assert env.step_hooks == (first, second)
    env.reset(seed=1, options={"pose": START})
    env.add_step_hook(third)
    env.step(ACTION)
    env.remove_step_hook(first)
    env.step(ACTION)
    env.remove_step_hook(second)
    env.remove_step_hook(third)
    env.step(ACTION)
    assert calls == [
        ("first", 0), ("second", 0),
        ("first", 1), ("second", 1), ("third", 1),
        ("second", 2), ("third", 2),
    ]  # fmt: skip
    with pytest.raises(ValueError, match="not a step hook"):
        env.remove_step_hook(first)
    with pytest.raises(TypeError, match="callable"):
        env.add_step_hook("not a function")  # type: ignore[arg-type]
    env.close()
    with pytest.raises(TypeError, match="callable"):
        make(room, on_step=[first, 3])


def test_a_hook_that_raises_reaches_the_caller(room) -> None:
    def broken(record: StepRecord) -> None:
        if record.step == 2:
            raise RuntimeError("hook failed at step 2")

    env = make(room, on_step=broken)
    env.reset(seed=0, options={"pose": START})
    env.step(ACTION)
    with pytest.raises(RuntimeError, match="step 2"):
        env.step(ACTION)
    env.close()


def _estimates(room, seed: int, n: int, hooked: bool) -> np.ndarray:
    env = make(room, on_step=Keep() if hooked else None)
    out = np.array([info["localization"]["estimate"] for _, info in drive(env, n, seed)])
    env.close()
    return out


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 2**16), n=st.integers(1, 15))
def test_a_hook_changes_nothing_of_the_drive(seed: int, n: int) -> None:
    room = room_map()
    np.testing.assert_array_equal(_estimates(room, seed, n, True), _estimates(room, seed, n, False))
