"""Thin wrapper: ``racecar-sim bench raycast`` (see [`mcl.bench.raycast`][mcl.bench.raycast])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("raycast"))
