"""The compile notice says what it measures, and the command prints the compile time it measured
(numba's own ``numba:compile`` events: a kernel loaded from the cache is not counted)."""

from __future__ import annotations

import numba
import numpy as np

import mcl.cli.compile_notice as compile_notice


def test_the_measured_compile_time_is_printed_once_after_the_notice(monkeypatch, capsys) -> None:
    monkeypatch.setattr(compile_notice, "kernels_cached", lambda: False)
    assert compile_notice.compile_notice() is True
    notice = capsys.readouterr().err
    assert "first run only" in notice and "measured and printed at the end" in notice

    @numba.njit(cache=False)
    def fresh(x):  # a new function: numba compiles it on this first call
        return np.sum(x * x) + 1.0

    assert fresh(np.arange(4.0)) == 15.0
    seconds = compile_notice.compile_report()
    line = capsys.readouterr().err.strip()
    assert seconds > 0 and line.startswith(f"numba compiled its kernels in {seconds:.1f} s")
    assert compile_notice.compile_report() == 0.0  # stopped: printed once
    assert capsys.readouterr().err == ""


def test_nothing_is_printed_with_a_warm_cache(monkeypatch, capsys) -> None:
    monkeypatch.setattr(compile_notice, "kernels_cached", lambda: True)
    assert compile_notice.compile_notice() is False

    @numba.njit(cache=False)
    def other(x):
        return x + 2

    assert other(1) == 3
    assert compile_notice.compile_report() == 0.0  # not measuring: no notice was given
    assert capsys.readouterr().err == ""
