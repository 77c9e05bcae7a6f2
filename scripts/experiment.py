"""Thin wrapper: `racecar-sim experiment` (see [`mcl.cli.experiment`][mcl.cli.experiment])."""

import sys

from mcl.cli.experiment import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
