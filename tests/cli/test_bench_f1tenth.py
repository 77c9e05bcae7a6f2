"""The f1tenth_gym part of the peers benchmark: runs ours without the peer, rejects bad flags.

(f1tenth_gym itself lives in its own venv and is not installed for the tests; its subprocess
script is exercised by running the benchmark, see the README.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mcl.bench import peer_f1tenth, peers
from racecar_sim.maps import bundled, resolve_map


def test_without_the_peer_it_measures_our_single_and_vector_env(capsys) -> None:
    grid = resolve_map("basement_loop")
    out = peer_f1tenth.compare(
        grid, bundled("basement_loop"), None, None, steps=60, runs=1, num_envs=2, vector_steps=5
    )
    text = capsys.readouterr().out
    assert "not measured" in text and peer_f1tenth.WORKLOAD in text
    assert set(out) == {"ours", "vector"}
    assert out["ours"]["wall"] > 0 and out["vector"]["wall"] > 0
    assert math.isnan(out["ours"]["x_wall"])  # no ratio without the peer


def test_start_pose_faces_a_straight_free_stretch() -> None:
    grid = resolve_map("basement_loop")
    pose = peer_f1tenth.start_pose(grid, length=8.0)
    assert grid.distance_at(pose[None, :2])[0] >= 1.0
    from racecar_sim.raycast import RayCaster

    ahead = RayCaster(grid, 30.0).cast(pose, np.array([-0.15, 0.0, 0.15]))
    assert ahead.min() >= 8.0
    with pytest.raises(ValueError, match="straight stretch"):
        peer_f1tenth.start_pose(grid, length=500.0)


def test_bad_peer_flags_are_one_line_errors(capsys) -> None:
    yaml = str(bundled("basement_loop"))
    code = peers.main(["--only", "f1tenth", "--map", yaml, "--f1tenth-python", "/nonexistent"])
    assert code == 2
    assert "both --f1tenth-python and --f1tenth-path" in capsys.readouterr().err
    code = peers.main(
        ["--only", "f1tenth", "--map", yaml, "--f1tenth-python", "/nonexistent/python",
         "--f1tenth-path", "/nonexistent"]
    )  # fmt: skip
    assert code == 2
    assert "--f1tenth-python /nonexistent/python does not exist" in capsys.readouterr().err
