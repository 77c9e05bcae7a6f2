"""``racecar-sim bench NAME [options]``: run one benchmark module of [`mcl.bench`][mcl.bench]."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import importlib
import sys
from collections.abc import Iterator, Sequence
from types import ModuleType
from typing import Any, NoReturn

from mcl.cli.common import HelpFormatter, NegativeValuesParser

BENCHMARKS: dict[str, str] = {
    "raycast": "ray casting rates and errors per method",
    "sim": "simulator steps per second",
    "mcl": "particle filter update rate per stage",
    "uncertainty": "cost of the uncertainty report and KLD count",
    "peers": "the MCL update against real peers (range_libc, f1tenth_gym); localization vs nav2 amcl",
    "sensor_models": "beam model vs likelihood field: localization error in the same drives",
    "executors": "the same sweep on the process pool and on a local Ray",
    "replay": "replaying the real bags: real-time factor on one core, settling time, scan_fit",
    "soak": "a 2-hour headless drive: peak memory at 10, 60 and 120 simulated minutes",
    "live": "a localized drive with and without the Foxglove live view (steps/s)",
    "live_hostile": "a drive with and without --live under misbehaving clients: wall ratio, same log",
    "dynamics": "the single-track car vs f1tenth_gym (skidpad, open loop) and its speed cost",
    "race_matrix": "scripted races on the loop maps: contacts, passes, laps per car by speed",
    "memory": "resident memory per car of the vector env, reset without poses (1, 32, 128 cars)",
}
"""Benchmark name -> what it measures (module ``mcl.bench.<name>``)."""


class _CommandParser(NegativeValuesParser):
    """A benchmark's parser as ``racecar-sim bench NAME``: help with defaults, one-line errors."""

    command = "racecar-sim bench"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["prog"] = self.command
        kwargs["formatter_class"] = HelpFormatter
        super().__init__(*args, **kwargs)

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        default = kwargs.get("default")
        if not kwargs.get("help") and default is not None and default is not False:
            kwargs["help"] = "(default: %(default)s)"
        return super().add_argument(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


@contextlib.contextmanager
def _command_parsers(module: ModuleType, prog: str) -> Iterator[None]:
    """While ``module`` (a benchmark) runs, the ``argparse`` it sees builds `_CommandParser`.

    The benchmark modules build plain parsers (they also run as ``scripts/bench_*.py``); only the
    name ``argparse`` inside ``module`` is swapped, for one ``racecar-sim bench`` call.
    """
    plain = getattr(module, "argparse", None)
    if plain is not argparse:
        yield
        return
    view = ModuleType("argparse")
    view.__dict__.update(vars(argparse))
    view.ArgumentParser = type("CommandParser", (_CommandParser,), {"command": prog})  # type: ignore[attr-defined]
    module.argparse = view  # type: ignore[attr-defined]
    try:
        yield
    finally:
        module.argparse = plain  # type: ignore[attr-defined]


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``bench NAME [options]``; ``bench --help`` lists the benchmarks."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        rows = "\n".join(f"  {n:<12} {d}" for n, d in BENCHMARKS.items())
        print(
            f"usage: racecar-sim bench NAME [options]   (racecar-sim bench NAME --help for its "
            f"options)\n\nbenchmarks:\n{rows}\n\nexamples:\n"
            "  racecar-sim bench sim --quick\n"
            "  racecar-sim bench raycast --quick"
        )
        return 0
    given = args[0]
    if given.startswith("-"):
        print(
            f"racecar-sim bench: error: {given!r} before the benchmark's name; usage: "
            f"racecar-sim bench NAME [options], NAME one of {', '.join(BENCHMARKS)}",
            file=sys.stderr,
        )
        return 2
    args[0] = given.replace("-", "_")  # sensor-models = sensor_models
    if args[0] not in BENCHMARKS:
        close = difflib.get_close_matches(args[0], list(BENCHMARKS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        print(
            f"racecar-sim bench: error: unknown benchmark {given!r}{hint}; "
            f"choose from {', '.join(BENCHMARKS)}",
            file=sys.stderr,
        )
        return 2
    return _run(args[0], args[1:], f"racecar-sim bench {args[0]}")


def _run(name: str, argv: Sequence[str], prog: str) -> int:
    """Benchmark ``name`` with ``argv``, its parser named ``prog`` (help with defaults, one-line
    errors); Ctrl-C ends it with 130 and a one-line message."""
    module = importlib.import_module(f"mcl.bench.{name}")
    try:
        with _command_parsers(module, prog):
            result = module.main(list(argv))
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    return result if isinstance(result, int) else 0


def run_script(name: str) -> int:
    """``scripts/bench_<name>.py``: the benchmark with the command's one-line errors, named by the
    script's own path."""
    return _run(name, sys.argv[1:], sys.argv[0])
