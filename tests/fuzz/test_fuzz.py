"""Seeded fuzzing: hostile maps, settings, filter settings, actions, command lines, damaged bags,
command-line paths, hostile scan headers, the race's and the localization wrappers' API misused
and misbehaving live-view clients, each kind run in a worker process under a 3 GiB memory limit
and a time limit. Every case must end in one clear error or a correct run
(tests/fuzz/harness.py says what counts).

The cases are the same on every run (fixed seeds); ``scripts/fuzz.py`` runs a longer campaign with
other seeds.
"""

from __future__ import annotations

import pytest

from tests.fuzz import mutations
from tests.fuzz.harness import judge, problem_kind, run_cases

# kind -> (cases, seconds the worker may take: imports, numba's cached kernels, the cases); the
# suite runs a few of each kind, scripts/fuzz.py runs campaigns of hundreds
BUDGET = {
    "setting": (30, 240),
    "filter": (16, 240),
    "map": (30, 180),
    "action": (30, 180),
    "cli": (8, 240),
    "bag": (12, 240),
    "race_api": (12, 240),
    "localization_api": (24, 240),
    "path": (10, 300),
    "scan": (10, 300),
    "live": (5, 300),
}


@pytest.mark.parametrize("kind", sorted(BUDGET))
def test_fuzz_cases_end_in_one_clear_error_or_a_correct_run(kind: str) -> None:
    n, timeout = BUDGET[kind]
    cases = getattr(mutations, f"{kind}_cases")(seed=2026, n=n)
    results = run_cases(cases, timeout=timeout)
    problems = [
        f"{case} -> {problem}"
        for case, result in zip(cases, results, strict=True)
        if (problem := judge(case, result)) is not None
    ]
    assert not problems, "\n".join(problems[:10])
    # the kind's cases are not all refused (or all accepted): both paths are exercised
    outcomes = {r["outcome"] if r["outcome"] != "exit" else r["exit"] for r in results}
    assert len(outcomes) >= 2 or kind in ("cli", "live"), outcomes  # live: every run correct


def test_mutations_are_seeded() -> None:
    assert mutations.map_cases(5, 10) == mutations.map_cases(5, 10)
    assert mutations.setting_cases(5, 10) != mutations.setting_cases(6, 10)


def test_the_judge_refuses_what_is_not_a_clear_error() -> None:
    case: dict = {}
    assert judge(case, {"outcome": "ok"}) is None
    good = {"outcome": "error", "type": "MapError", "mro": ["MapError", "ValueError"],
            "message": "map x: bad", "where": ""}  # fmt: skip
    assert judge(case, good) is None
    assert judge(case, {**good, "message": "two\nlines"}) is not None
    assert judge(case, {**good, "message": "x" * 1000}) is not None
    assert judge(case, {**good, "type": "TypeError", "mro": ["TypeError"]}) is not None
    assert judge(case, {"outcome": "lost", "end": "killed"}) is not None
    assert judge(case, {"outcome": "wrong", "message": "scan not finite"}) is not None
    cli = {"outcome": "exit", "exit": 2, "stderr": "racecar-sim drive: error: --env dt: no\n",
           "left": []}  # fmt: skip
    assert judge(case, cli) is None
    assert judge(case, {**cli, "exit": 1}) is not None
    assert judge(case, {**cli, "stderr": "Traceback (most recent call last):\n  x\n"}) is not None
    assert judge(case, {**cli, "left": ["out"]}) is not None
    # a case may name another clear type, from its owner only
    wrap = {"clear_types": ["TypeError"], "owner": "LocalizedRaceEnv"}
    type_error = {**good, "type": "TypeError", "mro": ["TypeError"],
                  "message": "LocalizedRaceEnv needs a racecar_sim.RaceEnv; got NoneType"}  # fmt: skip
    assert judge(wrap, type_error) is None
    assert judge(wrap, {**type_error, "message": "'NoneType' object is not iterable"}) is not None
    assert judge(case, type_error) is not None
    assert judge(case, {"outcome": "loss", "lost": ["user/data.txt"], "exit": 0}) is not None
    raised = {**good, "type": "ValueError", "mro": ["ValueError"]}
    assert judge({"kind": "scan", "command": True}, raised) is not None  # a command raised
    assert judge({"kind": "scan"}, raised) is None  # the API's one clear error


def test_problems_are_counted_by_kind() -> None:
    assert problem_kind({"outcome": "loss", "lost": ["a"]}) == "loss"
    assert problem_kind({"outcome": "lost", "end": "killed after the time limit of 9 s"}) == "hang"
    assert problem_kind({"outcome": "lost", "end": "exit 1: ... MemoryError"}) == "memory"
    assert problem_kind({"outcome": "error", "type": "MemoryError"}) == "memory"
    assert problem_kind({"outcome": "memory", "message": "the server reached 900 MiB"}) == "memory"
    assert problem_kind({"outcome": "wrong", "message": "scan not finite"}) == "wrong"
    assert problem_kind({"outcome": "exit", "exit": 1, "stderr": "Traceback"}) == "traceback"
