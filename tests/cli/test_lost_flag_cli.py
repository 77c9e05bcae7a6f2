"""racecar-sim lost-flag: mistakes are one line naming the flag (exit 2), before any drive runs."""

from __future__ import annotations

import numpy as np
import pytest

from mcl.cli.main import main
from mcl.wrappers.error_log import read_error_log
from tests.conftest import SHARED_MAPS
from tests.skips import shared_missing


@pytest.mark.parametrize(
    ("args", "flag", "words"),
    [
        (["--filter", "nonsense"], "--filter", "KEY=VALUE"),
        (["--filter", "sensor.sigma_hit=-1"], "--filter", "sigma_hit"),
        (["--filter", "lost.raise_below=0.9"], "--filter", "clear_above"),
        (["--worlds", "nowhere"], "--worlds", "nowhere"),
        (["--shared", "no/such/folder"], "--shared", "not found"),
        (
            ["--seeds", "0", "--kidnap-seeds", "0", "--worlds", "basement_loop"],
            "--seeds",
            "no drives",
        ),
        (["--filter-map", "no/such/map.yaml"], "--filter-map", "no/such/map.yaml"),
        # another place: it does not cover Stata
        (["--filter-map", "basement_loop"], "--filter-map", "free on"),
        (
            ["--filter-map", str(SHARED_MAPS / "stata_basement.yaml"), "--worlds", "basement_loop"],
            "--filter-map",
            "honest worlds",
        ),
    ],
)
def test_mistakes_are_one_line_naming_the_flag(args, flag, words, tmp_path, capsys) -> None:
    world = SHARED_MAPS / "basement_fixed_aligned.yaml"
    if flag in ("--filter", "--filter-map") and not world.is_file():  # checked first
        pytest.skip(shared_missing(world))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_:
        main(["lost-flag", *args, "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("racecar-sim lost-flag: error: ")
    assert err[0].split("error: ")[1].startswith(flag) and words in err[0]
    assert not out.exists()



def test_the_honest_world_filter_holds_the_map_given(tmp_path, capsys) -> None:
    """The world's own map as --filter-map (a map with nothing out of date): the kidnap drive's
    filter holds it (the run's settings name it) and the run ends with its table."""
    world = SHARED_MAPS / "basement_fixed_aligned.yaml"
    if not world.is_file():
        pytest.skip(shared_missing(world))
    out = tmp_path / "out"
    code = main(["lost-flag", "--worlds", "clean", "--seeds", "0", "--kidnap-seeds", "1",
                 "--kidnap-time", "1", "--after-kidnap", "1", "--workers", "1",
                 "--filter-map", str(world), "--out", str(out)])  # fmt: skip
    assert code == 0
    table = capsys.readouterr().out
    assert "| clean_kidnap | 1 |" in table
    saved = (out / "config.json").read_text(encoding="utf-8")
    assert str(world) in saved and "stata_basement.yaml" not in saved


def test_a_negative_filter_seed_offset_is_one_line_naming_the_flag(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_:
        main(["lost-flag", "--filter-seed-offset", "-1", "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--filter-seed-offset" in err[0] and "-1" in err[0]
    assert not out.exists()


def test_filter_seed_offset_redraws_the_filter_on_the_same_kidnap(tmp_path, capsys) -> None:
    """The same kidnap drive (the bundled loop) with the filter seeded by its seed and by its
    seed + 1000: the car's path is the same step for step, the estimates are not, and the run
    is named by its filter's seed."""
    args = ["lost-flag", "--worlds", "basement_loop", "--seeds", "0", "--kidnap-seeds", "1",
            "--kidnap-time", "1", "--after-kidnap", "1", "--workers", "1"]  # fmt: skip
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--filter-seed-offset", "1000", "--out", str(tmp_path / "b")]) == 0
    table = capsys.readouterr().out
    assert "| basement_loop_kidnap_seed0_filter1000 |" in table
    a = read_error_log(tmp_path / "a" / "logs" / "basement_loop_kidnap_seed0.csv")
    b = read_error_log(tmp_path / "b" / "logs" / "basement_loop_kidnap_seed0_filter1000.csv")
    for name in ("x_true", "y_true", "theta_true"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.x_est, b.x_est)
    assert '"filter_seed_offset": 1000' in (tmp_path / "b" / "config.json").read_text("utf-8")
