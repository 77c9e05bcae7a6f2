"""Thin wrapper: ``racecar-sim bench sensor_models`` (see [`mcl.bench.sensor_models`][mcl.bench.sensor_models])."""

import sys

from mcl.cli.bench import run_script

if __name__ == "__main__":
    sys.exit(run_script("sensor_models"))
