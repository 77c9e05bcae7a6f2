"""``racecar-sim bench NAME [options]``: run one benchmark module of :mod:`mcl.bench`."""

from __future__ import annotations

import difflib
import importlib
import sys
from collections.abc import Sequence

BENCHMARKS: dict[str, str] = {
    "raycast": "ray casting rates and errors per method",
    "sim": "simulator steps per second",
    "mcl": "particle filter update rate per stage",
    "uncertainty": "cost of the uncertainty report and KLD count",
}
"""Benchmark name -> what it measures (module ``mcl.bench.<name>``)."""


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
    if args[0] not in BENCHMARKS:
        close = difflib.get_close_matches(args[0], list(BENCHMARKS), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        print(
            f"racecar-sim bench: error: unknown benchmark {args[0]!r}{hint}; "
            f"choose from {', '.join(BENCHMARKS)}",
            file=sys.stderr,
        )
        return 2
    result = importlib.import_module(f"mcl.bench.{args[0]}").main(args[1:])
    return result if isinstance(result, int) else 0
