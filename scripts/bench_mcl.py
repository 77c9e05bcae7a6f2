"""Thin wrapper: `racecar-sim bench mcl` (see :mod:`mcl.bench.mcl`)."""

import sys

from mcl.bench.mcl import main

if __name__ == "__main__":
    sys.exit(main())
