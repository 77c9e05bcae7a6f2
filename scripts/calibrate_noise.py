"""Thin wrapper: `racecar-sim calibrate-noise` (see [`mcl.cli.calibrate_noise`][mcl.cli.calibrate_noise])."""

import sys

from mcl.cli.calibrate_noise import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
