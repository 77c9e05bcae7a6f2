"""The search filter ([mcl.filter.global_search][]): its verdicts from the scan fits, agreement,
the global start beside a filter that holds a wrong pose, and the adoption of its cloud (the
``room`` map, a static car, exact casting)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.filter.global_search import GlobalSearch
from mcl.filter.lost import LostDetector
from mcl.filter.lost_params import LostParams
from mcl.filter.particle_filter import ParticleFilter, ParticleFilterParams
from mcl.filter.place_keeping import PlaceKeeping, place_index
from mcl.filter.sensor_model import SensorModel, SensorModelParams
from racecar_sim.sensors.lidar import Lidar

TRUTH = np.array([6.0, 0.0, 0.4])  # free, 1.95 m from the nearest wall of the room map
ELSEWHERE = np.array([3.0, 3.5, -2.0])  # another free pose of the room map
DT = 0.025


@pytest.fixture(scope="module")
def sensor(room) -> SensorModel:
    return SensorModel(room, SensorModelParams(raycast_method="exact", parallel=False))


def _pf(room, sensor, pose: np.ndarray, seed: int = 0) -> ParticleFilter:
    pf = ParticleFilter(
        room, sensor_model=sensor, params=ParticleFilterParams(n_particles=300), rng=seed
    )
    pf.initialize(pose, (0.02, 0.02, 0.01))
    return pf


# ---------------------------------------------------------------------- verdicts
def test_the_verdict_waits_until_settled_and_needs_the_margin_either_way() -> None:
    search = GlobalSearch(adopt_margin=0.1, adopt_after_s=1.0)
    # not settled (no cloud converged yet): no verdict however large the gap
    assert search.compare(0.9, 0.5, 0.5) == 0
    assert search.fit_gap == pytest.approx(0.4)  # the first gap is taken whole
    assert search.fit == pytest.approx(0.9)  # and the search's own fit, for a restart
    search.converged_for = 1.0
    search.filter = object()  # settled() needs a running search
    # the average moves 1 - exp(-dt / 1 s) of the way: 0.4 + (1 - e^-0.5) (0.0 - 0.4) = 0.243
    assert search.compare(0.5, 0.5, 0.5) == 1
    assert search.fit_gap == pytest.approx(0.4 * math.exp(-0.5))
    assert search.fit == pytest.approx(0.5 + 0.4 * math.exp(-0.5))
    # a long stretch of the search fitting worse by 0.3: the average passes -0.1
    verdicts = [search.compare(0.5, 0.8, 0.5) for _ in range(6)]
    assert verdicts[0] == 0 and verdicts[-1] == -1
    search.fit_gap = 0.05
    assert search.compare(0.55, 0.5, 0.5) == 0  # within the margin: track on


def test_a_better_log_likelihood_adopts_where_the_fits_tie_but_not_a_worse_fit() -> None:
    search = GlobalSearch(adopt_margin=0.1, adopt_after_s=1.0, adopt_loglik=10.0)
    search.converged_for, search.filter = 1.0, object()  # settled
    assert search.compare(0.9, 0.9, 0.5, loglik_gap=15.0) == 1  # fits tie, the scan favours it
    assert search.loglik_gap == pytest.approx(15.0)
    search.fit_gap, search.loglik_gap = math.nan, math.nan
    assert search.compare(0.9, 0.9, 0.5, loglik_gap=5.0) == 0  # not by enough: track on
    # a drop of the gap is averaged: 5 + (1 - e^-0.5) (40 - 5) = 18.8 >= 10
    assert search.compare(0.9, 0.9, 0.5, loglik_gap=40.0) == 1
    search.fit_gap, search.loglik_gap = math.nan, math.nan
    assert search.compare(0.7, 0.9, 0.5, loglik_gap=100.0) == -1  # fits worse by 0.2: refused
    # without a threshold the log-likelihood is ignored
    plain = GlobalSearch(adopt_margin=0.1)
    plain.converged_for, plain.filter = 1.0, object()
    assert plain.compare(0.9, 0.9, 0.5, loglik_gap=1e6) == 0


def test_a_search_that_settled_on_a_wrong_place_finds_the_car_through_its_injected_poses(
    room, sensor
) -> None:
    lidar = Lidar(room)
    ends = {}
    for share in (0.0, 0.05):
        pf = _pf(room, sensor, ELSEWHERE)
        search = GlobalSearch(inject_share=share)
        search.start(pf)
        wrong = search.filter.poses_around(ELSEWHERE, (0.05, 0.05, 0.02), 300)
        search.filter.set_particles(wrong)  # settled on the wrong place
        rng = np.random.default_rng(3)
        for _ in range(120):
            search.correct(lidar.measure(TRUTH, rng), DT)
        ends[share] = search.filter.estimate()
        assert search.filter.recovery_share == share
    assert math.dist(ends[0.0][:2], ELSEWHERE[:2]) < 0.3  # nothing new: it stays
    assert math.dist(ends[0.05][:2], TRUTH[:2]) < 0.5  # poses that landed near the car took over


def test_a_search_agrees_within_a_metre_and_half_a_radian(room, sensor) -> None:
    search = GlobalSearch(agree_m=1.0, agree_rad=0.5)
    assert not search.agrees_with(TRUTH)  # no search runs
    pf = _pf(room, sensor, TRUTH)
    search.start(pf)
    assert search.running
    search.filter.initialize(TRUTH, (0.01, 0.01, 0.01))
    assert search.agrees_with(TRUTH + np.array([0.5, 0.5, 0.3]))
    assert not search.agrees_with(TRUTH + np.array([1.0, 0.5, 0.0]))  # 1.12 m
    assert not search.agrees_with(TRUTH + np.array([0.0, 0.0, 0.7]))
    assert search.agrees_with(TRUTH + np.array([0.0, 0.0, 2 * math.pi - 0.2]))  # wrapped: 0.2 rad


def test_a_search_is_stuck_once_converged_long_enough_on_a_place_fitting_under_the_bar() -> None:
    search = GlobalSearch()
    search.converged_for, search.fit = 2.9, 0.6
    assert not search.stuck(3.0, 0.75)  # not long enough
    search.converged_for = 3.0
    assert search.stuck(3.0, 0.75)
    assert not search.stuck(3.0, 0.6)  # at the bar is not under it
    search.fit = math.nan  # not compared yet
    assert not search.stuck(3.0, 0.75)


def test_a_rival_is_another_settled_place_that_fits_at_least_as_well(room, sensor) -> None:
    search = GlobalSearch(agree_m=1.0, agree_rad=0.5, adopt_after_s=1.0)
    assert not search.rival(ELSEWHERE)  # no search runs
    search.start(_pf(room, sensor, ELSEWHERE))
    search.filter.initialize(TRUTH, (0.01, 0.01, 0.01))
    search.fit_gap = 0.02  # fits a little better than the filter's place
    assert not search.rival(ELSEWHERE)  # not settled yet
    search.converged_for = 1.0
    assert search.rival(ELSEWHERE)
    assert not search.rival(TRUTH + np.array([0.5, 0.0, 0.1]))  # the filter's own place
    search.fit_gap = 0.0
    assert not search.rival(ELSEWHERE)  # the gap must be above 0
    search.fit_gap = -0.05
    assert not search.rival(ELSEWHERE)  # fits worse
    search.fit_gap = math.nan
    assert not search.rival(ELSEWHERE)  # not compared yet


def test_a_search_whose_weight_hops_to_another_place_counts_as_converged_anew(room, sensor) -> None:
    pf = _pf(room, sensor, TRUTH)
    lidar, rng = Lidar(room), np.random.default_rng(3)
    search = GlobalSearch(converged_sd=0.5, adopt_after_s=0.05)
    search.start(pf)
    search.filter.initialize(ELSEWHERE, (0.01, 0.01, 0.01))
    for _ in range(3):  # converged on ELSEWHERE, and settled there
        search.correct(lidar.measure(ELSEWHERE, rng), DT)
        search.compare(0.9, 0.5, DT)
    assert search.converged_for == pytest.approx(3 * DT) and search.settled()
    assert search.fit_gap == pytest.approx(0.4)
    # a rival place kept with a millionth of the weight; the car's scan moves the weight there
    poses = np.vstack([np.tile(ELSEWHERE, (150, 1)), np.tile(TRUTH, (150, 1))])
    search.filter.set_particles(poses, np.r_[np.ones(150), np.full(150, 1e-6)])
    assert math.dist(search.filter.estimate()[:2], ELSEWHERE[:2]) < 0.01
    search.correct(lidar.measure(TRUTH, rng), DT)
    assert math.dist(search.filter.estimate()[:2], TRUTH[:2]) < 0.01  # one tight cloud again
    assert search.converged_for == 0.0 and not search.settled()  # but on another place
    assert math.isnan(search.fit_gap) and math.isnan(search.fit)  # the old place's averages go
    search.correct(lidar.measure(TRUTH, rng), DT)
    assert search.converged_for == pytest.approx(DT)  # counted from the hop


# ---------------------------------------------------------------------- the search
def test_a_search_beside_a_wrong_filter_finds_the_car_and_the_filter_takes_its_cloud(
    room, sensor
) -> None:
    pf = _pf(room, sensor, ELSEWHERE)  # sure of a pose 4.7 m from the car
    lidar, rng = Lidar(room), np.random.default_rng(5)
    search = GlobalSearch(converged_sd=0.5, adopt_margin=0.1, adopt_after_s=0.25)
    search.start(pf)
    first = search.filter.particles.copy()
    assert first.shape[0] == pf.global_particle_count() > pf.params.n_particles
    assert np.ptp(first[:, 0]) > 5.0  # uniform over the room, not around either pose
    detector = LostDetector(LostParams())
    verdict = 0
    for _ in range(80):
        scan = lidar.measure(TRUTH, rng)
        pf.correct(scan)
        search.correct(scan, DT)
        if search.converged_for > 0:
            mine = search.filter.estimate()
            verdict = search.compare(
                detector.fit_at(search.filter, mine, scan),
                detector.fit_at(pf, pf.estimate(), scan),
                DT,
            )
            if verdict:
                break
    assert verdict == 1
    assert search.filter.n_particles == pf.params.n_particles  # shrunk once it settled
    assert math.dist(search.filter.estimate()[:2], TRUTH[:2]) < 0.2
    search.adopt(pf)
    assert not search.running and search.adoptions == 1
    assert pf.n_particles == 300
    assert math.dist(pf.estimate()[:2], TRUTH[:2]) < 0.2
    assert abs(math.remainder(pf.estimate()[2] - TRUTH[2], 2 * math.pi)) < 0.1


def test_a_denser_first_draw_is_weighed_once_and_lands_on_the_car_more_often(
    room, sensor
) -> None:
    """24 searches per density started beside a filter sure of a wrong pose, one scan of the
    car each: how often the cloud, resampled to the global count, sits on the car (more than
    half of it within 0.3 m and 0.15 rad). Measured: 3 of 24 at 20 poses per m² (the global
    count), 15 of 24 with a first draw of 200 per m²."""
    lidar = Lidar(room)
    n = _pf(room, sensor, ELSEWHERE).global_particle_count()
    on_the_car = {}
    for density in (0.0, 200.0):
        hits = 0
        for seed in range(24):
            search = GlobalSearch(draw_density=density)
            search.start(_pf(room, sensor, ELSEWHERE, seed))
            assert search.filter.n_particles == n  # the extra poses join at the next scan
            search.correct(lidar.measure(TRUTH, np.random.default_rng(seed)), DT)
            assert search.filter.last_injected == max(0, math.ceil(density * room.free_area) - n)
            assert search.filter.n_particles == n  # resampled back to the global count
            p = search.filter.particles
            turn = np.abs(np.remainder(p[:, 2] - TRUTH[2] + math.pi, 2 * math.pi) - math.pi)
            near = (np.hypot(*(p[:, :2] - TRUTH[:2]).T) < 0.3) & (turn < 0.15)
            hits += int(near.mean() > 0.5)
        on_the_car[density] = hits
    assert on_the_car[200.0] > 2 * on_the_car[0.0], on_the_car
    capped = GlobalSearch(draw_density=200.0, draw_max=n + 7)
    capped.start(_pf(room, sensor, ELSEWHERE))
    capped.correct(lidar.measure(TRUTH, np.random.default_rng(0)), DT)
    assert capped.filter.last_injected == 7


def test_adopt_without_a_search_is_refused(room, sensor) -> None:
    with pytest.raises(RuntimeError, match="no search runs"):
        GlobalSearch().adopt(_pf(room, sensor, TRUTH))


@pytest.mark.parametrize(
    ("name", "value"),
    [("converged_sd", 0.0), ("agree_m", -1.0), ("agree_rad", math.inf), ("adopt_after_s", "1"),
     ("adopt_margin", 1.5), ("converged_sd", True), ("inject_share", 0.6),
     ("adopt_loglik", 0.0), ("inject_share", True), ("inject_share", "0.1"), ("adopt_loglik", "10"),
     ("draw_density", -1.0), ("draw_density", math.inf), ("draw_density", "100"), ("draw_max", 0),
     ("draw_max", 2.5), ("scan_exponent", 0.0), ("scan_exponent", 1.2), ("scan_exponent", True),
     ("places", 4.0)],
)  # fmt: skip
def test_bad_settings_are_refused_naming_them(name: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"GlobalSearch {name} = "):
        GlobalSearch(**{name: value})


def test_the_widest_position_sd_is_the_square_root_of_the_largest_xy_eigenvalue() -> None:
    from mcl.filter.uncertainty import largest_position_sd

    assert largest_position_sd(np.diag([4.0, 1.0, 9.0])) == pytest.approx(2.0)  # heading ignored
    turned = np.array([[2.5, 1.5, 0.0], [1.5, 2.5, 0.0], [0.0, 0.0, 0.0]])  # eigenvalues 4 and 1
    assert largest_position_sd(turned) == pytest.approx(2.0)


def test_a_search_that_keeps_its_places_keeps_them_and_lands_on_the_car_as_often(room, sensor) -> None:
    """12 searches each way beside a filter sure of a wrong pose, 30 scans of the standing car:
    plain resampling gathers each search on a few places (where its first scans happened to
    favour a pose), the kept places stay (hundreds of them), and the estimate lands on the car
    at least as often. Measured: 2-4 places plainly, 221-224 kept; on the car in 4 and 7 of
    the 12."""
    lidar = Lidar(room)
    keeping = PlaceKeeping()
    on_the_car, places = {}, {}
    for name, kept, power in (("plain", None, 1.0), ("kept", keeping, 0.25)):
        hits, counts = 0, []
        for seed in range(12):
            search = GlobalSearch(places=kept, scan_exponent=power)
            search.start(_pf(room, sensor, ELSEWHERE, seed))
            rng = np.random.default_rng(seed)
            for _ in range(30):
                search.predict(np.zeros(3), DT)
                search.correct(lidar.measure(TRUTH, rng), DT)
            counts.append(np.unique(place_index(search.filter.particles, keeping)).size)
            hits += int(math.dist(search.filter.estimate()[:2], TRUTH[:2]) < 0.3)
        on_the_car[name], places[name] = hits, (min(counts), max(counts))
    assert places["plain"][1] <= 10 and places["kept"][0] >= 100, places
    assert on_the_car["kept"] >= on_the_car["plain"], on_the_car
