"""Thin wrapper: the peers benchmark (see :mod:`mcl.bench.peers`)."""

import sys

from mcl.bench.peers import main

if __name__ == "__main__":
    sys.exit(main())
