"""Thin wrapper: ``racecar-sim bench memory`` (see [`mcl.bench.memory`][mcl.bench.memory])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("memory"))
