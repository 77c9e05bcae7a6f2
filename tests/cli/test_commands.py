"""The ``racecar-sim`` command: help with defaults and examples that parse, the shared checks, the
compile notice, output folders on failure, and real runs of the installed console command."""

from __future__ import annotations

import argparse
import importlib
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import mcl.cli.drive
from mcl.cli import drive, experiment, fast_laps, recovery_ablation, update_map
from mcl.cli.bench import BENCHMARKS
from mcl.cli.common import Parser, check_env, output_folder
from mcl.cli.main import SUBCOMMANDS, main
from mcl.wrappers.error_log import read_error_log

REPO = Path(__file__).resolve().parents[2]
PARSERS = {
    "drive": drive.build_parser,
    "experiment": experiment.build_parser,
    "ablation": recovery_ablation.build_parser,
    "fast-laps": fast_laps.build_parser,
    "update-map": update_map.build_parser,
}


def _option_help(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Option string -> its help text as printed by --help (joined lines)."""
    text = parser.format_help().split("options:", 1)[1].split("examples", 1)[0]
    blocks = re.split(r"\n  (?=-)", "\n" + text)
    out = {}
    for block in blocks:
        block = " ".join(block.split())
        if block.startswith("-"):
            out[block.split()[0].rstrip(",")] = block
    return out


def _shown(default: object) -> str:
    if isinstance(default, tuple):
        return ",".join(f"{v:g}" for v in default)
    if isinstance(default, list):
        return ",".join(map(str, default))
    return str(default)


@pytest.mark.parametrize("sub", sorted(PARSERS))
def test_help_shows_every_default(sub: str) -> None:
    parser = PARSERS[sub]()
    helps = _option_help(parser)
    for action in parser._actions:
        if not action.option_strings or action.dest == "help":
            continue
        text = helps[action.option_strings[0]]
        assert action.help, f"{sub} {action.option_strings[0]} has no help"
        if action.default not in (None, False, []):
            assert f"(default: {_shown(action.default)})" in text, text
        elif action.default is None:
            assert "default" in text, f"{sub} {action.option_strings[0]}: say what None means"


@pytest.mark.parametrize("sub", sorted(PARSERS))
def test_help_examples_parse(sub: str) -> None:
    parser = PARSERS[sub]()
    epilog = (parser.epilog or "").replace("\\\n", " ")
    examples = [
        line.strip() for line in epilog.splitlines() if line.strip().startswith("racecar-sim")
    ]
    assert examples, f"{sub} --help has no examples"
    for example in examples:
        words = shlex.split(re.split(r"\s{2,}", example)[0])
        assert words[:2] == ["racecar-sim", sub]
        parser.parse_args(words[2:])  # exits (fails the test) on a bad example


def test_top_level_help_lists_every_subcommand(capsys) -> None:
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in SUBCOMMANDS:
        assert f"  {name} " in out
    assert "examples:" in out


def test_subcommand_help_exits_0_with_examples(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["drive", "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "(default: basement_loop)" in out and "examples:" in out


def test_env_values_get_the_type_of_their_setting() -> None:
    parser = Parser("test", None)
    settings = dict(
        check_env(
            parser,
            [
                "lidar_rate=20",
                "max_range=1e1",  # YAML reads 1e1 as text; it is still a number
                "n_beams=181",
                "terminate_on_collision=false",
                "odom_additive=[0, 0, 0.01]",
                "car={wheelbase: 0.3}",
            ],
        )
    )
    assert settings["lidar_rate"] == 20 and settings["max_range"] == 10.0
    assert settings["n_beams"] == 181 and isinstance(settings["n_beams"], int)
    assert settings["terminate_on_collision"] is False
    assert settings["odom_additive"] == (0, 0, 0.01)
    assert settings["car"] == {"wheelbase": 0.3}


def test_output_folder_is_removed_when_nothing_was_written(tmp_path) -> None:
    parser = Parser("test", None)
    out = tmp_path / "a" / "b"
    with pytest.raises(RuntimeError), output_folder(parser, out):
        assert out.is_dir()
        raise RuntimeError("failed before writing")
    assert not (tmp_path / "a").exists()
    with pytest.raises(RuntimeError), output_folder(parser, out):
        (out / "log.csv").write_text("step\n")
        raise RuntimeError("failed half-way")
    assert (out / "log.csv").is_file()  # what was written is kept


def test_output_folder_keeps_a_folder_that_was_there(tmp_path) -> None:
    parser = Parser("test", None)
    with pytest.raises(RuntimeError), output_folder(parser, tmp_path):
        raise RuntimeError("boom")
    assert tmp_path.is_dir()


def test_a_drive_that_fails_half_way_keeps_its_log(tmp_path, monkeypatch, capsys) -> None:
    real = mcl.cli.drive.run_one

    class Stop(Exception):
        pass

    def stop_after_some_steps(spec, log_path, **kwargs):
        frames = []

        def on_frame(frame, info):
            frames.append(info)
            if len(frames) > 10:
                raise Stop("wheel fell off")

        return real(spec, log_path, on_frame=on_frame, frame_every=1)

    monkeypatch.setattr(mcl.cli.drive, "run_one", stop_after_some_steps)
    out = tmp_path / "half"
    with pytest.raises(Stop):
        drive.main(["--out", str(out), "--duration", "1", "--particles", "50", "--video-fps", "0"])
    log = read_error_log(out / "error_log.csv")
    assert len(log) == 10  # the rows written before the failure


# ---------------------------------------------------------------------- real processes
def _console_command() -> Path:
    path = Path(sys.executable).parent / "racecar-sim"
    if not path.is_file():
        pytest.skip(f"{path} not installed (pip install -e . makes it)")
    return path


def test_console_command_reports_a_mistake_in_one_line(tmp_path) -> None:
    out = tmp_path / "out"
    done = subprocess.run(
        [str(_console_command()), "drive", "--map", "basment_loop", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        line for line in done.stderr.splitlines() if line.startswith("racecar-sim drive: error:")
    ]
    assert len(done.stderr.splitlines()) == 1 and "--map" in done.stderr
    assert not out.exists()


def test_experiment_script_with_a_missing_map_starts_no_run(tmp_path) -> None:
    out = tmp_path / "runs"
    cmd = [sys.executable, str(REPO / "scripts" / "experiment.py"), "--map", "nope.yaml"]
    done = subprocess.run(
        [*cmd, "--out", str(out)], capture_output=True, text=True, cwd=tmp_path, timeout=120
    )
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "--map" in lines[0] and "not found" in lines[0], done.stderr
    assert done.stdout == ""
    assert not out.exists()


def test_every_benchmark_module_is_a_bench_subcommand() -> None:
    import mcl.bench

    folder = Path(mcl.bench.__file__).parent
    with_main = {
        p.stem for p in folder.glob("*.py") if "\ndef main(" in p.read_text(encoding="utf-8")
    }
    assert with_main == set(BENCHMARKS)


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_bench_help_names_the_command_and_shows_defaults(name: str, capsys) -> None:
    module = importlib.import_module(f"mcl.bench.{name}")
    with pytest.raises(SystemExit) as exit_:
        main(["bench", name, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: racecar-sim bench {name} ")
    assert "(default: " in out
    assert module.argparse is argparse  # the benchmark's own parser is back as it was


def test_bench_mistake_is_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "sim", "--steps", "many"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert err.splitlines() == [
        "racecar-sim bench sim: error: argument --steps: invalid int value: 'many'"
    ]


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_bench_script_mistake_is_one_line_naming_the_script(name: str) -> None:
    """``scripts/bench_NAME.py`` run directly: the same one-line error as the command, no traceback."""
    script = REPO / "scripts" / f"bench_{name}.py"
    done = subprocess.run(
        [sys.executable, str(script), "--no-such-flag"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"{script}: error: unrecognized arguments: --no-such-flag"
    ], done.stderr


def test_experiment_with_a_failing_run_keeps_the_others_and_exits_1(
    tmp_path, monkeypatch, capsys
) -> None:
    import mcl.experiments.runner as runner

    real = runner.run_one

    def flaky(spec, log_path, **kwargs):
        if spec.series == "gaussian":
            raise RuntimeError("wheel fell off")
        return real(spec, log_path, **kwargs)

    monkeypatch.setattr(runner, "run_one", flaky)
    out = tmp_path / "sweep"
    args = [
        "experiment", "--uniform", "0.01", "--gaussian", "0.5", "--no-matched", "--seeds", "1",
        "--duration", "0.5", "--particles", "50", "--env", "n_beams=61", "--workers", "1",
        "--no-plots", "--out", str(out),
    ]  # fmt: skip
    assert main(args) == 1
    captured = capsys.readouterr()
    assert "1 runs done, 0 skipped (complete logs), 1 failed" in captured.out
    assert "failed runs: gaussian_c0.5_seed0" in captured.err
    assert captured.err.count("wheel fell off") == 1  # reported once, as it happened
    assert len(read_error_log(out / "logs" / "uniform_c0.01_seed0.csv")) == 20


def test_ctrl_c_is_one_line_and_leaves_no_empty_folder(tmp_path, monkeypatch, capsys) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(mcl.cli.drive, "run_one", interrupted)
    out = tmp_path / "out"
    assert main(["drive", "--out", str(out), "--video-fps", "0"]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == "racecar-sim drive: interrupted"
    assert not out.exists()


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_subcommand_has_examples_and_one_line_errors(name: str, capsys) -> None:
    try:
        code = main([name, "--help"])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr().out
    assert code == 0
    assert f"racecar-sim {name}" in out and "example" in out.lower()
    try:
        code = main([name, "--no-such-flag"])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err.splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith(f"racecar-sim {name}: error: ")
    assert "--no-such-flag" in err[0]
