"""Writing an [OccupancyMap][racecar_sim.maps.grid.OccupancyMap] as a ROS map_server map: a YAML
file and a PGM image beside it, readable by [load_map][racecar_sim.maps.loader.load_map] (and by
map_server, amcl, Foxglove). Free cells are written 254, blocked (occupied or unknown: one class
in racecar-sim) 0; ``mode: trinary``, ``negate: 0``, the usual thresholds 0.65 / 0.196.

Nothing is overwritten: both files are created new (``FileExistsError`` naming the one that is
there, before anything is written).
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.maps.grid import OccupancyMap

__all__ = ["save_map"]


def save_map(grid: OccupancyMap, yaml_path: str | os.PathLike[str]) -> Path:
    """Write ``grid`` to ``yaml_path`` (``.yaml``) and its image to the same name with ``.pgm``;
    returns the YAML's path. The origin keeps its yaw (radians).

    Raises:
        ValueError: ``yaml_path`` does not end in ``.yaml``, or ``grid`` is not an OccupancyMap.
        FileExistsError: the YAML or the PGM is already there (nothing is written).
        FileNotFoundError: the folder does not exist.
    """
    if not isinstance(grid, OccupancyMap):
        raise ValueError(f"save_map: grid must be an OccupancyMap, got {type(grid).__name__}")
    yaml_path = Path(yaml_path)
    if yaml_path.suffix != ".yaml":
        raise ValueError(f"save_map: {yaml_path} must end in .yaml")
    pgm_path = yaml_path.with_suffix(".pgm")
    for path in (yaml_path, pgm_path):
        if os.path.lexists(path):
            raise FileExistsError(f"{path} is already there; save_map writes new files only")
    ok, encoded = cv2.imencode(".pgm", np.where(grid.occupied, 0, 254).astype(np.uint8))
    if not ok:
        raise OSError(f"could not encode {pgm_path.name}")
    x, y, yaw = (float(v) for v in grid.origin)
    text = (
        f"image: {pgm_path.name}\n"
        f"resolution: {float(grid.resolution)!r}\n"
        f"origin: [{x!r}, {y!r}, {yaw!r}]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
        "mode: trinary\n"
    )
    with open(pgm_path, "xb") as f:
        f.write(encoded.tobytes())
    try:
        with open(yaml_path, "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        pgm_path.unlink()  # the PGM just made here, not the user's: the YAML appeared meanwhile
        raise
    return yaml_path
