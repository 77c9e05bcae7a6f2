"""Runs fuzz cases in a subprocess under a memory limit (``RLIMIT_AS``) and a time limit, and
judges what came back: one clear error or a correct run.

A clear error is a ``ValueError`` (``MapError``, ``BagError`` and the settings' errors are
ValueErrors) or Gymnasium's ``ResetNeeded``, whose message is one line of at most
:data:`MAX_MESSAGE` characters; for a command line, exit code 2 with exactly one stderr line
``racecar-sim SUBCOMMAND: error: ...`` and no traceback, and no output folder left behind.
Anything else (a ``TypeError``, ``MemoryError``, an assertion about the run, a killed worker,
exceeding the time limit) is a failure, except the ``clear_types`` a case names, whose message
must then start with the case's ``owner`` (a wrapper refusing the wrong kind of env: a
``TypeError`` naming itself).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path
from typing import Any

__all__ = ["MAX_MESSAGE", "MEMORY_LIMIT", "PROBLEM_KINDS", "judge", "problem_kind", "run_cases"]

ROOT = Path(__file__).resolve().parents[2]
MEMORY_LIMIT = 3 << 30
"""Bytes of address space a worker may have (3 GiB)."""
MAX_MESSAGE = 400
"""Longest error message that counts as one clear line."""
_CLEAR = ("ValueError", "ResetNeeded")


def _limit(memory: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    return apply


def run_cases(
    cases: list[dict[str, Any]], timeout: float, memory: int = MEMORY_LIMIT
) -> list[dict[str, Any]]:
    """Run ``cases`` in one worker process limited to ``memory`` bytes and ``timeout`` seconds;
    one result per case (a case the worker never reported gets ``outcome: "lost"`` with the
    worker's end: killed by the time limit, out of memory, or its stderr's last lines)."""
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    env.setdefault("NUMBA_NUM_THREADS", "2")
    try:
        run = subprocess.run(
            [sys.executable, "-m", "tests.fuzz.worker"],
            input=json.dumps(cases),
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=ROOT,
            env=env,
            preexec_fn=_limit(memory),
        )
        stdout, end = run.stdout, f"exit {run.returncode}: {run.stderr[-800:]}"
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout or b""
        stdout = out.decode() if isinstance(out, bytes) else out
        end = f"killed after the time limit of {timeout:g} s"
    results: list[dict[str, Any]] = [{"outcome": "lost", "end": end} for _ in cases]
    for line in stdout.splitlines():
        if line.startswith("{"):
            row = json.loads(line)
            results[row["index"]] = row
    return results


def judge(case: dict[str, Any], result: dict[str, Any]) -> str | None:
    """None when ``result`` is one clear error or a correct run, else what is wrong."""
    outcome = result["outcome"]
    if outcome == "ok":
        return None
    if outcome == "exit":
        if result["exit"] == 0:
            return None
        if result["left"]:
            return f"left {result['left']} behind"
        lines = result["stderr"].strip().splitlines()
        if result["exit"] != 2:
            return f"exit {result['exit']}: {lines[-3:]}"
        if len(lines) != 1 or "Traceback" in result["stderr"]:
            return f"not one stderr line: {lines[:5]}"
        if not lines[0].startswith("racecar-sim ") or len(lines[0]) > MAX_MESSAGE + 100:
            return f"not a one-line error: {lines[0][:300]}"
        return None
    if outcome == "loss":
        return f"lost files it did not make: {result['lost'][:5]}"
    if outcome == "error":
        if case.get("kind") == "cli" or case.get("command"):  # a command raising is a traceback
            return f"raised {result['type']}: {result['message'][:300]}\n{result['where']}"
        message = result["message"]
        # a case may name more clear types (a TypeError for the wrong kind of env), which must
        # then come from its owner, saying so
        extra = tuple(case.get("clear_types", ())) if message.startswith(case.get("owner", "\0")) else ()
        if not any(name in _CLEAR + extra for name in result["mro"]):
            return f"{result['type']}: {message[:300]}\n{result['where']}"
        if "\n" in message or not message.strip() or len(message) > MAX_MESSAGE:
            return f"not one short line ({len(message)} chars): {message[:300]!r}"
        return None
    return f"{outcome}: {result.get('message') or result.get('end')}"


PROBLEM_KINDS = ("traceback", "hang", "loss", "memory", "wrong")
"""How a problem is counted in a campaign (scripts/fuzz.py)."""


def problem_kind(result: dict[str, Any]) -> str:
    """Which of [PROBLEM_KINDS][tests.fuzz.harness.PROBLEM_KINDS] a judged problem is: a file lost
    (``loss``), the time limit (``hang``), the memory limit or a MemoryError (``memory``), a wrong
    run (``wrong``), else an exception, exit code or stderr that is not one clear line
    (``traceback``). A case may report ``memory`` itself (a process it watched grew too big)."""
    outcome = result["outcome"]
    end = str(result.get("end", ""))
    if outcome == "loss":
        return "loss"
    if outcome == "lost" and "time limit" in end:
        return "hang"
    if outcome == "memory" or result.get("type") == "MemoryError" or (
        outcome == "lost" and ("MemoryError" in end or "exit -9" in end or "Cannot allocate" in end)
    ):
        return "memory"
    if outcome == "wrong":
        return "wrong"
    return "traceback"
