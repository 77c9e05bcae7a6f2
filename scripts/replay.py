"""Thin wrapper: `racecar-sim replay` (see [`mcl.cli.replay`][mcl.cli.replay])."""

import sys

from mcl.cli.replay import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
