"""Work shared by threads that take items from one atomic counter: no thread waits for another to
wake up.

numba's ``prange`` (OpenMP) splits the work in fixed shares and ends with a barrier, so a parallel
region lasts until the slowest thread has woken up and done its share. On a virtual machine whose
idle CPU is halted, waking the second thread was measured to take from 0.1 to several milliseconds
(more than a whole 4000-particle update), and a parallel region then ran slower than one thread.

Here the calling thread and ``threads - 1`` pool threads each run the same ``nogil`` numba kernel,
which takes items (blocks of work) with `fetch_add()` on a shared counter until none are left.
A pool thread that the OS runs late finds fewer items, or none; a pool job that has not started
when the calling thread has taken the last item is cancelled instead of waited for. The result does
not depend on which thread did which item (each item writes its own outputs).

Before waking them, the pool's threads are allowed every CPU but the calling thread's (Linux):
on the 2-vCPU VM, after even 1 ms of idling the kernel woke the pool thread on the caller's own
CPU about half the time, and two threads then ran no faster than one.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba.core import types
from numba.extending import intrinsic

__all__ = ["fetch_add", "run_shared"]


@intrinsic
def fetch_add(typingctx, counter, delta):
    """``old = counter[0]; counter[0] += delta; return old`` as one atomic operation (int64).

    For numba kernels only (an LLVM ``atomicrmw add``); ``counter`` is a contiguous int64 array.
    """
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None
    sig = types.int64(counter, types.int64)

    def codegen(context, builder, signature, args):
        array, step = args
        data = context.make_array(signature.args[0])(context, builder, array).data
        return builder.atomic_rmw("add", data, step, "seq_cst")

    return sig, codegen


_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_lock = threading.Lock()
_worker_ids: list[int] = []  # native thread ids of the pool's threads
_worker_cpu: dict[int, int] = {}  # the CPU each was last kept off (see _keep_off)
_libc: ctypes.CDLL | None = None  # the C library, for sched_getcpu


def _get_pool(workers: int) -> ThreadPoolExecutor:
    """The module's pool of at least ``workers`` threads (created on first use, grown on demand)."""
    global _pool, _pool_size
    with _pool_lock:
        if _pool is None or _pool_size < workers:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _worker_ids.clear()
            _worker_cpu.clear()
            _pool = ThreadPoolExecutor(
                workers, thread_name_prefix="racecar-shared", initializer=_register
            )
            _pool_size = workers
        return _pool


def _register() -> None:
    _worker_ids.append(threading.get_native_id())


def _current_cpu() -> int:
    """The CPU this thread runs on (Linux with glibc or musl), or -1."""
    global _libc
    try:
        if _libc is None:
            _libc = ctypes.CDLL(None)
        return int(_libc.sched_getcpu())
    except (AttributeError, OSError, TypeError):  # no sched_getcpu (macOS), no CDLL(None) (Windows)
        return -1


def _keep_off(cpu: int) -> None:
    """Let the pool's threads run anywhere but ``cpu`` (the calling thread's).

    Measured on a 2-vCPU VM: after even 1 ms of idling, Linux woke the pool thread on the CPU of
    the thread that woke it about half the time, and the two then shared that CPU while the other
    stayed idle (two threads no faster than one). Only Linux; a no-op where affinity is not
    available or the machine has one CPU allowed.
    """
    if cpu < 0 or not hasattr(os, "sched_setaffinity"):
        return
    allowed = os.sched_getaffinity(0) - {cpu}
    if not allowed:
        return
    for tid in list(_worker_ids):
        if _worker_cpu.get(tid) != cpu:
            try:
                os.sched_setaffinity(tid, allowed)
                _worker_cpu[tid] = cpu
            except OSError:  # the thread has exited (an old pool)
                pass


@atexit.register
def _shutdown() -> None:
    if _pool is not None:
        _pool.shutdown(wait=False, cancel_futures=True)


def _forget_pool() -> None:
    """In a forked child the parent's pool threads do not exist: start a new pool on demand."""
    global _pool, _pool_size
    _pool = None
    _pool_size = 0
    _worker_ids.clear()
    _worker_cpu.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def run_shared(kernel: Callable[..., object], args: tuple, threads: int) -> None:
    """Run ``kernel(*args, counter)`` on this thread and on ``threads - 1`` pool threads.

    ``kernel`` is a numba function compiled with ``nogil=True`` that takes items with
    ``fetch_add(counter, 1)`` until the count passes its last item; ``counter`` is a fresh
    int64 array ``[0]``. Returns once every item is done: pool jobs that had not started are
    cancelled, started ones are waited for (each finishes at most the item it holds).
    """
    counter = np.zeros(1, dtype=np.int64)
    if threads <= 1:
        kernel(*args, counter)
        return
    pool = _get_pool(threads - 1)
    _keep_off(_current_cpu())
    jobs = [pool.submit(kernel, *args, counter) for _ in range(threads - 1)]
    try:
        kernel(*args, counter)
    finally:
        for job in jobs:
            if not job.cancel():
                job.result()
