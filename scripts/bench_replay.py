"""Thin wrapper: ``racecar-sim bench replay`` (see :mod:`mcl.bench.replay`)."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("replay"))
