"""A longer fuzz campaign than the tests' (tests/fuzz): many seeds of hostile maps, settings,
filter settings, actions, command lines, damaged bags, command-line paths (``path``), hostile
scan headers (``scan``), the race's and the localization wrappers' API misused and misbehaving
live-view clients against a short drive (``live``), each batch in
a worker process under a memory and a time limit. Prints a table per kind (clean errors, correct
runs, problems by kind: tracebacks, hangs, lost files, memory, wrong runs; the slowest case; the
workers' peak resident memory) and every problem found; exits 1 when there was one.

    python scripts/fuzz.py                       # 200 cases of each kind, seeds from 1
    python scripts/fuzz.py --kinds map setting --cases 1000 --seed 7
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.fuzz import mutations
from tests.fuzz.harness import MEMORY_LIMIT, PROBLEM_KINDS, judge, problem_kind, run_cases

KINDS = ("setting", "filter", "map", "action", "cli", "bag", "path", "scan", "race_api", "localization_api",
         "live")


def _short(value: object) -> object:
    """``value`` with every text longer than 80 characters cut (a case may hold a 100 KB path)."""
    if isinstance(value, str) and len(value) > 80:
        return f"{value[:40]}...({len(value)} characters)...{value[-20:]}"
    if isinstance(value, list):
        return [_short(v) for v in value]
    if isinstance(value, dict):
        return {k: _short(v) for k, v in value.items()}
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="scripts/fuzz.py", description=__doc__.split("\n")[0])
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    parser.add_argument("--cases", type=int, default=200, help="cases per kind (default 200)")
    parser.add_argument("--batch", type=int, default=50, help="cases per worker (default 50)")
    parser.add_argument("--seed", type=int, default=1, help="first seed (one seed per batch)")
    parser.add_argument("--memory-gb", type=float, default=MEMORY_LIMIT / 2**30)
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per worker")
    args = parser.parse_args(argv)
    if args.cases < 1 or args.batch < 1:
        parser.error("--cases and --batch must be >= 1")
    memory = int(args.memory_gb * 2**30)
    problems: list[str] = []
    shown = {"traceback": "tracebacks", "hang": "hangs", "loss": "losses", "wrong": "wrong runs"}
    names = " | ".join(shown.get(k, k) for k in PROBLEM_KINDS)
    print(f"| kind | cases | clean errors | correct runs | {names} | slowest case (s) | "
          "peak worker RSS (MiB) | wall (s) |")  # fmt: skip
    print("|---|" + "---:|" * (len(PROBLEM_KINDS) + 6))
    for kind in args.kinds:
        make = getattr(mutations, f"{kind}_cases")
        t0 = time.perf_counter()
        counts = {"error": 0, "ok": 0, "bad": 0, **dict.fromkeys(PROBLEM_KINDS, 0)}
        slowest = peak = 0.0
        done, seed = 0, args.seed
        while done < args.cases:
            n = min(args.batch, args.cases - done)
            cases = make(seed, n)
            for case, result in zip(cases, run_cases(cases, args.timeout, memory), strict=True):
                slowest = max(slowest, result.get("seconds", 0.0))
                peak = max(peak, result.get("peak_rss_mib", 0.0))
                problem = judge(case, result)
                if problem is not None:
                    counts["bad"] += 1
                    counts[problem_kind(result)] += 1
                    problems.append(f"[{kind}, seed {seed}] {_short(case)} -> {problem}")
                elif result["outcome"] == "ok" or result.get("exit") == 0:
                    counts["ok"] += 1
                else:
                    counts["error"] += 1
            done += n
            seed += 1
        wall = time.perf_counter() - t0
        found = " | ".join(str(counts[k]) for k in PROBLEM_KINDS)
        print(f"| {kind} | {done} | {counts['error']} | {counts['ok']} | {found} | "
              f"{slowest:.1f} | {peak:.0f} | {wall:.0f} |", flush=True)  # fmt: skip
    for p in problems:
        print(p[:2000])
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
