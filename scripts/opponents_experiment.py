"""Thin wrapper: `racecar-sim opponents` (see [`mcl.cli.opponents`][mcl.cli.opponents])."""

import sys

from mcl.cli.opponents import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
