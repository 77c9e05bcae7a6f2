"""Thin wrapper: `racecar-sim race` (see [`mcl.cli.race`][mcl.cli.race])."""

import sys

from mcl.cli.race import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
