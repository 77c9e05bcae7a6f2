"""Thin wrapper: ``racecar-sim bench live_hostile`` (see [mcl.bench.live_hostile][mcl.bench.live_hostile])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("live_hostile"))
