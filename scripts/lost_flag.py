"""Thin wrapper: `racecar-sim lost-flag` (see [mcl.cli.lost_flag][])."""

import sys

from mcl.cli.lost_flag import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
