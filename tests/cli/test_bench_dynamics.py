"""``racecar-sim bench dynamics`` without the peer: our skidpad and speed parts run and say so."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from mcl.bench import dynamics
from racecar_sim.maps import bundled
from racecar_sim.settings.config import CarParams


def test_skidpad_without_the_peer_shows_ours(capsys) -> None:
    rows = dynamics.skidpad_table(CarParams.f1tenth())
    text = capsys.readouterr().out
    assert "departs by over 5%" in text
    assert len(rows) == len(dynamics.STEERS) * len(dynamics.SPEEDS)
    assert all("theirs" not in row for row in rows.values())
    # ours at 7 m/s is held near the friction limit
    assert rows[(0.35, 7)]["ours"].lateral_accel < 1.01 * 1.0489 * 9.81


def test_speed_part_measures_both_models(capsys) -> None:
    out = dynamics.speed_cost(bundled("basement_loop"), steps=30, vector_steps=3, runs=1,
                              num_envs=2)  # fmt: skip
    text = capsys.readouterr().out
    assert "both models in turn" in text
    for kind in ("single", "vector"):
        assert out[kind]["kinematic"] > 0 and out[kind]["single_track"] > 0
        assert out[kind]["cost"] > 0 and out[kind]["cost_cpu"] > 0
    # one row per env, each with the wall-clock and the CPU-time ratio
    rows = [line for line in text.splitlines() if line.startswith(("| one env", "| vector env"))]
    assert len(rows) == 2 and all(row.count("|") == 6 for row in rows)


def test_bad_flags_are_one_line_errors(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        dynamics.main(["--f1tenth-python", "/nonexistent/python"])
    assert exc.value.code == 2
    assert "both --f1tenth-python and --f1tenth-path" in capsys.readouterr().err


PEERS = Path(__file__).resolve().parents[3] / "peers"  # ../peers beside the checkout
PEER_PYTHON = Path(os.environ.get("F1TENTH_PYTHON", PEERS / "f1tenth-venv" / "bin" / "python"))
PEER_PATH = Path(os.environ.get("F1TENTH_PATH", PEERS / "f1tenth_gym"))


@pytest.mark.skipif(not (PEER_PYTHON.exists() and PEER_PATH.is_dir()),
                    reason="f1tenth_gym and its venv are not in ../peers (or $F1TENTH_PYTHON, $F1TENTH_PATH)")  # fmt: skip
def test_skidpad_agrees_with_f1tenth_gym_where_its_tires_are_linear(capsys) -> None:
    from mcl.bench.peer_dynamics import PeerDynamics

    peer = PeerDynamics(str(PEER_PYTHON), str(PEER_PATH))
    try:
        car = CarParams.f1tenth()
        assert peer.params["mu"] == car.friction and peer.params["C_Sf"] == car.cornering_front
        rows = dynamics.skidpad_table(car, peer)
    finally:
        peer.close()
    limit = car.friction * 9.81
    linear = 0
    for row in rows.values():
        theirs, ours = row["theirs"], row["ours"]
        if theirs["lateral_accel"] < 0.5 * limit:
            linear += 1
            assert ours.radius == pytest.approx(theirs["radius"], rel=0.10)
        else:  # theirs corners on, ours is held by the friction
            assert ours.lateral_accel <= 1.01 * limit < 2 * theirs["lateral_accel"]
    assert linear >= 4
    assert "radii agree" in capsys.readouterr().out
