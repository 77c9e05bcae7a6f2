"""Thin wrapper: beam model vs likelihood field in simulation (see :mod:`mcl.bench.sensor_models`)."""

import sys

from mcl.bench.sensor_models import main

if __name__ == "__main__":
    sys.exit(main())
