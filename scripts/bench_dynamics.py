"""Thin wrapper: ``racecar-sim bench dynamics`` (see [`mcl.bench.dynamics`][mcl.bench.dynamics])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("dynamics"))
