"""Thin wrapper: `racecar-sim bench raycast` (see :mod:`mcl.bench.raycast`)."""

import sys

from mcl.bench.raycast import main

if __name__ == "__main__":
    main(sys.argv[1:])
