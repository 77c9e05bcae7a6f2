"""Thin wrapper: ``racecar-sim bench live`` (see [`mcl.bench.live`][mcl.bench.live])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("live"))
