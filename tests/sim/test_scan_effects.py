"""Correlated lidar failures (racecar_sim.sensors.scan_effects) and the odometry bias."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from racecar_sim.sensors.scan_effects import OdometryBias, ScanEffects

MAX = 30.0


def _effects(**kw) -> ScanEffects:
    base = dict(
        hit_bias=0.02, hit_sigma=0.03, short_fraction=0.15, short_run=12.0, long_fraction=0.07,
        long_run=6.0, long_excess=0.3, noreturn_edges=(0.0, 5.0, 10.0, 30.0),
        noreturn_probability=(0.01, 0.2, 0.7), noreturn_run=10.0,
    )  # fmt: skip
    base.update(kw)
    return ScanEffects(**base)


def _classify(z, r):
    res = z - r
    nr = z >= MAX
    return {
        "noreturn": nr,
        "short": ~nr & (res < -0.15),
        "long": ~nr & (res > 0.15),
        "hit": ~nr & (np.abs(res) <= 0.15),
    }


def test_fractions_and_run_lengths_match_the_settings():
    """Stationary fractions per range bin and mean run lengths come out as set (many beams)."""
    eff = _effects()
    rng = np.random.default_rng(3)
    for true_range, p_nr in ((3.0, 0.01), (7.0, 0.2)):
        r = np.full(2000, true_range)
        scans = np.array([eff.apply(r, MAX, rng) for _ in range(60)], dtype=np.float64)
        c = _classify(scans, r)
        assert c["noreturn"].mean() == pytest.approx(p_nr, abs=0.02 + 0.15 * p_nr)
        back = 1 - p_nr
        assert c["short"].mean() == pytest.approx(0.15 * back, rel=0.15)
        assert c["long"].mean() == pytest.approx(0.07 * back, rel=0.15)
        hits = scans[c["hit"]] - true_range
        assert hits.mean() == pytest.approx(0.02, abs=0.003)
        assert hits.std() == pytest.approx(0.03, rel=0.08)
    # runs: neighbouring failures cluster (mean run of short returns ~ short_run)
    r = np.full(4000, 3.0)
    scans = np.array([eff.apply(r, MAX, rng) for _ in range(30)], dtype=np.float64)
    short = _classify(scans, r)["short"]
    starts = (short[:, 1:] & ~short[:, :-1]).sum() + short[:, 0].sum()
    assert short.sum() / starts == pytest.approx(12.0, rel=0.2)
    # independent draws would give P(next short | short) ~ 0.15; runs give ~ 1 - 1/12
    assert (short[:, 1:] & short[:, :-1]).sum() / short[:, :-1].sum() > 0.85


def test_no_surface_means_no_return_and_long_returns_lie_behind():
    eff = _effects(long_fraction=0.5, short_fraction=0.0, noreturn_probability=(0.0, 0.0, 0.0))
    r = np.r_[np.full(500, 4.0), np.full(500, MAX)]
    z = eff.apply(r, MAX, np.random.default_rng(0)).astype(np.float64)
    assert (z[500:] == MAX).all()
    long = z[:500] > 4.15
    assert 0.35 < long.mean() < 0.65
    assert z[:500][long].mean() > 4.15 + 0.2  # excess 0.15 + exponential (mean 0.3)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    ranges=st.lists(st.floats(0.0, MAX), min_size=1, max_size=300),
)
def test_output_stays_in_range_and_is_reproducible(seed, ranges):
    eff = _effects()
    r = np.asarray(ranges)
    a = eff.apply(r, MAX, np.random.default_rng(seed))
    b = eff.apply(r, MAX, np.random.default_rng(seed))
    assert a.dtype == np.float32 and a.shape == r.shape
    assert np.array_equal(a, b)
    assert ((a >= 0) & (a <= MAX)).all()


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"short_fraction": 0.6, "long_fraction": 0.5}, "short_fraction"),
        ({"noreturn_edges": (0.0, 5.0)}, "one more entry"),
        ({"noreturn_edges": (1.0, 5.0, 9.0, 30.0)}, "start at 0"),
        ({"noreturn_probability": (0.1, 1.0, 0.2)}, r"\[0, 1\)"),
        ({"short_run": 0.5}, "short_run"),
        ({"hit_sigma": -1.0}, "hit_sigma"),
    ],
)
def test_bad_settings_are_refused_naming_them(kw, match):
    with pytest.raises(ValueError, match=match):
        _effects(**kw)


def test_from_mapping_names_unknown_keys():
    with pytest.raises(ValueError, match="unknown scan_effects setting"):
        ScanEffects.from_mapping({"hit_sigmaa": 0.1})


def test_odometry_bias():
    b = OdometryBias(scale=(-0.05, 0.0, 0.1), offset=(0.01, -0.02, 0.03))
    out = b.apply(np.array([2.0, 0.0, 1.0]))
    assert np.allclose(out, [2.0 * 0.95 + 0.01, -0.02, 1.1 + 0.03], atol=1e-6)
    with pytest.raises(ValueError, match="scale"):
        OdometryBias(scale=(0.0, 1.0))


def test_correlated_hit_error_has_the_asked_correlation_and_spread():
    fx = ScanEffects(hit_sigma=0.03, hit_corr=0.9)
    rng = np.random.default_rng(0)
    e = np.vstack([fx.apply(np.full(1000, 3.0), 30.0, rng) - 3.0 for _ in range(40)])
    assert e.std() == pytest.approx(0.03, rel=0.1)
    lag1 = np.mean([np.corrcoef(row[:-1], row[1:])[0, 1] for row in e])
    assert lag1 == pytest.approx(0.9, abs=0.03)
    white = np.vstack(
        [ScanEffects(hit_sigma=0.03).apply(np.full(1000, 3.0), 30.0, rng) - 3.0 for _ in range(40)]
    )
    assert abs(np.mean([np.corrcoef(r[:-1], r[1:])[0, 1] for r in white])) < 0.03


def test_the_body_blocks_its_beams_only_and_as_often_as_asked():
    fx = ScanEffects(body_first=0.0, body_last=0.05, body_probability=0.7, body_range=0.06)
    rng = np.random.default_rng(1)
    scans = np.vstack([fx.apply(np.full(1000, 4.0), 30.0, rng) for _ in range(200)])
    on = np.isclose(scans, 0.06)
    assert on[:, :50].mean() == pytest.approx(0.7, abs=0.03)
    assert not on[:, 50:].any()


def test_a_noreturn_run_ends_where_the_range_gets_nearer():
    """Beams alternate far (25 m, always a drop-out) and near (1 m, never): a run begun far
    must not carry into the near beams."""
    fx = ScanEffects(
        noreturn_edges=(0.0, 5.0, 30.0), noreturn_probability=(0.0, 0.99), noreturn_run=50.0
    )
    r = np.tile(np.r_[np.full(20, 25.0), np.full(20, 1.0)], 25)
    scan = fx.apply(r, 30.0, np.random.default_rng(2))
    assert (scan[r < 5] < 30.0).all()
    assert (scan[r > 5] >= 30.0).mean() > 0.9
