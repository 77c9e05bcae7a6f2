"""Thin wrapper: `racecar-sim bench executors` (see :mod:`mcl.bench.executors`)."""

import sys

from mcl.bench.executors import main

if __name__ == "__main__":
    sys.exit(main())
