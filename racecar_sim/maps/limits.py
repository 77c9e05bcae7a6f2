"""The limits on a map, checked before anything of its size is allocated.

A map's memory grows with its cell count: the image while it is read, the occupancy grid, the
distance field, the wall segments, the casters' tables. `MAX_MAP_CELLS` (4 million cells,
e.g. 2000 x 2000, a 100 m square at 5 cm) keeps a map, an env on it and a particle filter's
lookup table within a few GB (docs/settings.md has the measured memory); the largest real map in
the project's shared data has 2.25 million. Raise it per env with the setting ``max_map_cells``
(``RacecarEnv(max_map_cells=...)``, ``--env max_map_cells=...``) or for every command with the
environment variable ``RACECAR_SIM_MAX_MAP_CELLS``.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from racecar_sim.maps.grid import MapError

__all__ = [
    "MAX_MAP_CELLS",
    "MAX_ORIGIN",
    "MAX_RESOLUTION",
    "MIN_RESOLUTION",
    "check_cells",
    "image_size",
    "max_map_cells",
]

MAX_MAP_CELLS = 4_000_000
"""Default limit on a map's cells (width x height)."""
MIN_RESOLUTION = 1e-3
"""metres per cell: a millimetre cell is finer than any lidar measures."""
MAX_RESOLUTION = 1.0
"""metres per cell: a metre cell is coarser than the car (0.55 m long); the walls would be wrong."""
MAX_ORIGIN = 1e6
"""metres: a map origin's x and y (1000 km; UTM-sized numbers keep millimetre precision)."""
_ENV_VAR = "RACECAR_SIM_MAX_MAP_CELLS"


def max_map_cells() -> int:
    """The default cell limit: ``RACECAR_SIM_MAX_MAP_CELLS`` when set, else `MAX_MAP_CELLS`.

    Raises:
        MapError: the variable is set but not a positive whole number.
    """
    text = os.environ.get(_ENV_VAR)
    if not text:
        return MAX_MAP_CELLS
    try:
        value = int(float(text))
    except ValueError:
        value = 0
    if value < 1:
        raise MapError(f"{_ENV_VAR} = {text[:40]!r} must be a positive whole number of cells")
    return value


def check_cells(what: str, width: int, height: int, max_cells: int | None = None) -> None:
    """Refuse a ``width`` x ``height`` grid with more cells than ``max_cells`` (None: the default).

    Raises:
        MapError: one line naming the size, the limit and how to raise it.
    """
    limit = max_map_cells() if max_cells is None else int(max_cells)
    cells = int(width) * int(height)
    if cells > limit:
        raise MapError(
            f"{what} is {width} x {height} = {cells:,} cells, more than the limit of {limit:,} "
            f"(setting max_map_cells, e.g. --env max_map_cells={cells}, or {_ENV_VAR})"
        )


def _png_size(head: bytes) -> tuple[int, int] | None:
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    return None


def _pnm_size(head: bytes) -> tuple[int, int] | None:
    """Width and height of a PGM / PPM / PBM (P1-P6) header; comments (``#``) are skipped."""
    if len(head) < 2 or head[0:1] != b"P" or head[1:2] not in b"123456":
        return None
    numbers: list[int] = []
    for line in head[2:].split(b"\n"):
        for word in line.split(b"#", 1)[0].split():
            if not word.isdigit():
                return None
            numbers.append(int(word))
            if len(numbers) == 2:
                return numbers[0], numbers[1]
    return None


def image_size(path: Path) -> tuple[int, int] | None:
    """(width, height) in pixels from an image file's header, without decoding it (PNG and PGM /
    PPM read here, other formats by Pillow's header reader); None when the header cannot be read
    (the decoder then says what is wrong).

    Raises:
        MapError: Pillow refuses the header as a decompression bomb (beyond any limit here).
    """
    with open(path, "rb") as f:
        head = f.read(4096)
    size = _png_size(head) or _pnm_size(head)
    if size is not None:
        return size
    from PIL import Image

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pillow's DecompressionBombWarning: we check ourselves
        try:
            with Image.open(path) as img:
                return int(img.size[0]), int(img.size[1])
        except Image.DecompressionBombError:
            raise MapError(
                f"image {path}: more than {2 * Image.MAX_IMAGE_PIXELS:,} pixels, too many to read"
            ) from None
        except Exception:
            return None
