"""Benchmarks behind ``racecar-sim bench`` and ``scripts/bench_*.py``: rates and ratios measured in one run.

Each module has ``main(argv)``. The real Stata basement map is read from ``../shared/maps`` beside the
repository checkout (:data:`STATA`) when it is there.
"""

from pathlib import Path

SHARED = Path(__file__).resolve().parents[3] / "shared"
"""``../shared`` beside the repository checkout (absent in an installed wheel or a user's clone)."""
STATA = SHARED / "maps" / "stata_basement.yaml"
"""The MIT Stata basement map, when ``../shared`` is present."""
