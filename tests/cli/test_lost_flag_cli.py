"""racecar-sim lost-flag: mistakes are one line naming the flag (exit 2), before any drive runs."""

from __future__ import annotations

import pytest

from mcl.cli.main import main
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
    ],
)
def test_mistakes_are_one_line_naming_the_flag(args, flag, words, tmp_path, capsys) -> None:
    world = SHARED_MAPS / "basement_fixed_aligned.yaml"
    if flag == "--filter" and not world.is_file():  # the real-data folder is checked first
        pytest.skip(shared_missing(world))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_:
        main(["lost-flag", *args, "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("racecar-sim lost-flag: error: ")
    assert flag in err[0] and words in err[0]
    assert not out.exists()
