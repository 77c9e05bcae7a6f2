"""Thin wrapper: ``racecar-sim bench soak`` (see [`mcl.bench.soak`][mcl.bench.soak])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("soak"))
