"""Thin wrapper: `racecar-sim fast-laps` (see [`mcl.cli.fast_laps`][mcl.cli.fast_laps])."""

import sys

from mcl.cli.fast_laps import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
