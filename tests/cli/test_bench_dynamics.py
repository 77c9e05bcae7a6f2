"""``racecar-sim bench dynamics`` without the peer: our skidpad and speed parts run and say so."""

from __future__ import annotations

from mcl.bench import dynamics
from racecar_sim.config import CarParams
from racecar_sim.maps import bundled


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
        assert out[kind]["cost"] > 0


def test_bad_flags_are_one_line_errors(capsys) -> None:
    import pytest

    with pytest.raises(SystemExit) as exc:
        dynamics.main(["--f1tenth-python", "/nonexistent/python"])
    assert exc.value.code == 2
    assert "both --f1tenth-python and --f1tenth-path" in capsys.readouterr().err
