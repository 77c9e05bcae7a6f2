"""The calibration on the shared MIT racecar bags, and the test that the simulator now looks like
the real lidar (skipped when ../shared or the rosbags package is absent).

The reference poses come from scan matching (global search tested separately, slow); one
fixture tracks and judges each bag once, from the lidar pose the global search finds a third into
it (``STARTS``), to keep the suite short.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import racecar_sim  # noqa: F401
from mcl.calibration.scan_stats import residual_fractions
from tests.skips import SHARED, shared_missing

BAGS = SHARED / "bags"
NAMES = ("localization_bag1_2022-03-29-19-23-29.bag", "localization_bag2_2022-03-29-19-24-34.bag")
START = {NAMES[0]: (120, (-19.34, 5.74, 1.136)), NAMES[1]: (120, (-20.49, -0.70, 1.763))}
MAX = 30.0


def _bag(name: str) -> Path:
    path = BAGS / name
    if not path.is_file():
        pytest.skip(shared_missing(path))
    pytest.importorskip("rosbags", reason="reading bags needs the rosbags package")
    return path


@pytest.fixture(scope="module")
def judged(stata_map):
    """Per bag: the recording judged by :mod:`mcl.calibration.judge` (de-skewed scans, exact
    casts from robustly refined poses)."""
    from mcl.calibration.validation import judge_bag

    return [judge_bag(_bag(n), stata_map, np.array(s)) for n, s in zip(NAMES, STARTS, strict=True)]


STARTS = ((-19.737, 4.391, 1.644), (-20.464, -0.832, 1.775))
CLEAN_FROM = (84, 232)
"""The clean stretch of each bag: bag 1 after its first 2.1 s (its short returns fall from
0.23 to 0.03 there: something unmapped beside the start), bag 2's last third (after the
people around the car: 0.35 to 0.04)."""
BLOCK = 40  # scans: one second


@pytest.mark.slow
def test_reference_poses_fit_the_map(judged):
    for bag in judged:
        rec, poses = bag.rec, bag.poses
        assert len(poses.lidar) == len(rec.scans)
        assert np.median(poses.fit15) > 0.7  # most beams within 15 cm of the map
        steps = np.hypot(*np.diff(poses.base[:, :2], axis=0).T)
        # 2.9 m/s at most, scans 25 ms apart: 7 cm. Where the scan fits the map poorly (the first
        # second of bag 1, parts of bag 2) consecutive poses jitter by a few cm, up to 0.16 m
        # apart: a limit of these reference poses (README), hence the percentile
        assert np.percentile(steps, 90) < 0.08 and steps.max() < 0.3


def _clean(judged):
    z = np.vstack([b.z[k:] for b, k in zip(judged, CLEAN_FROM, strict=True)])
    zs = np.vstack([b.z_star[k:] for b, k in zip(judged, CLEAN_FROM, strict=True)])
    poses = np.vstack([b.poses.base[k:] for b, k in zip(judged, CLEAN_FROM, strict=True)])
    return z, zs, poses


@pytest.mark.slow
def test_the_profile_in_the_clean_scene_looks_like_a_clean_corridor(stata_map, judged):
    """The five fractions of the simulated lidar with ``noise_profile="mit_racecar"`` in the
    clean scene, scanning from the clean stretches' own poses, against the real scans of
    those stretches, by the same judge.

    Tolerance per fraction: its standard deviation over the one-second blocks of the two clean
    stretches (at least 0.01, the sampling spread of ~100 simulated scans): a simulated clean
    corridor must be as close to the real one as one second of the real corridor is to
    another. The ideal simulator must fail the same test on three fractions or more.
    """
    from mcl.calibration.validation import simulated_fractions

    z, zs, poses = _clean(judged)
    real = residual_fractions(z, zs, MAX).as_dict()
    blocks = [
        residual_fractions(b.z[i : i + BLOCK], b.z_star[i : i + BLOCK], MAX).as_dict()
        for b, k in zip(judged, CLEAN_FROM, strict=True)
        for i in range(k, len(b.z) - BLOCK + 1, BLOCK)
    ]
    tol = {k: max(0.01, float(np.std([bl[k] for bl in blocks], ddof=1))) for k in real}
    sim = simulated_fractions(stata_map, poses, 3, noise_profile="mit_racecar", scene="clean")
    sim = sim.as_dict()
    for k in real:
        assert abs(sim[k] - real[k]) <= tol[k], (k, sim[k], real[k], tol[k])
    ideal = simulated_fractions(stata_map, poses, 3).as_dict()
    misses = [k for k in real if abs(ideal[k] - real[k]) > tol[k]]
    assert len(misses) >= 3, (ideal, real, tol)


@pytest.mark.slow
def test_global_search_finds_the_car_on_a_real_scan(stata_map):
    """The whole-floor search alone puts bag 1's scan 120 where the tracking fixture starts."""
    from mcl.calibration.reference_poses import scan_beams
    from mcl.calibration.scan_match import ScanMatcher
    from mcl.io import read_bag

    rec = read_bag(_bag(NAMES[0]))
    k, guess = START[NAMES[0]]
    ranges, angles = scan_beams(rec, k, 0.275, True)
    pose, _ = ScanMatcher(stata_map, angles, MAX).global_search(ranges)
    assert np.hypot(pose[0] - guess[0], pose[1] - guess[1]) < 0.1
    assert abs(pose[2] - guess[2]) < 0.03


@pytest.mark.slow
def test_calibrate_noise_reproduces_the_shipped_profile(tmp_path):
    """The command on the two bags writes a profile whose lidar numbers are the shipped ones.

    Tracking starts from given poses here (the shipped profile started from the global search), so the poses differ by millimetres and the numbers by a little: 0.01
    on fractions and EM weights, 10 % on run lengths; the odometry, which differences poses over
    0.25 s, to 25 %.
    """
    from mcl.cli.calibrate_noise import main
    from racecar_sim.sensors.noise_profiles import profile_document

    bags = [str(_bag(n)) for n in NAMES]
    maps = Path(__file__).resolve().parents[2] / ".." / "shared" / "maps" / "stata_basement.yaml"
    out = tmp_path / "profile.yaml"
    # --start: the lidar pose of the scan a third into each bag (what the global search finds)
    starts = ["--start=-19.737,4.391,1.644", "--start=-20.464,-0.832,1.775"]
    assert main([*bags, "--map", str(maps), "--out", str(out), *starts]) == 0
    mine = profile_document(out)
    shipped = profile_document("mit_racecar")
    a, b = mine["settings"]["scan_effects"], shipped["settings"]["scan_effects"]
    for key in ("short_fraction", "long_fraction", "hit_bias", "hit_sigma", "hit_corr"):
        assert a[key] == pytest.approx(b[key], abs=0.01), key
    for key in ("body_first", "body_last", "body_probability", "body_range"):
        assert a[key] == pytest.approx(b[key], abs=0.005), key
    assert "scene" not in mine["settings"]  # the sensor only: the room is a separate setting
    for key in ("short_run", "long_run", "noreturn_run"):
        assert a[key] == pytest.approx(b[key], rel=0.1), key
    assert a["noreturn_probability"] == pytest.approx(b["noreturn_probability"], abs=0.02)
    em, em0 = mine["fit"]["beam_model_em"], shipped["fit"]["beam_model_em"]
    for key in ("z_hit", "z_short", "z_max", "z_rand", "sigma_hit", "bias"):
        assert em[key] == pytest.approx(em0[key], abs=0.01), key
    od, od0 = mine["settings"]["odom_bias"]["scale"], shipped["settings"]["odom_bias"]["scale"]
    assert od[0] == pytest.approx(od0[0], abs=0.02) and od[2] == pytest.approx(od0[2], abs=0.04)
    assert mine["settings"]["odom_additive"] == pytest.approx(
        shipped["settings"]["odom_additive"], rel=0.25
    )


SHARE_TOL = {"openings": 0.015, "clutter_clean": 0.01, "clutter_cluttered": 0.03}
"""Tolerances on the scenes' beam shares: openings +- 0.015 (the two clean stretches differ by
0.005, a hundred simulated scans with the scene drawn anew at each spread by about 0.005, and
their wide runs are cut where the sensor's own noise breaks them); the clean scene's short runs
+- 0.01 (the clean stretches show 0.005 and 0.012); the cluttered scene's +- 0.03 (a fifth of
bag 2's 0.17: its furniture and people come and go along the corridor)."""


@pytest.mark.slow
def test_the_scenes_cover_the_bags_beam_shares_on_both_routes(stata_map, judged):
    """The scenes' wide runs of long returns (openings) and of short returns (furniture, people)
    cover the shares of beams the bags show, from the bags' own poses on stata_basement.yaml
    AND on the noise experiment's route (the wall follower's drives in
    basement_fixed_aligned.yaml), by the same judge. The clean scene against the bags' clean
    stretches, the cluttered one against bag 2. (Sized by wall length, the clean scene's
    openings came back on 25-57 % of the beams on the wall follower's route, 6-8 % on the bags'.)
    """
    from mcl.calibration.room_split import body_block, room_stats
    from mcl.calibration.validation import simulated_room, wall_follower_route
    from tests.conftest import shared_map_path

    body = body_block(np.vstack([b.z for b in judged]))
    spacing = float(np.median(np.diff(judged[0].rec.angles)))

    def real(z, zs):
        zs = np.where(body.mask(zs.shape[1])[None, :], np.inf, zs)
        return room_stats(z, zs, spacing, MAX)

    clean = real(*(np.vstack([getattr(b, f)[k:] for b, k in zip(judged, CLEAN_FROM, strict=True)])
                   for f in ("z", "z_star")))  # fmt: skip
    bag2 = real(judged[1].z, judged[1].z_star)
    world = shared_map_path("basement_fixed_aligned.yaml")
    routes = {
        "bags": (stata_map, np.vstack([b.poses.base for b in judged]), 6),
        "wall follower": (world, wall_follower_route(world, (0, 1, 2)), 1),
    }
    for scene, target in (("clean", clean), ("cluttered", bag2)):
        for route, (grid, poses, every) in routes.items():
            sim = simulated_room(grid, poses, every, body=body.last, noise_profile="mit_racecar", scene=scene)
            got = (route, scene, sim.openings, target.openings, sim.clutter, target.clutter)
            assert abs(sim.openings - target.openings) <= SHARE_TOL["openings"], got
            assert abs(sim.clutter - target.clutter) <= SHARE_TOL[f"clutter_{scene}"], got
