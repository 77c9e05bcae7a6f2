"""``racecar-sim make-maps``: draw the bundled maps (see [`racecar_sim.maps.draw`][racecar_sim.maps.draw])."""

from __future__ import annotations

import importlib
import os
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from mcl.cli.common import Parser, check_out, output_folder, path_arg
from racecar_sim.maps import draw, load_map
from racecar_sim.world.track import LOOP_STARTS, Track, centre_loop

_bundled = importlib.import_module(
    "racecar_sim.maps.bundled"
)  # the module (maps.bundled is a function)

EXAMPLES = """\
examples:
  racecar-sim make-maps                     redraw the bundled maps (in a checkout: its maps/;
                                            installed: into ./maps, never into the package)
  racecar-sim make-maps --out /tmp/maps     draw them elsewhere (e.g. to compare)
"""

INSTALLED_OUT = Path("maps")
"""Where ``make-maps`` draws by default when the package is installed (not a checkout): ``./maps``."""


def default_out() -> tuple[Path, str | None]:
    """The default output folder, and a notice to print when it is not the bundled maps' own
    folder: ``$RACECAR_SIM_MAPS`` when set, else the checkout's ``maps/``
    ([`racecar_sim.maps.bundled.checkout_maps_dir()`][racecar_sim.maps.bundled.checkout_maps_dir]), else, for an installed package, ``./maps``
    in the current directory (the package's own files are left as they are)."""
    if os.environ.get("RACECAR_SIM_MAPS") or _bundled.checkout_maps_dir() is not None:
        return draw.bundled_dir(), None
    return INSTALLED_OUT, (
        "racecar-sim is installed, not run from a source checkout: drawing the maps into "
        f"{INSTALLED_OUT.resolve()} (the installed package's maps stay as they are; --out DIR "
        "draws elsewhere)"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Draw every bundled map into ``--out`` (default: `default_out()`)."""
    parser = Parser("racecar-sim make-maps", (draw.__doc__ or "").split("\n\n")[0], EXAMPLES)
    parser.add_argument(
        "--out",
        type=path_arg,
        default=None,
        metavar="DIR",
        help="output folder (default: the checkout's maps/; installed: ./maps)",
    )
    args = parser.parse_args(argv)
    notice = None
    if args.out is None:
        args.out, notice = default_out()
    out = check_out(parser, args.out, owned=False)
    problem = draw.draw_problem(out)
    if problem is not None:
        parser.fail("--out", problem)
    if notice is not None:
        print(notice)
    with output_folder(parser, out, mark=False):
        for path in draw.draw_maps(out):
            img = cv2.imread(str(path.with_suffix(".png")), cv2.IMREAD_UNCHANGED)
            h, w = img.shape
            area = float(np.count_nonzero(img == draw.FREE)) * draw.RESOLUTION**2
            print(
                f"{path}: {w} x {h} cells = {w * draw.RESOLUTION:.2f} m x "
                f"{h * draw.RESOLUTION:.2f} m, free {area:.1f} m^2"
            )
        for path in write_tracks(out):
            print(f"{path}: {Track.from_csv(path).length:.2f} m")
    return 0


def write_tracks(out: Path) -> list[Path]:
    """The bundled loop maps' tracks, driven on the maps just drawn into ``out``: the wall
    follower's loop (``NAME_loop.csv``) and its centerline (``NAME_centerline.csv``); a file is
    replaced only when the map beside it was drawn here."""
    from mcl.agents.track import drive_loop

    old = os.environ.get("RACECAR_SIM_MAPS")
    os.environ["RACECAR_SIM_MAPS"] = str(out)  # drive on the maps just drawn
    written = []
    try:
        for name in sorted(LOOP_STARTS):
            yaml_path = out / f"{name}.yaml"
            ours = lambda _p, y=yaml_path, n=name: draw.drawn_here(y, n)  # noqa: E731
            loop = drive_loop.__wrapped__(name)
            centerline = centre_loop(load_map(yaml_path), loop.points)
            written.append(loop.to_csv(out / f"{name}_loop.csv", ours))
            written.append(centerline.to_csv(out / f"{name}_centerline.csv", ours))
    finally:
        if old is None:
            os.environ.pop("RACECAR_SIM_MAPS", None)
        else:
            os.environ["RACECAR_SIM_MAPS"] = old
    return written
