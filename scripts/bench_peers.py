"""Thin wrapper: ``racecar-sim bench peers`` (see [`mcl.bench.peers`][mcl.bench.peers])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("peers"))
