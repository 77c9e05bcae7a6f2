"""``racecar-sim make-maps``: draw the bundled maps (see :mod:`racecar_sim.maps.draw`)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.maps import draw


def main(argv: Sequence[str] | None = None) -> int:
    """Draw every bundled map into ``--out`` (default: the package's own map folder)."""
    parser = argparse.ArgumentParser(
        prog="racecar-sim make-maps",
        description=(draw.__doc__ or "").split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--out", type=Path, default=draw.bundled_dir(), help="output folder")
    args = parser.parse_args(argv)
    for path in draw.draw_maps(args.out):
        img = cv2.imread(str(path.with_suffix(".png")), cv2.IMREAD_UNCHANGED)
        h, w = img.shape
        area = float(np.count_nonzero(img == draw.FREE)) * draw.RESOLUTION**2
        print(
            f"{path}: {w} x {h} cells = {w * draw.RESOLUTION:.2f} m x "
            f"{h * draw.RESOLUTION:.2f} m, free {area:.1f} m^2"
        )
    return 0
