"""Thin wrapper: ``racecar-sim bench sim`` (see [`mcl.bench.sim`][mcl.bench.sim])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("sim"))
