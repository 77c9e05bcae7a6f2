"""A user's mistake on ``racecar-sim``: one line on stderr naming the flag, exit code 2, no traceback,
no output folder, and no run started. Commands run in-process through ``mcl.cli.main.main``."""

from __future__ import annotations

import json

import pytest

import mcl.cli.drive
import mcl.cli.experiment
import mcl.cli.recovery_ablation
from mcl.cli.main import main
from mcl.experiments.noise_sweep import ExperimentConfig
from mcl.experiments.runner import record_settings
from racecar_sim.file_guard import MARKER, claim_folder


@pytest.fixture
def no_runs(monkeypatch):
    """Make any run that starts fail the test: mistakes must be found before the first run."""

    def started(*args, **kwargs):
        raise AssertionError("a run started although the command line had a mistake")

    monkeypatch.setattr(mcl.cli.drive, "run_one", started)
    monkeypatch.setattr(mcl.cli.experiment, "run_experiment", started)
    monkeypatch.setattr(mcl.cli.experiment, "run_recovery_experiment", started)
    monkeypatch.setattr(mcl.cli.recovery_ablation, "run_recovery_experiment", started)


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    """``racecar-sim ARGV`` in-process: (exit code, stdout, stderr)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(code: int, err: str, flag: str, fragment: str) -> str:
    lines = err.splitlines()
    assert code == 2
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("racecar-sim") and ": error: " in line
    assert flag in line and fragment in line, line
    assert "Traceback" not in err
    return line


# (subcommand arguments, the flag the message must name, a fragment of the problem).
# {missing} is a map YAML path that does not exist, {file} an existing file that is not a folder.
DRIVE_MISTAKES = [
    (["--map", "basment_loop"], "--map", "did you mean 'basement_loop'"),
    (["--map", "{missing}"], "--map", "not found"),
    (["--duration", "-5"], "--duration", "(0, 86400]"),
    (["--duration", "0"], "--duration", "(0, 86400]"),
    (["--duration", "soon"], "--duration", "'soon'"),
    (["--duration", "1e9"], "--duration", "seconds in (0, 86400]"),
    (["--live-speed", "1e-9"], "--live-speed", "0 (unpaced) or in [0.01, 1000]"),
    (["--live-speed", "-1"], "--live-speed", "0 (unpaced) or in [0.01, 1000]"),
    (["--particles", "0"], "--particles", ">= 1"),
    (["--particles", "1.5"], "--particles", "whole number"),
    (["--seed", "-1"], "--seed", ">= 0"),
    (["--video-fps", "-1"], "--video-fps", ">= 0"),
    (["--driver", "bus"], "--driver", "invalid choice"),
    (["--env", "lidar_rate=abc"], "--env lidar_rate", "must be a number, got 'abc'"),
    (["--env", "lidar_rat=20"], "--env lidar_rat", "did you mean 'lidar_rate'"),
    (["--env", "n_beams=2.5"], "--env n_beams", "whole number"),
    (["--env", "lidar_rate=-1"], "--env lidar_rate", "rate"),
    (["--env", "terminate_on_collision=maybe"], "--env terminate_on_collision", "true or false"),
    (["--env", "odom_additive=3"], "--env odom_additive", "3 numbers"),
    (["--env", "car=3"], "--env car", "mapping"),
    (["--env", "map=office"], "--env map", "--map"),
    (["--env", "car_model=dynamic"], "--env car_model", "must be one of"),
    (["--filter-map", "{missing}"], "--filter-map", "not found"),
    (["--map", "corridor", "--filter-map", "office"], "--filter-map", "at least 50% must be"),
    (["--noise-profile", "mit_racecer"], "--env noise_profile", "mit_racecar"),
    (["--env", "obstacles={boxs: 3}"], "--env obstacles", "unknown obstacles setting"),
    (["--env", "lidar_rate"], "--env", "NAME=VALUE"),
    (["--env", "p_short=0.6", "--env", "p_max=0.6"], "--env", "p_short + p_max"),
    (["--out", "{file}"], "--out", "not a folder"),
    (["--bogus"], "unrecognized arguments", "--bogus"),
]
EXPERIMENT_MISTAKES = [
    (["--map", "{missing}"], "--map", "not found"),
    (["--map", "stata"], "--map", "no bundled map named 'stata'"),
    (["--map", "corridor", "--filter-map", "office"], "--filter-map", "at least 50% must be"),
    (["--seeds", "0"], "--seeds", ">= 1"),
    (["--seeds", "three"], "--seeds", "whole number"),
    (["--workers", "0"], "--workers", ">= 1"),
    (["--duration", "-1"], "--duration", "(0, 86400]"),
    (["--duration", "1e9"], "--duration", "(0, 86400]"),
    (["--particles", "0"], "--particles", ">= 1"),
    (["--env", "lidar_rate=abc"], "--env lidar_rate", "must be a number, got 'abc'"),
    (["--env", "beams=100"], "--env beams", "unknown setting"),
    (["--uniform", "", "--gaussian", ""], "--uniform/--gaussian", "no run"),
    (["--uniform", "0.1,abc"], "--uniform", "'abc'"),
    (["--gaussian", "0.1,-1"], "--gaussian", "> 0"),
    (["--scenario", "kidnap", "--duration", "3"], "--duration", "before the kidnap"),
    (["--scenario", "global", "--time-limit", "0"], "--time-limit", "> 0"),
    (["--kidnap-time", "-1"], "--kidnap-time", ">= 0"),
    (["--scenario", "lost"], "--scenario", "invalid choice"),
    (["--driver", "bus"], "--driver", "invalid choice"),
    (["--out", "{file}"], "--out", "not a folder"),
]
ABLATION_MISTAKES = [
    (["--map", "{missing}"], "--map", "not found"),
    (["--seeds", "0"], "--seeds", ">= 1"),
    (["--workers", "-1"], "--workers", ">= 1"),
    (["--variants", "full", "nothing"], "--variants", "invalid choice"),
    (["--scenario", "tracking"], "--scenario", "invalid choice"),
]


def _cases() -> list:
    cases = []
    for sub, mistakes in (
        ("drive", DRIVE_MISTAKES),
        ("experiment", EXPERIMENT_MISTAKES),
        ("ablation", ABLATION_MISTAKES),
    ):
        for args, flag, fragment in mistakes:
            cases.append(pytest.param(sub, args, flag, fragment, id=f"{sub} {' '.join(args)}"))
    return cases


@pytest.mark.parametrize(("sub", "args", "flag", "fragment"), _cases())
def test_a_mistake_is_one_line_naming_the_flag(
    sub, args, flag, fragment, tmp_path, capsys, no_runs
) -> None:
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("not a folder")
    names = {"{missing}": str(tmp_path / "maps" / "missing.yaml"), "{file}": str(a_file)}
    args = [names.get(a, a) for a in args]
    out = tmp_path / "out" / "run"
    if "--out" not in args:
        args = [*args, "--out", str(out)]
    code, stdout, err = run([sub, *args], capsys)
    assert_one_line_error(code, err, flag, fragment)
    assert stdout == ""
    assert not (tmp_path / "out").exists()  # not even the parent was created


def test_env_lidar_rate_abc_says_exactly_what_is_wrong(tmp_path, capsys, no_runs) -> None:
    out = tmp_path / "x"
    code, _, err = run(["experiment", "--env", "lidar_rate=abc", "--out", str(out)], capsys)
    line = assert_one_line_error(code, err, "--env", "abc")
    assert line.endswith("--env lidar_rate: must be a number, got 'abc'")


def test_resume_into_a_folder_made_with_other_settings_stops_before_running(
    tmp_path, capsys, no_runs
) -> None:
    out = tmp_path / "sweep"
    claim_folder(out)  # as an earlier experiment left it
    recorded = out / "config.json"
    record_settings(ExperimentConfig(seeds=1), recorded, resume=False)
    before = recorded.read_text()
    code, _, err = run(["experiment", "--resume", "--seeds", "2", "--out", str(out)], capsys)
    assert_one_line_error(code, err, "--resume", "seeds")
    assert str(out) in err
    assert recorded.read_text() == before  # the folder's record is untouched
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "config.json"]
    settings = json.loads(before)
    assert settings["seeds"] == 1


def test_unknown_subcommand_and_benchmark(capsys) -> None:
    code, _, err = run(["driev"], capsys)
    assert_one_line_error(code, err, "subcommand 'driev'", "did you mean 'drive'")
    code, _, err = run(["bench", "raycats"], capsys)
    assert_one_line_error(code, err, "benchmark 'raycats'", "did you mean 'raycast'")


def test_make_maps_refuses_a_file_as_output_folder(tmp_path, capsys) -> None:
    a_file = tmp_path / "maps"
    a_file.write_text("")
    code, _, err = run(["make-maps", "--out", str(a_file)], capsys)
    assert_one_line_error(code, err, "--out", "not a folder")


def test_an_output_folder_that_cannot_be_made_is_a_mistake(tmp_path, capsys, no_runs) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    # check_out sees the file in the way; a folder below a file cannot be created either
    code, _, err = run(["drive", "--out", str(blocker / "sub" / "out")], capsys)
    assert_one_line_error(code, err, "--out", "not a folder")
