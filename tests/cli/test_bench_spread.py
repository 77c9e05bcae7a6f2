"""The spread-cloud part of the peers benchmark: its clouds, its numbers, its flag checks."""

from __future__ import annotations

import numpy as np

from mcl.bench import peer_rangelibc, peer_spread, peers
from racecar_sim.maps import bundled


def test_clouds_are_spread_over_free_space_and_tracking_around_the_truth(default_map) -> None:
    truth = default_map.sample_free_poses(np.random.default_rng(0), 1, clearance=1.0)[0]
    work = peer_spread.clouds(default_map, (500, 900), truth, np.random.default_rng(1))
    assert list(work) == ["spread 500", "spread 900", "tracking 500"]
    spread = work["spread 900"]
    assert default_map.is_free(spread[:, :2]).all()
    assert np.ptp(spread[:, 0]) > 2 * np.ptp(work["tracking 500"][:, 0])
    assert np.abs(work["tracking 500"][:, :2] - truth[:2]).max() < 3.0


def test_it_times_every_variant_on_every_cloud(default_map, capsys) -> None:
    res = peer_spread.compare_spread(default_map, sizes=(300,), n_beams=10, rounds=2, threads=(1,))
    text = capsys.readouterr().out
    assert set(res) == {"spread 300", "tracking 300"}
    assert "spread 300 particles (sorted)" in text
    assert "tracking 300 particles (narrow: not sorted)" in text
    for cloud in res.values():
        assert cloud["ours/1_ms"] > 0 and cloud["unsorted/1_ms"] > 0
        assert cloud["ours/1_x_unsorted"] > 0
        if peer_rangelibc.available():
            assert cloud["glt_ms"] > 0 and cloud["ours/1_x_glt"] > 0


def test_bad_spread_flags_exit_2(capsys) -> None:
    yaml = str(bundled("basement_loop"))
    for flag in (["--spread-rounds", "0"], ["--spread-particles", "100", "0"]):
        try:
            peers.main(["--only", "spread", "--map", yaml, *flag])
        except SystemExit as exc:
            assert exc.code == 2
        else:
            raise AssertionError(f"{flag} was accepted")
        assert (
            "--spread-particles and --spread-rounds must be at least 1" in capsys.readouterr().err
        )


def test_the_cpu_clock_times_every_variant_and_a_bad_clock_is_refused(default_map, capsys) -> None:
    res = peer_spread.compare_spread(
        default_map, sizes=(200,), n_beams=10, rounds=1, threads=(1,), clock="cpu"
    )
    assert "median cpu ms per update" in capsys.readouterr().out
    assert all(cloud["ours/1_ms"] > 0 for cloud in res.values())
    try:
        peer_spread.compare_spread(default_map, sizes=(200,), clock="sundial")
    except ValueError as exc:
        assert "clock must be one of ('wall', 'cpu')" in str(exc)
    else:
        raise AssertionError("clock='sundial' was accepted")
