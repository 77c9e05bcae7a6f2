"""Kidnaps in the honest world (the car in ``basement_fixed_aligned.yaml``, the filter holding the
out-of-date ``stata_basement.yaml``, the ``mit_racecar`` noise) of `racecar-sim lost-flag`:

- clean kidnap seed 4 carries the car into the corridor at y = -2 m, whose other end, 25 m west,
  fits the same share of beams; only the scans' log-likelihood tells them apart;
- cluttered kidnap seed 5 (the search compared after 1 s settled): a search filter that
  resamples plainly settles on a place that fits the scan well under the car's usual fit and,
  undecided, would track it on; started again, it finds the car; keeping its rival places, it
  finds the car without starting again;
- cluttered kidnap seed 2: a search that resamples plainly settles on places that fit worse
  than the filter's and starts again, four times; keeping its places and tempering its scans, it
  settles on the car's place at once;
- clean kidnap seed 7: the car stands after the kidnap, and the search's weight hops between the
  car's place and one 15 m away every 0.6-1 s; settled for half a second, the search is compared
  with the filter before it hops, and the filter takes the car's place;
- cluttered kidnap seed 8: the car is found at once, on a place the old map explains less well
  than the one it left; searches that settle on the filter's place take the flag down;
- cluttered kidnap seed 13: the same, where the old map explains only half the beams at the
  car's new place; in the filter's second draw the flag stays down over the car found there,
  judged by the place's own fit once the searches confirmed it.

Every drive here learns the odometry's scale between confirmed poses (``source="map"``), as when
these kidnaps were chosen: which place a search settles on hangs on the filter's draw, and the
default scale, learned from the scans, draws otherwise (the 40 honest kidnaps with the defaults:
docs/localization_changing_world.md)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mcl.experiments.lost_flag import LostFlagConfig, default_worlds, kidnap_times
from mcl.experiments.runs import run_one
from mcl.wrappers.error_log import ErrorLog, read_error_log
from mcl.wrappers.localization import as_localization_config
from tests.skips import need_shared

BRIDGES = {"filter": {"odometry_scale": {"source": "map"}}}


def _kidnap_log(
    tmp_path, settings: dict | None, world: str, seed: int, after_kidnap: float = 15.0,
    draw: int = 0,
) -> ErrorLog:
    """The error log of kidnap ``seed`` of ``world``, ``after_kidnap`` seconds driven after the
    kidnap at 10 s, the filter seeded by ``seed + draw``."""
    need_shared("maps/basement_fixed_aligned.yaml", "maps/stata_basement.yaml")
    from tests.skips import SHARED

    worlds = [w for w in default_worlds(SHARED) if w.name == world]
    config = LostFlagConfig(
        worlds=tuple(worlds), seeds=0, kidnap_seeds=seed + 1, after_kidnap=after_kidnap,
        filter_seed_offset=draw,
    )
    spec = config.runs()[seed]
    assert spec.scenario == "kidnap" and spec.seed == seed
    settings = {**(settings or {}), **BRIDGES}
    spec = replace(spec, config=as_localization_config(settings))
    log = tmp_path / "kidnap.csv"
    run_one(spec, log)
    return read_error_log(log)


def _recovered_after(
    tmp_path, settings: dict | None, world: str = "clean", seed: int = 4,
    after_kidnap: float = 15.0,
) -> float:
    """Seconds from the kidnap until the error stays under 0.5 m for 2 s (NaN: never within
    ``after_kidnap`` seconds)."""
    log = _kidnap_log(tmp_path, settings, world, seed, after_kidnap)
    config = LostFlagConfig()
    return kidnap_times(log, config.kidnap_time, config.hold_s)[1]


def test_the_default_filter_finds_the_car_in_a_corridor_like_another(tmp_path) -> None:
    # 2.2 s on the machine that measured it; driven 12 s after the kidnap, enough for 10 s and
    # the 2 s the error must stay under 0.5 m
    assert _recovered_after(tmp_path, None, after_kidnap=12.0) <= 10.0


def test_without_the_log_likelihood_and_the_injection_the_search_keeps_the_other_end(
    tmp_path,
) -> None:
    old = {"lost": {"search_inject_share": 0.0, "search_adopt_loglik": math.inf}}
    assert math.isnan(_recovered_after(tmp_path, old))  # 11 m off to the end


SETTLED_1S = {"search_adopt_s": 1.0}  # the search compared after 1 s settled, not half a second
PLAIN_SEARCH = {"search_place_draws": 0.0, "search_scan_exponent": 1.0, **SETTLED_1S}


def test_a_plain_search_settled_on_a_look_alike_starts_again_and_finds_the_car(tmp_path) -> None:
    plain = {"lost": PLAIN_SEARCH}
    assert _recovered_after(tmp_path, plain, "cluttered", 5) <= 15.0  # 12.45 s where measured


def test_without_the_restart_a_plain_search_tracks_the_look_alike_on(tmp_path) -> None:
    # (keeping its places, the search finds this car without the restart: 6.6 s where measured,
    # settled 1 s; not driven here, to keep the suite short)
    never = {"search_restart_misfit": math.inf}
    assert math.isnan(_recovered_after(tmp_path, {"lost": {**never, **PLAIN_SEARCH}}, "cluttered", 5))


def test_a_search_that_keeps_its_places_finds_the_car_sooner_than_a_plain_one(tmp_path) -> None:
    # found 2.2 s after the kidnap where measured; resampling plainly, 14.1 s after (the four
    # searches before settled on places that fit worse)
    assert _recovered_after(tmp_path, None, "cluttered", 2) <= 5.0
    assert not _recovered_after(tmp_path, {"lost": PLAIN_SEARCH}, "cluttered", 2) <= 10.0  # NaN too


def test_a_search_compared_after_half_a_second_finds_a_car_it_would_hop_away_from(tmp_path) -> None:
    assert _recovered_after(tmp_path, None, "clean", 7, after_kidnap=12.0) <= 10.0  # 1.97 s measured
    # settled for 1 s (the earlier default), the search hops away first, every time
    assert math.isnan(_recovered_after(tmp_path, {"lost": {"search_adopt_s": 1.0}}, "clean", 7))


def _flag_down_after(log: ErrorLog, kidnap_at: float = 10.0) -> float:
    """Seconds from the kidnap until the flag first comes down with the error under 0.5 m (NaN:
    never within the log)."""
    t, err, lost = log.time, log.position_error, np.asarray(log.lost, dtype=np.bool_)
    down = np.flatnonzero((t > kidnap_at + 1e-9) & ~lost & (err < 0.5))
    return float(t[down[0]] - kidnap_at) if down.size else math.nan


def test_searches_that_settle_on_the_filters_place_take_the_flag_down_over_a_found_car(tmp_path) -> None:
    # cluttered kidnap 8: found at once, where the old map explains the scans less well than
    # where the car was; two searches in a row settle there and the flag comes down (1.2 s
    # after the kidnap where measured), and the car is held
    log = _kidnap_log(tmp_path, None, "cluttered", 8, after_kidnap=10.0)
    assert _flag_down_after(log) <= 5.0
    held = (log.time > 10.5) & (log.time < 20.0)
    assert float(np.max(log.position_error[held])) < 0.5
    # without the confirmations the flag waits for the fit to come back (12.8 s where measured)
    # or, as here, a later search takes a place far away first
    never = {"lost": {"search_confirmations": 0}}
    unconfirmed = _kidnap_log(tmp_path, never, "cluttered", 8, after_kidnap=8.5)
    assert not _flag_down_after(unconfirmed) <= 8.0  # NaN (never) passes too


def test_searches_that_confirm_the_place_take_the_flag_down_where_the_old_map_fits_half(tmp_path) -> None:
    # cluttered kidnap 13: the car is carried to a place whose scans the old map explains only
    # about half (0.47-0.60 of the beams, under clear_above's 0.65); the filter finds it within
    # a second, two searches in a row settle there, and the flag comes down (5.0 s after the
    # kidnap where measured; asking the fit to pass clear_above, never within 20 s)
    log = _kidnap_log(tmp_path, None, "cluttered", 13, after_kidnap=7.5)
    assert _flag_down_after(log) <= 7.0
    found = log.time > 11.0
    assert float(np.max(log.position_error[found])) < 1.0


def test_a_confirmed_place_is_judged_by_its_own_fit(tmp_path) -> None:
    # cluttered kidnap 13, the filter's second draw: two searches confirm the car 1.4 s after
    # the kidnap, where the old map explains 0.44-0.55 of the beams; judged by the bars of the
    # place it left, the averaged fit's dips under 0.5 raise the flag at 16.0 s over a car
    # 0.14 m away, and it stays up to the end of the drive. Judged by its own fit (0.46), two
    # short dips under it, 19.0-19.75 s and 23.5-25.0 s, added up to the 1.5 s that raise the
    # flag (25.1 s) while the time under the bar was kept between them; counted in one stretch,
    # they raise nothing
    log = _kidnap_log(tmp_path, None, "cluttered", 13, after_kidnap=17.0, draw=1000)
    found = log.time > 12.0
    assert float(np.max(log.position_error[found])) < 0.5
    assert not np.any(np.asarray(log.lost, dtype=np.bool_)[found])


def test_the_flag_stays_up_over_a_kidnapped_car_until_a_place_fits(tmp_path) -> None:
    # cluttered kidnap 14: the car usually explains 0.71 of the beams; at the kidnap the fit at
    # the estimate falls to 0.24. Had its average carried on from before the jump (0.96), it would
    # have been back over the bar the found car must reach (0.61) 0.27 s after the jump, and the
    # flag would have come down over an estimate 38 m off; restarted at the jump, it speaks only
    # of the place the car was carried to, and the flag stays up while no place fits
    log = _kidnap_log(tmp_path, None, "cluttered", 14, after_kidnap=4.0)
    after = (log.time > 10.1) & (log.time < 14.0)
    far = after & (log.position_error > 5.0)
    assert far.sum() > 100  # the search has not found the car yet
    assert np.asarray(log.lost, dtype=np.bool_)[far].all()
