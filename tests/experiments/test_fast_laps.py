"""Tests of the fast-lap experiment (mcl.experiments.fast_laps) and its command."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mcl.cli.fast_laps
from mcl.agents.track import track_for_map
from mcl.cli.main import main
from mcl.experiments.fast_laps import (
    ALPHA_MOTION,
    LAB_MOTION,
    FastLapConfig,
    fast_lap_specs,
    markdown_table,
    run_fast_laps,
)
from mcl.experiments.runs import RunSpec, run_one

pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
)


def test_specs_start_on_the_loop_and_pair_the_series_per_seed() -> None:
    cfg = FastLapConfig(seeds=3, duration=5.0)
    specs = fast_lap_specs(cfg)
    assert [(s.seed, s.series) for s in specs] == [
        (k, m) for k in range(3) for m in ("lab", "alpha")
    ]
    track = track_for_map("basement_loop")
    starts = [dict(s.scenario_settings)["start"] for s in specs[::2]]
    for x, y, _ in starts:
        _, lateral = track.project(np.array([x, y]))
        assert abs(lateral) < 1e-6
    s_values = [track.project(np.array(p[:2]))[0] for p in starts]
    assert s_values[1] - s_values[0] == pytest.approx(track.length / 3, rel=1e-3)
    assert specs[0].motion == LAB_MOTION and specs[1].motion == ALPHA_MOTION
    assert dict(specs[0].driver_settings) == {"speed": 6.0}


def test_racing_driver_holds_the_speed_in_corners(tmp_path) -> None:
    spec = RunSpec(map="basement_loop", driver="racing", seed=0, duration=8.0, n_particles=200,
                   driver_settings=(("speed", 5.0),),
                   scenario_settings=(("start", (9.0, 2.5, 0.0)),))  # fmt: skip
    result = run_one(spec, tmp_path / "log.csv")
    assert result.status == "ok" and result.n_collisions == 0
    assert result.stats.mean_error < 0.2


def test_a_small_experiment_writes_its_table(tmp_path) -> None:
    cfg = FastLapConfig(seeds=1, duration=3.0, n_particles=200)
    rows, results = run_fast_laps(cfg, tmp_path, workers=1)
    assert [r.series for r in rows] == ["lab", "alpha"]
    assert all(r.status == "ok" for r in results)
    for row in rows:
        assert row.runs == 1 and row.failed == 0
        assert 0 <= row.median <= row.p95 and math.isfinite(row.mean)
    text = (tmp_path / "summary.md").read_text()
    assert text.strip() == markdown_table(rows, cfg.diverged_m)
    assert "| lab | 1 |" in text


def test_bad_settings_are_one_line_errors(capsys, monkeypatch, tmp_path) -> None:
    def started(*args, **kwargs):
        raise AssertionError("a run started although the command line had a mistake")

    monkeypatch.setattr(mcl.cli.fast_laps, "compile_notice", started)
    for argv, fragment in (
        (["--map", "corridor"], "no loop known"),
        (["--speed", "0"], "--speed"),
        (["--env", "odom_lead=-1"], "odom_lead"),
    ):
        with pytest.raises(SystemExit) as exc:
            main(["fast-laps", "--out", str(tmp_path / "x"), *argv])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and fragment in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()
