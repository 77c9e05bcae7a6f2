"""Draw the bundled occupancy maps (``maps/*.yaml`` + ``*.png`` at the top of the repository).

Every map is a ROS ``map_server`` pair: an 8-bit grayscale PNG (0 = occupied, 254 = free,
205 = unknown, used for everything outside the building) and a YAML file with the resolution
(metres per cell) and the world pose of the lower-left corner of the image.

The drawing is fully deterministic (no randomness at all): geometry is written by hand in
metres, rasterised at `RESOLUTION` and saved with fixed PNG parameters, so drawing twice gives
byte-identical files.

World frame: the origin of every map is ``[0.0, 0.0, 0.0]``, i.e. world ``(0, 0)`` is the
lower-left corner of the image, x to the right, y up. Cell ``(row, col)`` covers
``x in [col * res, (col + 1) * res)`` and ``y in [(H - 1 - row) * res, (H - row) * res)``.

Maps:

* ``basement_loop`` (default): a ~30 m x 20 m basement hallway loop (hallways 1.9-2.2 m wide)
  with a jog, a 45 degree corner, a rounded corner, door recesses, a lobby with a pillar,
  wall stubs and a 4 m x 4 m side room behind a 1.2 m doorway.
* ``office``: a 20 m x 15 m office with rooms, doors, desks, cabinets, pillars and a
  corridor loop at least 1.5 m wide round a central block of rooms.
* ``corridor``: a plain 40 m x 2 m corridor closed at both ends (ambiguous along its axis).

Command line: ``racecar-sim make-maps [--out DIR]`` (or ``python scripts/make_maps.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.file_guard import NotOurs, replace_problem
from racecar_sim.maps.bundled import maps_dir

RESOLUTION = 0.05  # metres per cell
FREE = 254  # free cell value
UNKNOWN = 205  # unknown cell value (outside the building)
OCCUPIED = 0  # occupied cell value
WALL_THICKNESS = 0.20  # metres, outer wall drawn round all free space
PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 9]  # fixed params -> byte-identical output

Point = tuple[float, float]

# Suggested start poses [x (m), y (m), theta (rad)] in the world frame: the middle of a straight
# hallway of each map's driving loop, heading along the hallway.
START_POSES: dict[str, tuple[float, float, float]] = {
    "basement_loop": (9.0, 2.5, 0.0),  # south hallway, driving east (island on the left)
    "office": (11.5, 6.1, 0.0),  # south corridor of the loop, driving east
    "corridor": (20.5, 1.5, 0.0),  # middle of the corridor, driving along +x
}

# Hallway centre points of basement_loop in the world frame, metres (one per straight or
# diagonal hallway), used by the tests to check hallway widths.
BASEMENT_HALL_CENTRES: dict[str, Point] = {
    "south": (9.0, 2.5),
    "east": (28.8, 9.0),
    "diagonal": (28.1, 17.4),
    "north_east": (23.5, 19.1),
    "north_west": (10.5, 18.5),
    "west_upper": (2.45, 16.0),
    "west_lower": (2.45, 5.5),
}


class MapCanvas:
    """Boolean free / obstacle masks in metres, rendered to a map_server image.

    Args:
        width: image width in metres.
        height: image height in metres.
        offset: ``(x, y)`` in metres added to every coordinate passed to the drawing methods,
            so a building can be designed in its own frame and placed with a margin.
        resolution: metres per cell.
    """

    def __init__(
        self,
        width: float,
        height: float,
        offset: Point = (0.0, 0.0),
        resolution: float = RESOLUTION,
    ) -> None:
        self.res = resolution
        self.cols = round(width / resolution)
        self.rows = round(height / resolution)
        self.offset = offset
        self.free = np.zeros((self.rows, self.cols), dtype=bool)
        self.solid = np.zeros((self.rows, self.cols), dtype=bool)
        self.filled = np.zeros((self.rows, self.cols), dtype=bool)
        # World coordinates (metres) of the cell centres.
        self._xc = (np.arange(self.cols) + 0.5) * resolution
        self._yc = (self.rows - 1 - np.arange(self.rows) + 0.5) * resolution

    # -- masks ---------------------------------------------------------------------------
    def rect_mask(self, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        """Cells whose centre lies in ``[x0, x1) x [y0, y1)`` (metres, design frame)."""
        ox, oy = self.offset
        cols = (self._xc >= x0 + ox) & (self._xc < x1 + ox)
        rows = (self._yc >= y0 + oy) & (self._yc < y1 + oy)
        return rows[:, None] & cols[None, :]

    def poly_mask(self, points: Sequence[Point]) -> np.ndarray:
        """Cells whose centre lies inside a polygon (vertices in metres, design frame).

        Even-odd rule on the cell centres, the same convention as `rect_mask()`, so a
        polygon edge that coincides with a rectangle edge rasterises to the same cell boundary.
        """
        ox, oy = self.offset
        # Centres nudged by a few micrometres so 45-degree edges through cell centres have no
        # ties (ties would be decided by rounding noise and give ragged edges).
        x = self._xc[None, :] + 3e-6
        y = self._yc[:, None] + 7e-6
        inside = np.zeros((self.rows, self.cols), dtype=bool)
        verts = [(px + ox, py + oy) for px, py in points]
        for (xi, yi), (xj, yj) in zip(verts, verts[1:] + verts[:1], strict=True):
            if yi == yj:
                continue
            crosses = (yi > y) != (yj > y)
            x_cross = xi + (y - yi) * (xj - xi) / (yj - yi)
            inside ^= crosses & (x < x_cross)
        return inside

    def disk_mask(self, cx: float, cy: float, radius: float) -> np.ndarray:
        """Cells whose centre is within ``radius`` metres of ``(cx, cy)`` (design frame)."""
        ox, oy = self.offset
        dx = self._xc[None, :] - (cx + ox)
        dy = self._yc[:, None] - (cy + oy)
        return dx * dx + dy * dy <= radius * radius

    # -- drawing -------------------------------------------------------------------------
    def free_rect(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Mark the rectangle ``[x0, x1) x [y0, y1)`` (metres) as free space."""
        self.free |= self.rect_mask(x0, y0, x1, y1)

    def free_poly(self, points: Sequence[Point]) -> None:
        """Mark a polygon (vertices in metres) as free space."""
        self.free |= self.poly_mask(points)

    def block_rect(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Put a solid obstacle (wall, pillar, desk) on ``[x0, x1) x [y0, y1)`` (metres)."""
        self.solid |= self.rect_mask(x0, y0, x1, y1)

    def fill_rect(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Mark ``[x0, x1) x [y0, y1)`` (metres) as building: occupied wherever not free."""
        self.filled |= self.rect_mask(x0, y0, x1, y1)

    # -- output --------------------------------------------------------------------------
    def render(self, wall_thickness: float = WALL_THICKNESS) -> np.ndarray:
        """Return the uint8 map image.

        Free space is ``free`` minus ``solid``; only its largest 4-connected component is kept
        (unreachable pockets become occupied). Every non-free cell within ``wall_thickness``
        metres (Chebyshev) of free space, every solid cell and every non-free cell of the filled
        building footprint is occupied; the rest (outside the building) is unknown.
        """
        free = self.free & ~self.solid
        n, labels, stats, _ = cv2.connectedComponentsWithStats(
            free.astype(np.uint8), connectivity=4
        )
        if n > 1:
            biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
            free = labels == biggest
        k = 2 * round(wall_thickness / self.res) + 1
        near = cv2.dilate(free.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)
        img = np.full((self.rows, self.cols), UNKNOWN, dtype=np.uint8)
        img[near | self.solid | self.filled] = OCCUPIED
        img[free] = FREE
        return img


def draw_basement_loop() -> np.ndarray:
    """Basement hallway loop, about 30.6 m x 20 m including walls, 0.05 m cells.

    Design frame (metres), placed with a 0.5 m offset in the image:

    * south hallway y 1.0-3.0 (2.0 m wide), x 1.0-29.4;
    * east hallway x 27.2-29.4 (2.2 m wide), y 1.0-16.0, joined to the north hallway by a
      45 degree diagonal (about 2.1 m wide);
    * north hallway in two parts with a 0.6 m jog at x ~ 14: east part y 17.6-19.6, west part
      y 17.0-19.0;
    * west hallway x 1.0-2.9 (1.9 m wide) with a rounded outer NW corner and a 3.1 m x 3.5 m
      lobby holding a 0.4 m pillar;
    * inner corners chamfered by 0.5-1.0 m (all different);
    * door recesses 0.5-1.5 m deep, wall stubs, and a 4.2 m x 4.0 m side room off the south
      hallway through a 1.2 m doorway (with a 0.3 m column inside).
    """
    c = MapCanvas(31.5, 21.0, offset=(0.5, 0.5))
    # Hallways.
    c.free_rect(1.0, 1.0, 29.4, 3.0)  # south
    c.free_rect(27.2, 1.0, 29.4, 16.0)  # east
    c.free_rect(14.0, 17.6, 25.0, 19.6)  # north, east part
    c.free_rect(1.0, 17.0, 14.6, 19.0)  # north, west part
    c.free_rect(1.0, 1.0, 2.9, 19.0)  # west
    # NE corner: 45 degree diagonal hallway between the east and north hallways.
    c.free_poly(
        [
            (24.5, 17.6),
            (25.4, 17.6),
            (27.2, 15.8),
            (27.2, 15.0),
            (29.4, 15.0),
            (29.4, 16.6),
            (26.4, 19.6),
            (24.5, 19.6),
        ]
    )
    # Jog in the north hallway, both steps sloped at 45 degrees.
    c.free_poly([(14.6, 17.0), (15.2, 17.6), (14.6, 17.6)])
    c.free_poly([(13.4, 19.0), (14.0, 19.6), (14.0, 19.0)])
    # Inner corner chamfers (island corners), each a different size.
    c.free_poly([(2.9, 3.0), (3.4, 3.0), (2.9, 3.5)])  # SW, 0.5 m
    c.free_poly([(26.2, 3.0), (27.2, 3.0), (27.2, 4.0)])  # SE, 1.0 m
    c.free_poly([(2.9, 16.2), (2.9, 17.0), (3.7, 17.0)])  # NW, 0.8 m
    # NW outer corner rounded (radius 1.2 m), SW and SE outer corners stay square.
    corner = c.rect_mask(1.0, 17.8, 2.2, 19.0) & ~c.disk_mask(2.2, 17.8, 1.2)
    c.free &= ~corner
    # West lobby with a free-standing pillar.
    c.free_rect(2.9, 8.0, 6.0, 11.5)
    c.block_rect(4.0, 9.55, 4.4, 9.95)
    # Side room (4.2 m x 4.0 m) behind the south hallway's inner wall, 1.2 m doorway.
    c.free_rect(10.0, 3.2, 14.2, 7.2)
    c.free_rect(11.2, 3.0, 12.4, 3.2)
    c.block_rect(12.9, 5.8, 13.2, 6.1)
    # Door recesses / alcoves (depth in metres in the comments).
    c.free_rect(5.0, 0.5, 6.2, 1.0)  # south hallway, outer side, 0.5
    c.free_rect(19.0, 0.0, 20.5, 1.0)  # south hallway, outer side, 1.0
    c.free_rect(29.4, 6.0, 30.2, 7.2)  # east hallway, outer side, 0.8
    c.free_rect(26.0, 10.0, 27.2, 11.0)  # east hallway, inner side, 1.2
    c.free_rect(7.0, 19.0, 8.2, 19.6)  # north hallway (west part), outer side, 0.6
    c.free_rect(18.0, 16.1, 19.5, 17.6)  # north hallway (east part), inner side, 1.5
    c.free_rect(0.4, 13.0, 1.0, 14.0)  # west hallway, outer side, 0.6
    # Wall stubs (pilasters) sticking out of the walls.
    c.block_rect(16.0, 2.8, 16.3, 3.0)  # south hallway inner wall, 0.2 m
    c.block_rect(29.05, 12.0, 29.4, 12.3)  # east hallway outer wall, 0.35 m
    c.block_rect(21.5, 17.6, 21.8, 17.85)  # north hallway inner wall, 0.25 m
    return c.render()


def draw_office() -> np.ndarray:
    """Cluttered office, 20 m x 15 m inside the outer walls, 0.05 m cells.

    Design frame (metres), placed with a 0.5 m offset in the image:

    * three offices along the south wall (y 0-4.4), joined to each other and to the corridor
      by doors 1.0-1.2 m wide, with desks and cabinets;
    * a corridor loop at least 1.6 m wide: south corridor y 4.6-6.6, west leg x 0-2.0, north
      corridor y 13.0-15.0 (a printer cabinet narrows it to 1.6 m), east aisle x 14.0-16.0 of an
      open-plan area with desk clusters and two pillars;
    * a central block x 2.0-14.0, y 6.6-13.0 holding a meeting room (big table) and a kitchen
      (counter, fridge, table), joined by a door and opening onto the loop by three doors.
    """
    c = MapCanvas(21.0, 16.0, offset=(0.5, 0.5))
    c.fill_rect(-WALL_THICKNESS, -WALL_THICKNESS, 20.0 + WALL_THICKNESS, 15.0 + WALL_THICKNESS)
    c.free_rect(0.0, 0.0, 20.0, 15.0)

    # South offices: wall along y 4.4-4.6 with three doors, two dividers.
    c.block_rect(0.0, 4.4, 2.0, 4.6)
    c.block_rect(3.0, 4.4, 8.0, 4.6)  # door of office A: x 2.0-3.0
    c.block_rect(9.2, 4.4, 15.0, 4.6)  # door of office B: x 8.0-9.2
    c.block_rect(16.2, 4.4, 20.0, 4.6)  # door of office C: x 15.0-16.2
    c.block_rect(6.0, 0.0, 6.2, 1.5)  # divider A|B, door y 1.5-2.5
    c.block_rect(6.0, 2.5, 6.2, 4.4)
    c.block_rect(12.6, 0.0, 12.8, 4.4)  # divider B|C, no door
    # Office A furniture.
    c.block_rect(0.5, 0.0, 2.1, 0.8)  # desk
    c.block_rect(3.5, 0.0, 5.1, 0.8)  # desk
    c.block_rect(0.0, 3.0, 0.5, 4.0)  # cabinet
    # Office B furniture.
    c.block_rect(10.6, 0.0, 12.6, 0.8)  # desk
    c.block_rect(11.8, 0.8, 12.6, 2.0)  # desk return (L-shape)
    c.block_rect(6.2, 3.0, 6.6, 4.4)  # bookshelf
    # Office C furniture.
    c.block_rect(14.0, 1.6, 16.0, 2.4)  # free-standing desk
    c.block_rect(17.5, 0.0, 20.0, 0.8)  # desk
    c.block_rect(19.4, 2.0, 20.0, 4.0)  # cabinet
    c.block_rect(13.4, 3.4, 13.8, 3.8)  # pillar

    # Central block x 2.0-14.0, y 6.6-13.0: perimeter walls 0.2 m with doors.
    c.block_rect(2.0, 6.6, 4.0, 6.8)  # south wall, meeting-room door x 4.0-5.2
    c.block_rect(5.2, 6.6, 14.0, 6.8)
    c.block_rect(2.0, 12.8, 10.0, 13.0)  # north wall, kitchen door x 10.0-11.2
    c.block_rect(11.2, 12.8, 14.0, 13.0)
    c.block_rect(2.0, 6.6, 2.2, 13.0)  # west wall
    c.block_rect(13.8, 6.6, 14.0, 7.4)  # east wall, kitchen door y 7.4-8.6
    c.block_rect(13.8, 8.6, 14.0, 13.0)
    c.block_rect(8.0, 6.6, 8.2, 9.0)  # divider, door y 9.0-10.2
    c.block_rect(8.0, 10.2, 8.2, 13.0)
    # Meeting room furniture.
    c.block_rect(3.8, 8.8, 6.4, 10.8)  # table
    c.block_rect(2.2, 12.3, 3.6, 12.8)  # sideboard
    # Kitchen furniture.
    c.block_rect(11.6, 12.2, 13.8, 12.8)  # counter
    c.block_rect(13.2, 10.0, 13.8, 11.2)  # fridge
    c.block_rect(9.8, 8.8, 12.0, 10.2)  # table

    # Corridor furniture (keeps the loop >= 1.6 m wide).
    c.block_rect(6.0, 14.6, 7.2, 15.0)  # printer cabinet, north corridor
    # Open-plan area x 14.0-20.0, y 4.6-15.0; aisle x 14.0-16.0 kept clear.
    c.block_rect(16.4, 7.6, 16.8, 8.0)  # pillar
    c.block_rect(16.4, 11.4, 16.8, 11.8)  # pillar
    c.block_rect(17.4, 7.2, 19.0, 8.6)  # desk cluster
    c.block_rect(17.4, 10.0, 19.0, 11.4)  # desk cluster
    c.block_rect(16.5, 14.5, 19.5, 15.0)  # cabinets along the north wall
    c.block_rect(19.6, 12.0, 20.0, 13.6)  # cabinet along the east wall
    return c.render()


def draw_corridor() -> np.ndarray:
    """Featureless straight corridor, 40 m x 2 m, closed at both ends, 0.05 m cells.

    Free space x 0.5-40.5 m, y 0.5-2.5 m in the world frame; plain parallel walls 0.2 m thick.
    """
    c = MapCanvas(41.0, 3.0, offset=(0.5, 0.5))
    c.free_rect(0.0, 0.0, 40.0, 2.0)
    return c.render()


MAPS: dict[str, Callable[[], np.ndarray]] = {
    "basement_loop": draw_basement_loop,
    "office": draw_office,
    "corridor": draw_corridor,
}


def map_yaml(name: str, resolution: float = RESOLUTION, origin: Point = (0.0, 0.0)) -> str:
    """ROS map_server YAML text for ``<name>.png``; ``origin`` in metres, yaw 0."""
    return (
        f"image: {name}.png\n"
        f"resolution: {resolution}\n"
        f"origin: [{origin[0]:.1f}, {origin[1]:.1f}, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
        "mode: trinary\n"
    )


def drawn_here(yaml_path: Path, name: str) -> bool:
    """Whether ``yaml_path`` is the YAML [draw_maps][racecar_sim.maps.draw.draw_maps] writes for
    map ``name`` (its exact text)."""
    text = map_yaml(name).encode()
    with open(yaml_path, "rb") as f:
        return f.read(len(text) + 1) == text


def draw_problem(out_dir: Path) -> str | None:
    """Why [draw_maps][racecar_sim.maps.draw.draw_maps] may not write into ``out_dir`` (None: it
    may): a ``<name>.yaml`` or ``<name>.png`` of a bundled map is there and was not drawn here. A
    YAML is ours when its text is exactly [map_yaml][racecar_sim.maps.draw.map_yaml]'s; a PNG when
    the YAML beside it is ours (or the folder is racecar-sim's,
    [file_guard][racecar_sim.file_guard])."""
    for name in MAPS:
        yaml_path = Path(out_dir) / f"{name}.yaml"
        for path in (yaml_path, yaml_path.with_suffix(".png")):
            problem = replace_problem(path, lambda _p, y=yaml_path, n=name: drawn_here(y, n))
            if problem is not None:
                return problem
    return None


def draw_maps(out_dir: Path) -> list[Path]:
    """Draw every map into ``out_dir`` (created if needed) and return the YAML paths.

    Raises:
        FileExistsError: a map file there was not drawn here
            ([draw_problem][racecar_sim.maps.draw.draw_problem]); checked for every map before
            any is written ([NotOurs][racecar_sim.file_guard.NotOurs]).
    """
    out_dir = Path(out_dir)
    problem = draw_problem(out_dir)
    if problem is not None:
        raise NotOurs(problem)
    out_dir.mkdir(parents=True, exist_ok=True)
    yamls: list[Path] = []
    for name, draw in MAPS.items():
        img = draw()
        png = out_dir / f"{name}.png"
        if not cv2.imwrite(str(png), img, PNG_PARAMS):
            raise OSError(f"could not write {png}")
        yaml_path = out_dir / f"{name}.yaml"
        yaml_path.write_text(map_yaml(name), encoding="utf-8")
        yamls.append(yaml_path)
    return yamls


def bundled_dir() -> Path:
    """Where `draw_maps()` writes by default: the bundled maps' folder
    ([`racecar_sim.maps.bundled.maps_dir()`][racecar_sim.maps.bundled.maps_dir]; in a checkout, its top-level ``maps/``)."""
    return maps_dir()
