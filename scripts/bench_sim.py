"""Thin wrapper: `racecar-sim bench sim` (see :mod:`mcl.bench.sim`)."""

import sys

from mcl.bench.sim import main

if __name__ == "__main__":
    main(sys.argv[1:])
