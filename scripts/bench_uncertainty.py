"""Thin wrapper: ``racecar-sim bench uncertainty`` (see [`mcl.bench.uncertainty`][mcl.bench.uncertainty])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("uncertainty"))
