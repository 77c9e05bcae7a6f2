"""The peers benchmark's default-filter update: its path, its scans and what it times."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.bench.default_update import DEFAULT_STAGES, DefaultUpdate, odometry_path
from mcl.filter.sensor_model import SensorModel, SensorModelParams


def test_the_path_is_the_arc_the_twist_drives() -> None:
    # 1 m/s forward turning at 0.5 rad/s: a circle of radius 2 m about the point 2 m to the left
    start = np.array([3.0, -1.0, 0.3])
    path = odometry_path(start, np.array([1.0, 0.0, 0.5]), 0.1, 40)
    centre = start[:2] + 2.0 * np.array([-math.sin(0.3), math.cos(0.3)])
    assert np.allclose(np.hypot(*(path[:, :2] - centre).T), 2.0, atol=1e-9)
    turned = np.angle(np.exp(1j * (path[:, 2] - start[2])))
    assert np.allclose(turned, np.angle(np.exp(1j * 0.05 * np.arange(40))), atol=1e-9)
    assert np.all((path[:, 2] >= -math.pi) & (path[:, 2] < math.pi))


def test_it_tracks_the_car_along_the_path_without_raising_the_lost_flag(default_map) -> None:
    sm = SensorModel(
        default_map, SensorModelParams(num_beams_per_particle=30, raycast_method="exact")
    )
    start = default_map.sample_free_poses(np.random.default_rng(3), 1, clearance=1.0)[0]
    twist = np.array([1.0, 0.0, 0.0])
    steps = 10
    path = odometry_path(start, twist, 0.025, steps + 1)
    if not default_map.is_free(path[:, :2]).all():
        pytest.skip("the sampled start faces a wall")
    update = DefaultUpdate(default_map, sm, 300, start, twist, 0.025, steps, (0.2, 0.2, 0.05), 1)
    times = [update.step() for _ in range(steps)]
    assert all(set(t) == set(DEFAULT_STAGES) and min(t.values()) >= 0 for t in times)
    assert math.hypot(*(update.filter.estimate()[:2] - path[-1, :2])) < 0.2
    assert update.steps == steps and update.lost == 0 and update.searching == 0


def test_a_path_through_a_wall_is_refused(default_map) -> None:
    sm = SensorModel(
        default_map, SensorModelParams(num_beams_per_particle=10, raycast_method="exact")
    )
    start = default_map.sample_free_poses(np.random.default_rng(0), 1)[0]
    with pytest.raises(ValueError, match="leaves the free space"):
        DefaultUpdate(
            default_map, sm, 50, start, np.array([400.0, 0.0, 0.0]), 1.0, 2, (0.1,) * 3, 0
        )


def test_the_peers_flag_adds_the_default_filter_line(capsys) -> None:
    from mcl.bench import peer_rangelibc, peers
    from racecar_sim.maps import bundled

    args = ["--only", "rangelibc", "--default-filter", "--map", str(bundled("basement_loop"))]
    small = ["--particles", "200", "--beams", "10", "--updates", "2", "--warmup", "1"]
    assert peers.main([*args, *small, "--threads", "1"]) in (0, None)
    text = capsys.readouterr().out
    if not peer_rangelibc.available():
        assert "skipped" in text
        return
    line = next(x for x in text.splitlines() if x.startswith("default filter"))
    assert "of 3 updates" in line and "lost flag up in 0" in line
