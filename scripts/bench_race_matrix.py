"""Thin wrapper: ``racecar-sim bench race-matrix`` (see [`mcl.bench.race_matrix`][mcl.bench.race_matrix])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("race_matrix"))
