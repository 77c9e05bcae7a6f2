"""The compile notice tells the truth: it is said when numba starts compiling a kernel of ours (its
own ``numba:compile`` event, fired only on a cache miss), never when every kernel comes from the
on-disk cache; the command then prints the compile time it measured; the Python API logs the same
notice (logger ``racecar_sim``, INFO) instead of printing."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numba
import numpy as np

import mcl.cli.compile_notice as compile_notice
from racecar_sim.compile_log import on_first_compile


def _our_function(body: str, name: str = "probe"):
    """A fresh Python function whose module counts as ours (``racecar_sim._probe``)."""
    namespace: dict = {"__name__": "racecar_sim._probe", "np": np}
    exec(textwrap.dedent(body), namespace)
    return namespace[name]


def test_the_notice_comes_with_the_first_compile_of_ours_and_the_time_after(capsys) -> None:
    compile_notice.compile_notice()

    @numba.njit(cache=False)
    def users_own(x):  # a kernel of the test module, not ours: no notice
        return x + 2

    assert users_own(1) == 3
    assert capsys.readouterr().err == ""
    first = numba.njit(_our_function("def probe(x):\n    return np.sum(x * x) + 1.0\n"))
    second = numba.njit(_our_function("def probe(x):\n    return x - 1.0\n"))
    assert first(np.arange(4.0)) == 15.0 and second(2.0) == 1.0
    notice = capsys.readouterr().err
    assert notice.count("compiling numba kernels") == 1  # once, at the first compile
    assert "racecar_sim._probe.probe first" in notice and "measured and printed" in notice
    seconds = compile_notice.compile_report()
    line = capsys.readouterr().err.strip()
    assert seconds > 0 and line.startswith(f"numba compiled its kernels in {seconds:.1f} s")
    assert compile_notice.compile_report() == 0.0  # stopped: printed once
    assert capsys.readouterr().err == ""


def test_nothing_is_said_when_nothing_compiles(capsys) -> None:
    kernel = numba.njit(_our_function("def probe(x):\n    return x * 3\n"))
    assert kernel(2) == 6  # compiled before the command starts listening
    compile_notice.compile_notice()
    assert kernel(5) == 15  # the same signature: nothing to compile
    assert compile_notice.compile_report() == 0.0
    assert capsys.readouterr().err == ""


def test_on_first_compile_calls_back_once_and_stops_when_told() -> None:
    seen: list[str] = []
    stop = on_first_compile(seen.append)
    numba.njit(_our_function("def probe(x):\n    return x + 10\n"))(1)
    numba.njit(_our_function("def probe(x):\n    return x + 11\n"))(1)
    stop()
    assert seen == ["racecar_sim._probe.probe"]


_PROBE_MODULE = """\
import numba


@numba.njit(cache=True)
def kernel(x):
    return 2 * x + 1
"""

_RUN = """\
import importlib.util, logging, sys
logging.basicConfig(level=logging.INFO, format="%(name)s %(levelname)s: %(message)s")
import racecar_sim.env  # installs the library's log of the first compile
from mcl.cli.compile_notice import compile_notice, compile_report
spec = importlib.util.spec_from_file_location("racecar_sim.cache_probe", sys.argv[1])
module = sys.modules[spec.name] = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
compile_notice()
assert module.kernel(3) == 7
print("measured", compile_report() > 0)
"""


def test_a_cold_cache_says_so_and_a_warm_one_says_nothing(tmp_path) -> None:
    """Two processes on one empty numba cache: the first compiles (the notice, the library's INFO
    log, the measured time), the second loads the kernel from the cache and says nothing."""
    probe = tmp_path / "cache_probe.py"
    probe.write_text(_PROBE_MODULE)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    command = [sys.executable, "-c", _RUN, str(probe)]
    runs = [
        subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
        for _ in range(2)
    ]
    for run in runs:
        assert run.returncode == 0, run.stderr
    cold, warm = runs
    first = "compiling numba kernels (racecar_sim.cache_probe.kernel first"
    assert f"racecar_sim INFO: {first}" in cold.stderr  # the library's log
    assert f"\n{first}" in "\n" + cold.stderr  # the command's notice
    assert "numba compiled its kernels in" in cold.stderr and "measured True" in cold.stdout
    assert "compiling" not in warm.stderr and "compiled" not in warm.stderr, warm.stderr
    assert "measured False" in warm.stdout
