"""Thin wrapper: `racecar-sim bench replay` (see :mod:`mcl.bench.replay`)."""

import sys

from mcl.bench.replay import main

if __name__ == "__main__":
    main(sys.argv[1:])
