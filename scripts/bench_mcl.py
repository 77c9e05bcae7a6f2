"""Thin wrapper: ``racecar-sim bench mcl`` (see [`mcl.bench.mcl`][mcl.bench.mcl])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("mcl"))
