"""A flag's value may start with a minus sign: ``--init -20.9,-0.3,1.26`` (the replay help's own
example; every pose on the Stata map has a negative x) reads as ``--init=-20.9,-0.3,1.26``, for every
flag of every subcommand and benchmark."""

from __future__ import annotations

import argparse
import importlib

import pytest

import mcl.cli.common as common
from mcl.cli.bench import BENCHMARKS
from mcl.cli.main import SUBCOMMANDS, main

POSE = "-20.9,-0.3,1.26"


class _Captured(Exception):
    pass


def _parser_of(module_name: str, monkeypatch, parser_class: type) -> argparse.ArgumentParser:
    """The parser a subcommand's ``main`` builds, caught when it starts parsing."""
    seen: list[argparse.ArgumentParser] = []

    def capture(self, *args, **kwargs):
        seen.append(self)
        raise _Captured

    with monkeypatch.context() as m:
        m.setattr(parser_class, "parse_args", capture)
        with pytest.raises(_Captured):
            importlib.import_module(module_name).main([])
    return seen[0]


def _value_flags(parser: argparse.ArgumentParser) -> list[str]:
    return [
        a.option_strings[-1]
        for a in parser._actions
        if a.option_strings and a.nargs is None and not isinstance(a, argparse._HelpAction)
    ]


@pytest.mark.parametrize("name", sorted(set(SUBCOMMANDS) - {"bench"}))
def test_every_flag_of_every_subcommand_takes_a_negative_value(name, monkeypatch, capsys) -> None:
    parser = _parser_of(SUBCOMMANDS[name][0], monkeypatch, common.Parser)
    flags = _value_flags(parser)
    assert flags, f"{name} has no flag taking a value"
    for flag in flags:
        try:
            args, _ = parser.parse_known_args([flag, POSE])
        except SystemExit:  # the value's own check refused it (e.g. a count): not argparse's
            err = capsys.readouterr().err
            assert "expected one argument" not in err, f"{name} {flag}: {err}"
            assert flag in err, f"{name} {flag}: {err}"
        else:
            action = next(a for a in parser._actions if flag in a.option_strings)
            value = getattr(args, action.dest)
            assert value is not None and value != action.default, f"{name} {flag} -> {value!r}"


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_every_benchmark_flag_takes_a_negative_value(name, capsys) -> None:
    code = None
    module = importlib.import_module(f"mcl.bench.{name}")
    import mcl.cli.bench as bench

    with bench._command_parsers(module, f"racecar-sim bench {name}"):
        parser_class = module.argparse.ArgumentParser
        seen: list[argparse.ArgumentParser] = []
        original = parser_class.parse_args

        def capture(self, *args, **kwargs):
            seen.append(self)
            raise _Captured

        parser_class.parse_args = capture
        try:
            with pytest.raises(_Captured):
                module.main([])
        finally:
            parser_class.parse_args = original
    parser = seen[0]
    for flag in _value_flags(parser):
        try:
            parser.parse_known_args([flag, POSE])
        except SystemExit as exc:
            code = exc.code
            err = capsys.readouterr().err
            assert code == 2 and "expected one argument" not in err, f"{name} {flag}: {err}"


def test_the_replay_help_example_parses(tmp_path, capsys) -> None:
    """``--init -20.9,-0.3,1.26`` and ``--init=...`` get past the parser and the pose check to the
    next check (the bag that is not there)."""
    for init in (["--init", POSE], [f"--init={POSE}"], ["--init", "-20.9, -0.3, 1.26"]):
        with pytest.raises(SystemExit) as exc:
            main(["replay", str(tmp_path / "none.bag"), "--map", "basement_loop", *init])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and "does not exist" in err, err
    from mcl.cli.replay import _init, build_parser

    parser = build_parser()
    args = parser.parse_args(["BAG", "--init", POSE, "--seed", "3"])
    assert _init(parser, args.init) == (-20.9, -0.3, 1.26) and args.seed == 3


def test_calibrate_noise_start_takes_negative_poses(monkeypatch) -> None:
    parser = _parser_of("mcl.cli.calibrate_noise", monkeypatch, common.Parser)
    args = parser.parse_args(["A.bag", "B.bag", "--start", "-19.34,5.74,1.136", "--start", POSE])
    assert [list(s) for s in args.start] == [[-19.34, 5.74, 1.136], [-20.9, -0.3, 1.26]]


def test_a_word_that_is_not_a_number_is_still_an_option(capsys) -> None:
    """Only numbers are taken as values: ``--init --seed 3`` still says --init lacks its value."""
    with pytest.raises(SystemExit) as exc:
        main(["replay", "BAG", "--map", "basement_loop", "--init", "--seed", "3"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--init: expected one argument" in err
    for text in ("-1", "-0.5", "-1e-3", "-.5,2", POSE, "-1, 2,3e2"):
        assert common.NEGATIVE_NUMBERS.match(text), text
    for text in ("-x", "--seed", "-1,a", "-", "-1,,2"):
        assert not common.NEGATIVE_NUMBERS.match(text), text
