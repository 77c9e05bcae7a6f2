"""How one map differs from another of the same place, cell by cell, and a map edited by it.

For measuring which differences between a filter's out-of-date map and the world cost the filter
the car: ``map_changes(old, new)`` finds, in ``old``'s grid, the cells ``new`` has opened (blocked
in ``old``, free in ``new``: a wall taken down, a recess, a corridor rebuilt wider) and the cells
it has closed (free in ``old``, blocked in ``new``: a new wall, a room shut off);
``with_cells(old, cells, free)`` is ``old`` with those cells set free or blocked. The two maps may
have any origins and resolutions: each cell of ``old`` is compared with the cell of ``new`` under
its centre (world frame); cells of ``old`` whose centre falls outside ``new``'s image are left as
they are (``new`` says nothing about them).

Blocked means occupied or unknown, as everywhere in racecar-sim (unknown cells stop the lidar and
the car).
"""

from __future__ import annotations

import numpy as np

from racecar_sim.maps.grid import OccupancyMap

__all__ = ["map_changes", "with_cells"]


def map_changes(old: OccupancyMap, new: OccupancyMap) -> tuple[np.ndarray, np.ndarray]:
    """The cells of ``old`` that ``new`` has opened and closed, as ``(opened, closed)``: bool
    arrays of ``old``'s shape (grid frame, row 0 = the image's top row). ``opened`` where ``old``
    is blocked and the cell of ``new`` under the cell's centre is free; ``closed`` where ``old``
    is free and that cell of ``new`` is blocked. Cells whose centre lies outside ``new``'s image
    are in neither.

    Args:
        old: the map whose grid the masks are in (e.g. the filter's map).
        new: the map of the same place as it is now (e.g. the world's), in the same world frame.

    Raises:
        ValueError: ``old`` or ``new`` is not an OccupancyMap.
    """
    for name, grid in (("old", old), ("new", new)):
        if not isinstance(grid, OccupancyMap):
            raise ValueError(f"map_changes: {name} must be an OccupancyMap, got {type(grid).__name__}")
    rows, cols = np.indices(old.shape)
    centres = old.grid_to_world(np.stack([rows, cols], axis=-1))
    inside = new.in_bounds(new.world_to_grid(centres))
    new_free = new.is_free(centres)  # False outside new's image
    opened = old.occupied & new_free
    closed = ~old.occupied & inside & ~new_free
    return opened, closed


def with_cells(
    old: OccupancyMap, cells: np.ndarray, free: bool, name: str | None = None
) -> OccupancyMap:
    """``old`` with ``cells`` (a bool mask of its shape, grid frame) set free (``free=True``) or
    blocked; its geometry (resolution, origin) unchanged. ``name`` defaults to ``old``'s name
    with ``+opened`` or ``+closed``.

    Raises:
        ValueError: ``cells`` is not a bool array of ``old``'s shape.
    """
    cells = np.asarray(cells)
    if cells.dtype != np.bool_ or cells.shape != old.shape:
        raise ValueError(
            f"cells must be a bool mask of the map's shape {old.shape}, got {cells.dtype} "
            f"{cells.shape}"
        )
    occupied = old.occupied.copy()
    occupied[cells] = not free
    label = name if name is not None else f"{old.name}+{'opened' if free else 'closed'}"
    return OccupancyMap(occupied, old.resolution, old.origin, name=label)
