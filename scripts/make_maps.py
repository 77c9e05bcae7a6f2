"""Thin wrapper: ``racecar-sim make-maps`` (see [`racecar_sim.maps.draw`][racecar_sim.maps.draw])."""

import sys

from mcl.cli.main import main

if __name__ == "__main__":
    sys.exit(main(["make-maps", *sys.argv[1:]]))
