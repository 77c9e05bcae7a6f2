"""Thin wrapper: `racecar-sim train-agent` (see [`mcl.cli.train_agent`][mcl.cli.train_agent])."""

import sys

from mcl.cli.train_agent import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
