"""Thin wrapper: `racecar-sim bench uncertainty` (see :mod:`mcl.bench.uncertainty`)."""

import sys

from mcl.bench.uncertainty import main

if __name__ == "__main__":
    main(sys.argv[1:])
