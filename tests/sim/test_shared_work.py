"""Threads sharing work through one atomic counter: every item done exactly once, and a pool
thread that cannot run does not hold the caller up."""

from __future__ import annotations

import os
import threading
import time

import numba as nb
import numpy as np
import pytest

from racecar_sim.raycast import shared_work
from racecar_sim.raycast.shared_work import fetch_add, run_shared


@nb.njit(nogil=True)
def _visit(visits, spin, counter):
    """Take items one at a time; count each visit (a plain, non-atomic increment: a double
    claim would show as a 2) and spin a little so the threads interleave."""
    n = visits.shape[0]
    while True:
        i = fetch_add(counter, 1)
        if i >= n:
            break
        acc = 0.0
        for k in range(spin):
            acc += k * 1e-9
        visits[i] += 1 + int(acc * 0.0)


@nb.njit(nogil=True)
def _add_many(counter, times):
    for _ in range(times):
        fetch_add(counter, 1)


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_every_item_taken_exactly_once(threads):
    visits = np.zeros(5000, dtype=np.int64)
    run_shared(_visit, (visits, 200), threads)
    np.testing.assert_array_equal(visits, 1)


def test_fetch_add_is_atomic_across_threads():
    counter = np.zeros(1, dtype=np.int64)
    workers = [threading.Thread(target=_add_many, args=(counter, 200_000)) for _ in range(3)]
    for w in workers:
        w.start()
    _add_many(counter, 200_000)
    for w in workers:
        w.join()
    assert counter[0] == 800_000


def test_fetch_add_returns_the_old_value():
    @nb.njit
    def twice(counter):
        return fetch_add(counter, 5), fetch_add(counter, -2)

    counter = np.array([7], dtype=np.int64)
    assert twice(counter) == (7, 12)
    assert counter[0] == 10


def test_a_pool_thread_that_cannot_run_is_not_waited_for():
    """Every pool thread busy: the caller does all the items, cancels the queued jobs and
    returns at once."""
    visits = np.zeros(3000, dtype=np.int64)
    run_shared(_visit, (visits, 0), 2)  # the pool exists
    release = threading.Event()
    pool = shared_work._get_pool(1)
    blockers = [pool.submit(release.wait, 30.0) for _ in range(shared_work._pool_size)]
    try:
        visits[:] = 0
        start = time.perf_counter()
        run_shared(_visit, (visits, 0), 2)
        assert time.perf_counter() - start < 10.0  # the blockers hold for 30 s
        np.testing.assert_array_equal(visits, 1)
    finally:
        release.set()
        for b in blockers:
            b.result()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_a_forked_child_gets_its_own_pool():
    """The parent's pool threads do not exist in a forked child; the child still uses two threads'
    worth of items without hanging (a multiprocessing worker started by fork)."""
    import multiprocessing

    visits = np.zeros(2000, dtype=np.int64)
    run_shared(_visit, (visits, 0), 2)  # the parent's pool exists
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(1) as pool:
        assert pool.apply(_child_run, ()) == 2000


def _child_run() -> int:
    assert shared_work._pool is None  # forgotten at the fork
    visits = np.zeros(2000, dtype=np.int64)
    run_shared(_visit, (visits, 0), 2)
    assert shared_work._pool is not None and shared_work._pool_size == 1
    return int((visits == 1).sum())


@pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs Linux CPU affinity and two CPUs",
)
def test_pool_threads_are_kept_off_the_callers_cpu():
    """Before waking the pool, its threads are allowed every CPU but the caller's (so Linux does
    not wake them on the caller's CPU to share it)."""
    visits = np.zeros(2000, dtype=np.int64)
    run_shared(_visit, (visits, 0), 2)  # threads exist and have registered
    run_shared(_visit, (visits, 0), 2)
    assert shared_work._worker_ids
    for tid in shared_work._worker_ids:
        cpu = shared_work._worker_cpu[tid]
        assert os.sched_getaffinity(tid) == os.sched_getaffinity(0) - {cpu}
