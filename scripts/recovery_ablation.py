"""Thin wrapper: `racecar-sim recovery-ablation` (see [`mcl.cli.recovery_ablation`][mcl.cli.recovery_ablation])."""

import sys

from mcl.cli.recovery_ablation import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
