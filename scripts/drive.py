"""Thin wrapper: `racecar-sim drive` (see [`mcl.cli.drive`][mcl.cli.drive])."""

import sys

from mcl.cli.drive import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
