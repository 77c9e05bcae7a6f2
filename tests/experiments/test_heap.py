"""The drive's heap trim returns the pages the allocator keeps but nothing holds."""

from __future__ import annotations

import subprocess
import sys

import pytest

# A child process, so this test's own heap does not matter: 150 MB in 4 kB blocks, every 64th
# kept, the rest freed. glibc keeps the freed blocks' pages (they lie below a kept block), and
# malloc_trim(0) hands them back.
_CHILD = """
import sys
from mcl.experiments.heap import release_free_heap

def rss_kib():
    with open("/proc/self/status", encoding="ascii") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))

blocks = [bytes(4000) + bytes([i % 256]) for i in range(37_500)]
kept = blocks[::64]
del blocks
before = rss_kib()
ran = release_free_heap()
print(int(ran), before, rss_kib(), len(kept))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="malloc_trim is glibc's (Linux)")
def test_the_trim_returns_freed_pages_to_the_system() -> None:
    done = subprocess.run(
        [sys.executable, "-c", _CHILD], capture_output=True, text=True, timeout=120, check=True
    )
    ran, before, after, _ = (int(v) for v in done.stdout.split())
    if not ran:
        pytest.skip("this C library has no malloc_trim (not glibc)")
    assert before - after > 50_000  # KiB: most of the ~146 MB freed comes back


def test_no_trim_where_the_c_library_has_none(monkeypatch) -> None:
    import mcl.experiments.heap as heap

    monkeypatch.setattr(heap, "_malloc_trim", lambda: None)
    assert heap.release_free_heap() is False
