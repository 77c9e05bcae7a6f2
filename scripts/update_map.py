"""Thin wrapper: `racecar-sim update-map` (see [`mcl.cli.update_map`][mcl.cli.update_map])."""

import sys

from mcl.cli.update_map import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
