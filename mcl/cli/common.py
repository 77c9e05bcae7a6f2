"""What every ``racecar-sim`` subcommand shares: a parser whose errors are one line, help that shows
the defaults, and checks that turn a user's mistake into one line naming the flag, before anything
is written.

A mistake ends the command with ``racecar-sim SUBCOMMAND: error: --flag: the problem`` on stderr and
exit code 2 (argparse's convention), no traceback, and no output folder created: subcommands check
their map, env settings and flags first, then create ``--out`` with `output_folder()`, which
removes the folder again if the command fails before writing anything into it. The output paths'
checks ([out_paths][mcl.cli.out_paths], re-exported here) keep a command from writing into,
replacing or removing anything racecar-sim did not make.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import difflib
import math
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import yaml

from mcl.cli.out_paths import check_bag, check_file_out, check_out, output_folder, path_arg

__all__ = [
    "ENV_HELP",
    "MAP_HELP",
    "NEGATIVE_NUMBERS",
    "HelpFormatter",
    "NegativeValuesParser",
    "Parser",
    "check_bag",
    "check_env",
    "check_env_builds",
    "check_file_out",
    "check_map",
    "check_out",
    "check_resume",
    "duration_or_zero",
    "duration_seconds",
    "live_speed",
    "non_negative_float",
    "non_negative_int",
    "number_list",
    "output_folder",
    "path_arg",
    "positive_float",
    "positive_int",
]


# ---------------------------------------------------------------------- parser
class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the description's and epilog's line breaks (examples) and appends each option's
    default to its help, unless the default is None (the help says what happens) or a flag's False.
    """

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            "%(default)" in text
            or "default" in text
            or not action.option_strings
            or default is None
            or default is False
            or default == []
            or default is argparse.SUPPRESS  # also --help and --version
        ):
            return text
        if isinstance(default, tuple | list):
            shown = ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in default)
            shown = shown or "none"
        else:
            shown = str(default)
        return f"{text} (default: {shown.replace('%', '%%')})"


_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
NEGATIVE_NUMBERS = re.compile(rf"^-{_NUMBER}(?:\s*,\s*[-+]?{_NUMBER})*$")
"""A negative number or a comma-separated list of numbers that starts with one (``-20.9,-0.3,1.26``):
an option's value, not an option (argparse alone takes only ``-3`` and ``-0.5`` so)."""


class NegativeValuesParser(argparse.ArgumentParser):
    """An ArgumentParser that reads ``--init -20.9,-0.3,1.26`` as ``--init=-20.9,-0.3,1.26``.

    argparse takes a word starting with ``-`` for an option unless it is ``-3`` or ``-0.5`` alone,
    so a pose with a negative x after its flag was an unknown option (``expected one argument``).
    Here a word matching `NEGATIVE_NUMBERS` right after a flag that takes one value is joined
    to it with ``=`` before argparse sees the words; nothing else changes.
    """

    def parse_known_args(self, args: Sequence[str] | None = None, namespace: Any = None) -> Any:
        words = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(self._joined_negative_values(words), namespace)

    def _joined_negative_values(self, words: list[str]) -> list[str]:
        takes_one = {
            flag for action in self._actions if action.nargs is None for flag in action.option_strings
        }
        out: list[str] = []
        for word in words:
            if out and out[-1] in takes_one and NEGATIVE_NUMBERS.match(word):
                out[-1] = f"{out[-1]}={word}"
            else:
                out.append(word)
        return out


class Parser(NegativeValuesParser):
    """An ArgumentParser whose errors are one line (``PROG: error: PROBLEM``) and exit code 2, and
    which takes values such as ``-20.9,-0.3,1.26`` after a flag ([`NegativeValuesParser`][mcl.cli.common.NegativeValuesParser])."""

    def __init__(self, prog: str, description: str | None, epilog: str | None = None) -> None:
        super().__init__(
            prog=prog, description=description, epilog=epilog, formatter_class=HelpFormatter
        )

    def error(self, message: str) -> NoReturn:
        one_line = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {one_line}\n")

    def fail(self, flag: str, problem: str) -> NoReturn:
        """Stop with ``FLAG: PROBLEM`` (exit code 2)."""
        self.error(f"{flag}: {problem}")


def _env_names() -> str:
    from racecar_sim.settings.config import EnvConfig

    return ", ".join(f.name for f in dataclasses.fields(EnvConfig) if f.name != "map")


def _map_names() -> str:
    from racecar_sim.maps import bundled_names

    return ", ".join(bundled_names())


MAP_HELP = f"a bundled map ({_map_names()}) or a map_server YAML path"
"""Help of every ``--map``."""
ENV_HELP = (
    "a RacecarEnv setting for the run, repeatable, e.g. --env lidar_rate=20 --env range_sigma=0.05; "
    f"NAME is one of {_env_names()} (racecar_sim.settings.config.EnvConfig)"
)
"""Help of every ``--env``."""


# ---------------------------------------------------------------------- argument types
def _number(text: str, kind: type, what: str, ok, rule: str) -> Any:
    try:
        value = kind(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if not (math.isfinite(value) and ok(value)):
        raise argparse.ArgumentTypeError(f"must be {rule}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    return _number(text, float, "a number", lambda v: v > 0, "a number > 0")


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    return _number(text, float, "a number", lambda v: v >= 0, "a number >= 0")


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    return _number(text, int, "a whole number", lambda v: v >= 1, "a whole number >= 1")


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0."""
    return _number(text, int, "a whole number", lambda v: v >= 0, "a whole number >= 0")


def duration_seconds(text: str) -> float:
    """argparse type: simulated seconds within the run bound (a day;
    [RUN_BOUNDS][mcl.experiments.run_bounds.RUN_BOUNDS])."""
    from mcl.experiments.run_bounds import RUN_BOUNDS

    b = RUN_BOUNDS["run.duration"]
    return _number(text, float, "a number", lambda v: b.low < v <= b.high, f"seconds in {b.text()}")


def duration_or_zero(text: str) -> float:
    """argparse type: 0 (none) or simulated seconds as
    [duration_seconds][mcl.cli.common.duration_seconds]."""
    from mcl.experiments.run_bounds import RUN_BOUNDS

    b = RUN_BOUNDS["run.duration"]
    ok = lambda v: 0 <= v <= b.high  # noqa: E731
    return _number(text, float, "a number", ok, f"0 or seconds in {b.text()}")


def live_speed(text: str) -> float:
    """argparse type: 0 (unpaced) or times real time within the run bound
    ([RUN_BOUNDS][mcl.experiments.run_bounds.RUN_BOUNDS]; at least 0.01)."""
    from mcl.experiments.run_bounds import RUN_BOUNDS

    b = RUN_BOUNDS["live.speed"]
    ok = lambda v: v == 0 or b.low <= v <= b.high  # noqa: E731
    return _number(text, float, "a number", ok, f"0 (unpaced) or in {b.text()}")


def number_list(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated numbers > 0 (empty text: none)."""
    values = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        try:
            value = float(part)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected comma-separated numbers, got {part!r} in {text!r}"
            ) from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"every number must be > 0, got {part!r}")
        values.append(value)
    return tuple(values)


# ---------------------------------------------------------------------- checks
def _did_you_mean(word: str, choices: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def check_map(
    parser: Parser, spec: str, flag: str = "--map", env: Sequence[tuple[str, Any]] = ()
) -> str:
    """Load the map ``spec`` (bundled name or YAML path) once, or stop naming ``flag``; the
    ``max_map_cells`` of the ``env`` settings (from `check_env()`) applies."""
    from racecar_sim.maps import MapError, bundled_names, resolve_map

    try:
        resolve_map(spec, dict(env).get("max_map_cells"))
    except (MapError, OSError, ValueError) as exc:
        hint = (
            ""
            if os.sep in spec or spec.endswith((".yaml", ".yml"))
            else _did_you_mean(spec, bundled_names())
        )
        parser.fail(flag, f"{exc}{hint}")
    return spec


def _env_fields() -> dict[str, tuple[str, Any]]:
    """RacecarEnv setting name -> (its annotation, its default) (the map is set with ``--map``)."""
    from racecar_sim.settings.config import EnvConfig

    out: dict[str, tuple[str, Any]] = {}
    for f in dataclasses.fields(EnvConfig):
        if f.name == "map":
            continue
        default: Any = None
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
        out[f.name] = (kind, default)
    return out


def _env_value(text: str, kind: str, default: Any) -> Any:
    """A setting's value from its text, by its annotation ``kind`` (or the type of its default);
    ValueError says what was expected."""
    from racecar_sim.settings.validation import YAMLRefused, load_yaml, short

    try:
        value = load_yaml(text)  # no aliases; 1e12 is a number
    except YAMLRefused as exc:
        raise ValueError(str(exc)) from None
    except yaml.YAMLError:
        value = text
    shown = short(text)
    if kind == "bool" or (kind not in ("int", "float") and isinstance(default, bool)):
        if not isinstance(value, bool):
            raise ValueError(f"must be true or false, got {shown}")
    elif kind == "int" or (kind != "float" and isinstance(default, int)):
        if isinstance(value, str):
            with contextlib.suppress(ValueError):
                value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"must be a whole number, got {shown}")
    elif kind == "float" or isinstance(default, float):
        if isinstance(value, str):  # YAML reads 1e3 as text
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"must be a number, got {shown}")
    elif isinstance(default, tuple):
        ok = isinstance(value, list | tuple) and len(value) == len(default)
        if not ok or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            example = "[" + ", ".join(f"{v:g}" for v in default) + "]"
            raise ValueError(f"must be {len(default)} numbers like {example}, got {shown}")
        value = tuple(value)
    elif dataclasses.is_dataclass(default):
        if not isinstance(value, dict):
            raise ValueError(f"must be a mapping like {{wheelbase: 0.33}}, got {shown}")
    return value


def check_env(
    parser: Parser, items: Sequence[str], flag: str = "--env"
) -> tuple[tuple[str, Any], ...]:
    """``NAME=VALUE`` texts -> validated RacecarEnv settings, or stop with ``--env NAME: problem``.

    Each value is read as YAML and must have the type of the setting's default; then the settings
    are checked by [`racecar_sim.settings.config.EnvConfig`][racecar_sim.settings.config.EnvConfig], one by one (so a bad value is named) and
    together.
    """
    from racecar_sim.settings.config import EnvConfig
    from racecar_sim.settings.validation import short

    fields = _env_fields()
    settings: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            parser.fail(flag, f"expected NAME=VALUE, e.g. {flag} lidar_rate=20, got {short(item)}")
        if len(name) > 40:
            name = name[:37] + "..."
        if name == "map":
            parser.fail(f"{flag} map", "set the map with --map")
        if name not in fields:
            parser.fail(
                f"{flag} {name}",
                f"unknown setting{_did_you_mean(name, list(fields))}; "
                f"settings: {', '.join(fields)}",
            )
        try:
            settings[name] = _env_value(text.strip(), *fields[name])
            EnvConfig(**{name: settings[name]})
        except (TypeError, ValueError) as exc:
            parser.fail(f"{flag} {name}", str(exc))
    try:
        EnvConfig(**settings)
    except (TypeError, ValueError) as exc:
        parser.fail(flag, str(exc))
    return tuple(settings.items())


def check_env_builds(
    parser: Parser, spec: str, env: Sequence[tuple[str, Any]], seed: int | None = 0
) -> None:
    """Build the env on map ``spec`` with the ``env`` settings and reset it once (``seed``), or
    stop with one line: the problems found only then (no room for the car on the map, no start
    pose with ``start_clearance``, no room for obstacles) are a user's mistake too."""
    from racecar_sim.env import RacecarEnv
    from racecar_sim.maps import MapError

    try:
        RacecarEnv(spec, **dict(env)).reset(seed=seed)
    except MapError as exc:
        parser.fail("--map", str(exc))
    except ValueError as exc:
        parser.fail("--env", str(exc))


def check_resume(parser: Parser, config: object, out: Path, resume: bool) -> None:
    """With ``--resume``, refuse a folder made with other settings before anything runs (the
    experiment's own check, [settings_difference][mcl.experiments.runner.settings_difference])."""
    from mcl.experiments.runner import settings_difference

    problem = settings_difference(config, out / "config.json") if resume else None
    if problem is not None:
        parser.error(problem)
