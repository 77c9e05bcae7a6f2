"""The global-start figures of the peers benchmark: the first update's cloud, its timing, the
bag replays with and without the sort (same trajectory), the flag check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.bench import global_start, peer_rangelibc, peers, shared_dir, stata_map
from racecar_sim.maps import bundled, load_map
from tests.skips import shared_missing


def test_the_global_cloud_is_the_replay_filters_start(default_map) -> None:
    cloud = global_start.global_cloud(default_map, seed=0)
    assert cloud.shape == (min(300_000, math.ceil(300.0 * default_map.free_area)), 3)
    assert default_map.is_free(cloud[:, :2]).all()
    assert np.ptp(cloud[:, 2]) > 6.0  # every heading


def test_the_first_update_is_timed_sorted_unsorted_and_gives_the_same_particles(
    default_map, capsys
) -> None:
    res = global_start.first_update(default_map, n_beams=10, rounds=2)
    text = capsys.readouterr().out
    assert res["n"] == global_start.global_cloud(default_map, 0).shape[0]
    assert res["sorted"] > 0 and res["unsorted"] > 0
    assert "same particles: True" in text
    if peer_rangelibc.available():
        assert res["glt"] > 0 and "the GLT" in text


@pytest.mark.skipif(
    not stata_map().is_file() or not list((shared_dir() / "bags").glob("*bag1*.bag")),
    reason=shared_missing(stata_map()) if not stata_map().is_file()
    else shared_missing(shared_dir() / "bags" / "localization_bag1_2022-03-29-19-23-29.bag"),
)
def test_a_bag_replays_to_the_same_trajectory_with_and_without_the_sort(capsys) -> None:
    bag = sorted((shared_dir() / "bags").glob("*bag1*.bag"))[0]
    res = global_start.bag_replays(load_map(stata_map()), [bag], rounds=1)
    assert res[bag.name]["same"] == 1.0
    assert res[bag.name]["sorted"] > 0 and res[bag.name]["unsorted"] > 0
    assert "same trajectory: True" in capsys.readouterr().out


def test_negative_global_rounds_exit_2(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        peers.main(["--only", "spread", "--map", str(bundled("basement_loop")),
                    "--global-rounds", "-1"])  # fmt: skip
    assert exc.value.code == 2
    assert "--global-rounds must be at least 0" in capsys.readouterr().err
