"""Thin wrapper: `racecar-sim train-agent` (see :mod:`mcl.cli.train_agent`)."""

import sys

from mcl.cli.train_agent import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
