"""Calibration pieces on synthetic data with known answers: EM of the beam model, odometry
error model and lag, scan matching, de-skewing."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from mcl.calibration.beam_em import fit_beam_model
from mcl.calibration.odometry_fit import best_lag, fit_odometry
from mcl.calibration.pipeline import hit_sigma_for_ratio
from mcl.calibration.reference_poses import (
    ReferencePoses,
    compose,
    deskew,
    integrate_twist,
    relative,
)
from mcl.calibration.scan_match import ScanMatcher
from mcl.calibration.scan_stats import failure_stats, residual_fractions
from mcl.io import BagData
from racecar_sim.raycast import RayCaster

MAX = 30.0


def _beam_data(rng, n, w, sigma, bias, lam):
    z_star = rng.uniform(0.5, 10.0, n)
    u = rng.random(n)
    z = z_star + bias + sigma * rng.standard_normal(n)
    t1, t2, t3 = w[1], w[1] + w[2], w[1] + w[2] + w[3]
    short = u < t1
    v = rng.random(n)
    z[short] = -np.log1p(-v[short] * -np.expm1(-lam * z_star[short])) / lam
    z[(u >= t1) & (u < t2)] = np.nan
    rand = (u >= t2) & (u < t3)
    z[rand] = rng.uniform(0, MAX, rand.sum())
    return z, z_star


def test_em_recovers_the_parameters_it_was_given():
    rng = np.random.default_rng(0)
    w = (0.75, 0.08, 0.05, 0.12)
    z, zs = _beam_data(rng, 300_000, w, sigma=0.04, bias=0.015, lam=1.5)
    fit = fit_beam_model(z, zs, MAX)
    assert fit.z_hit == pytest.approx(0.75, abs=0.02)
    assert fit.z_max == pytest.approx(0.05, abs=0.002)  # the no-return fraction, exactly
    assert fit.z_short == pytest.approx(0.08, abs=0.02)
    assert fit.z_rand == pytest.approx(0.12, abs=0.02)
    assert fit.sigma_hit == pytest.approx(0.04, rel=0.05)
    assert fit.bias == pytest.approx(0.015, abs=0.002)
    assert fit.lambda_short == pytest.approx(1.5, rel=0.25)
    assert fit.z_hit + fit.z_short + fit.z_max + fit.z_rand == pytest.approx(1.0)
    unbiased = fit_beam_model(z, zs, MAX, fit_bias=False)
    assert unbiased.bias == 0.0 and unbiased.sigma_hit > fit.sigma_hit


def test_em_refuses_too_few_beams():
    with pytest.raises(ValueError, match="at least 100"):
        fit_beam_model(np.ones(10), np.ones(10), MAX)


def test_residual_fractions_count_what_they_say():
    zs = np.full(10, 5.0)
    z = np.array([5.0, 5.04, 5.1, 4.0, 6.0, np.nan, np.nan, 5.0, 5.0, 5.0])
    f = residual_fractions(z, zs, MAX)
    assert f.noreturn == pytest.approx(0.2)
    assert f.short == pytest.approx(0.1) and f.long == pytest.approx(0.1)
    assert f.within5 == pytest.approx(5 / 8) and f.within15 == pytest.approx(6 / 8)
    s = failure_stats(np.vstack([z, z]), np.vstack([zs, zs]), MAX)
    assert s.run_length["noreturn"] == 2.0 and s.next_same["noreturn"] == 0.5


def _recording(times, twist, scan_times, ranges=None, angles=None):
    """A synthetic recording: odometry twists at ``times``, scans at ``scan_times``."""
    angles = np.zeros(3) if angles is None else angles
    ranges = np.zeros((len(scan_times), angles.size)) if ranges is None else ranges
    return BagData(
        path=Path("synthetic"), scan_topic="/scan", odom_topic="/odom", scan_times=scan_times,
        scans=ranges, angles=angles, range_min=0.02, range_max=MAX, scan_frame="laser",
        odom_times=times, odom_twist=twist, odom_pose=np.zeros_like(twist), mount_offset=0.275,
        mount_source="argument",
    )  # fmt: skip


def test_odometry_fit_recovers_bias_noise_and_lag():
    """Truth drives a varying twist; the odometry reads it 0.1 s early, 5 % slow, 10 % over on
    omega, plus noise. Reference poses: the truth integrated (exact)."""
    rng = np.random.default_rng(1)
    dt = 0.02
    t = np.arange(0, 60, dt)
    v = 2.0 + 0.5 * np.sin(0.7 * t)
    w = 0.8 * np.sin(1.3 * t)
    lead = 0.1
    v_odo = 0.95 * (2.0 + 0.5 * np.sin(0.7 * (t + lead))) + 0.05 * rng.standard_normal(t.size)
    w_odo = 1.10 * 0.8 * np.sin(1.3 * (t + lead)) + 0.05 * rng.standard_normal(t.size)
    scan_t = np.arange(0, 59.5, 0.025)
    base = [np.zeros(3)]
    truth = np.column_stack([v, np.zeros_like(v), w])
    for a, b in itertools.pairwise(scan_t):
        base.append(compose(base[-1], integrate_twist(t, truth, a, b)))
    base = np.array(base)
    poses = ReferencePoses(base, base, np.zeros(len(base)), np.ones(len(base)), np.ones(len(base)),
                           0, False)  # fmt: skip
    rec = _recording(t, np.column_stack([v_odo, np.zeros_like(v), w_odo]), scan_t)
    lag = best_lag([(rec, poses)], lags=np.arange(-0.2, 0.201, 0.02))
    assert lag == pytest.approx(lead, abs=0.021)
    fit = fit_odometry([(rec, poses)], lag=lag)
    assert fit.scale_bias[0] == pytest.approx(-0.05, abs=0.01)
    assert fit.scale_bias[2] == pytest.approx(0.10, abs=0.02)
    # per-message noise 0.05 averaged over 0.25 s (12.5 messages): ~0.014 at window level
    assert fit.additive[0] == pytest.approx(0.05 / math.sqrt(12.5), rel=0.5)
    assert fit.lag == lag


def test_se2_helpers_and_deskew():
    a = np.array([1.0, 2.0, 0.5])
    b = np.array([0.3, -0.2, 1.0])
    assert np.allclose(relative(a, compose(a, b)), b)
    assert np.allclose(integrate_twist(np.array([0.0]), np.array([[1.0, 0.0, 0.0]]), 0.0, 2.0),
                       [2.0, 0.0, 0.0])  # fmt: skip
    r = np.array([2.0, 3.0, np.nan])
    ang = np.array([-0.5, 0.0, 0.5])
    r0, a0 = deskew(r, ang, 0.01, 0.0, 0.0, 0.275)
    assert np.allclose(r0[:2], r[:2]) and np.isnan(r0[2]) and np.allclose(a0, ang)
    # moving forward: later beams were taken from farther ahead, so seen from the first beam's
    # pose the straight-ahead end point is farther away
    r1, _ = deskew(np.array([2.0, 2.0]), np.array([0.0, 0.0]), 0.01, 1.0, 0.0, 0.275)
    assert r1[0] == pytest.approx(2.0) and r1[1] == pytest.approx(2.01)


def test_scan_matcher_finds_a_synthetic_scan_on_the_room(room):
    angles = np.linspace(-2.35, 2.35, 541)
    true = np.array([6.3, 1.1, 2.2])
    ranges = RayCaster(room, 30.0).cast(true, angles)[0]
    ranges = ranges + np.random.default_rng(0).normal(0, 0.01, ranges.size)
    m = ScanMatcher(room, angles, 30.0)
    pose, _loss = m.global_search(ranges)
    assert np.hypot(*(pose[:2] - true[:2])) < 0.03
    assert abs((pose[2] - true[2] + math.pi) % (2 * math.pi) - math.pi) < 0.01
    local, _ = m.refine(true + np.array([0.08, -0.05, 0.03]), ranges)
    assert np.hypot(*(local[:2] - true[:2])) < 0.02


@pytest.mark.parametrize("ratio", [0.5, 0.7, 0.9])
def test_hit_sigma_for_ratio_inverts_the_ratio(ratio):
    s = hit_sigma_for_ratio(ratio, 0.01)
    rng = np.random.default_rng(0)
    e = 0.01 + s * rng.standard_normal(400_000)
    assert (np.abs(e) <= 0.05).sum() / (np.abs(e) <= 0.15).sum() == pytest.approx(ratio, abs=0.005)


def test_poses_from_a_replay_trajectory(room, tmp_path):
    """Poses read from a replay's trajectory.csv: the lidar sits mount ahead, exact scans fit."""
    from mcl.calibration.reference_poses import poses_from_trajectory

    angles = np.linspace(-2.35, 2.35, 181)
    base = np.array([[6.0, 1.0, 2.0], [6.05, 1.02, 2.01]])
    lidar = compose(base, np.array([0.275, 0.0, 0.0]))
    ranges = RayCaster(room, 30.0).cast(lidar, angles)
    rec = _recording(np.array([0.0]), np.zeros((1, 3)), np.array([0.0, 0.025]), ranges, angles)
    path = tmp_path / "trajectory.csv"
    path.write_text("time,x,y,theta,scan_fit\n" + "".join(f"{i},{x},{y},{t},1\n" for i, (x, y, t) in enumerate(base)))
    poses = poses_from_trajectory(rec, ScanMatcher(room, angles, MAX), path)
    assert np.allclose(poses.lidar, lidar) and np.allclose(poses.base, base)
    assert (poses.fit5 == 1.0).all()
    path.write_text("time,x,y,theta\n0,6,1,2\n")
    with pytest.raises(ValueError, match="1 rows for 2 scans"):
        poses_from_trajectory(rec, ScanMatcher(room, angles, MAX), path)
