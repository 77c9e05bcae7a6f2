"""Thin wrapper: ``racecar-sim bench executors`` (see [`mcl.bench.executors`][mcl.bench.executors])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("executors"))
