"""The lidar apart from the room: wide runs, the sensor's beams, the body block, correlation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.calibration.room_split import (
    body_block,
    hit_correlation,
    room_stats,
    sensor_beams,
    wide_runs,
)
from racecar_sim.sensors.scan_effects import ScanEffects


@settings(max_examples=80)
@given(
    bits=st.lists(st.lists(st.booleans(), min_size=12, max_size=12), min_size=1, max_size=4),
    width=st.floats(0.05, 0.6),
)
def test_wide_runs_are_the_runs_that_span_the_width(bits, width):
    mask = np.array(bits)
    z_star = np.full(mask.shape, 2.0)  # every beam spans 2 m x 0.05 rad = 0.1 m
    out = wide_runs(mask, z_star, 0.05, width)
    assert not (out & ~mask).any()
    for row, got in zip(mask, out, strict=True):
        i = 0
        while i < row.size:
            if row[i]:
                j = i
                while j < row.size and row[j]:
                    j += 1
                assert got[i:j].all() == ((j - i) * 0.1 >= width - 1e-12)
                assert got[i:j].all() or not got[i:j].any()
                i = j
            else:
                i += 1


def _corridor(n_scans=30, n=600):
    """Straight walls 2 m away: a smooth cast with one depth edge at beam 300."""
    z_star = np.tile(np.r_[np.full(300, 2.0), np.full(n - 300, 6.0)], (n_scans, 1))
    return z_star


def test_sensor_beams_drop_depth_edges_and_wide_runs_only():
    zs = _corridor()
    z = zs + 0.01
    z[:, 100:140] = 1.0  # a box: 40 beams x 2 m x 0.005 rad = 0.4 m wide
    z[:, 200] = 1.0  # a single short beam: the sensor's
    keep = sensor_beams(z, zs, 0.005, 30.0)
    assert not keep[:, 100:140].any()
    assert keep[:, 200].all()
    assert not keep[:, 299:301].any()  # beside the edge
    assert keep[:, 150:290].all()
    st_ = room_stats(z, zs, 0.005, 30.0)
    assert st_.clutter == pytest.approx(40 / 600, abs=1e-9)
    assert st_.openings == 0.0
    assert st_.clutter_ratio == pytest.approx(0.5)


def test_body_block_finds_the_beams_the_car_blocks():
    rng = np.random.default_rng(0)
    z = np.full((100, 500), 3.0)
    hit = rng.random((100, 25)) < 0.7
    z[:, :25][hit] = 0.06
    z[rng.random(z.shape) < 0.01] = 0.1  # scattered close readings elsewhere are not the body
    b = body_block(z)
    assert (b.first, b.last) == (0.0, 25 / 500)
    assert b.probability == pytest.approx(0.7, abs=0.05)
    assert b.range == pytest.approx(0.06)
    assert body_block(np.full((10, 50), 3.0)).last == 0.0


@pytest.mark.parametrize("rho", [0.0, 0.6, 0.95])
def test_hit_correlation_measures_the_simulated_one(rho):
    fx = ScanEffects(hit_sigma=0.03, hit_corr=rho)
    rng = np.random.default_rng(3)
    zs = np.full((60, 800), 3.0)
    z = np.vstack([fx.apply(row, 30.0, rng) for row in zs]).astype(np.float64)
    assert hit_correlation(z, zs, np.ones_like(zs, dtype=bool)) == pytest.approx(rho, abs=0.05)
