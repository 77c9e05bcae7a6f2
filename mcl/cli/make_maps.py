"""``racecar-sim make-maps``: draw the bundled maps (see :mod:`racecar_sim.maps.draw`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from mcl.cli.common import Parser, check_out, output_folder
from racecar_sim.maps import draw

EXAMPLES = """\
examples:
  racecar-sim make-maps                     redraw the bundled maps (in a checkout: its maps/)
  racecar-sim make-maps --out /tmp/maps     draw them elsewhere (e.g. to compare)
"""


def main(argv: Sequence[str] | None = None) -> int:
    """Draw every bundled map into ``--out`` (default: the bundled maps' folder, ``maps/`` in a checkout)."""
    parser = Parser("racecar-sim make-maps", (draw.__doc__ or "").split("\n\n")[0], EXAMPLES)
    parser.add_argument(
        "--out", type=Path, default=draw.bundled_dir(), metavar="DIR", help="output folder"
    )
    args = parser.parse_args(argv)
    out = check_out(parser, args.out)
    with output_folder(parser, out):
        for path in draw.draw_maps(out):
            img = cv2.imread(str(path.with_suffix(".png")), cv2.IMREAD_UNCHANGED)
            h, w = img.shape
            area = float(np.count_nonzero(img == draw.FREE)) * draw.RESOLUTION**2
            print(
                f"{path}: {w} x {h} cells = {w * draw.RESOLUTION:.2f} m x "
                f"{h * draw.RESOLUTION:.2f} m, free {area:.1f} m^2"
            )
    return 0
