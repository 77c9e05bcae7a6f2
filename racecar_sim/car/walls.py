"""The map's walls as pymunk segments: computed once per map, put into a car's space only near it.

Every edge between a free cell and an occupied (or unknown) cell is a wall segment lying exactly on
that cell edge; collinear neighbouring edges are merged (`wall_segments()`). A large map has
thousands of them (Stata basement: 8 912), and making a pymunk shape costs ~10 us of Python, so a
space holding all of them took ~0.1 s per car to build (seconds for a vector env of 32 cars).

`WallTiles` (one per map, shared by every car: `tiles_for()`) buckets the segments into
square tiles of `TILE` metres. `WallLoader` (one per car) keeps in the car's space only
the segments of the block of tiles around the place pymunk is about to look at, and swaps the block
when that place moves into another tile. Shapes are made the first time a car needs them and kept.

The block is always put in in the order of the segments' global index (all of it removed and
re-added on a swap), which is the order in which a space holding all walls received them; pymunk's
spatial hash lists shapes by insertion order, so it visits the walls near the car in the same order
either way, and contacts are solved in the same order.
"""

from __future__ import annotations

import math
import weakref

import numpy as np
import pymunk

from racecar_sim.maps import OccupancyMap

__all__ = ["TILE", "WALL_COLLISION_TYPE", "WallLoader", "WallTiles", "tiles_for", "wall_segments"]

TILE = 4.0
"""Tile edge in metres."""
WALL_COLLISION_TYPE = 2
"""pymunk collision type of the wall segments."""
WALL_FRICTION = 0.2
"""The car scrapes along a wall rather than sticking to it."""


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of True along each row of a bool (R, C) array: (row, first col, end col exclusive)."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    step = np.diff(padded, axis=1)
    rows, starts = np.nonzero(step == 1)
    _, ends = np.nonzero(step == -1)  # row-major order pairs each start with its end
    return rows, starts, ends


def wall_segments(occupancy_map: OccupancyMap) -> np.ndarray:
    """The free/occupied cell edges of a map as world-frame segments.

    Cells beyond the image count as occupied, so the border of the free space at the image edge is
    included. Collinear touching edges are merged.

    Returns:
        float64 (K, 2, 2): segment k runs from ``[k, 0]`` to ``[k, 1]``, world metres.
    """
    occ = np.pad(occupancy_map.occupied, 1, constant_values=True)
    height = occupancy_map.height
    res = occupancy_map.resolution
    # Horizontal edges: index i lies between padded rows i and i+1, the top edge of grid row i, at
    # v = (H - i) * res; padded column j is grid column j - 1.
    rows, c0, c1 = _runs(occ[1:] != occ[:-1])
    v = (height - rows).astype(np.float64) * res
    u0 = (c0 - 1).astype(np.float64) * res
    u1 = (c1 - 1).astype(np.float64) * res
    h_uv = np.stack([np.stack([u0, v], axis=-1), np.stack([u1, v], axis=-1)], axis=1)
    # Vertical edges: index j lies between padded columns j and j+1, the left edge of grid column
    # j, at u = j * res; padded rows [r0, r1) are grid rows r0-1 .. r1-2.
    cols, r0, r1 = _runs((occ[:, 1:] != occ[:, :-1]).T)
    u = cols.astype(np.float64) * res
    v_top = (height - r0 + 1).astype(np.float64) * res
    v_bottom = (height - r1 + 1).astype(np.float64) * res
    v_uv = np.stack([np.stack([u, v_top], axis=-1), np.stack([u, v_bottom], axis=-1)], axis=1)
    uv = np.concatenate([h_uv, v_uv], axis=0)
    return occupancy_map.map_to_world(uv)


class WallTiles:
    """A map's wall segments (world frame) and, per square tile of ``tile`` metres, which touch it.

    A segment belongs to every tile its bounding box overlaps. Read-only once built; shared by
    every car on the map.
    """

    def __init__(self, occupancy_map: OccupancyMap, tile: float = TILE) -> None:
        self.segments = wall_segments(occupancy_map)
        self.segment_list: list[tuple[tuple[float, float], tuple[float, float]]] = [
            (tuple(a), tuple(b)) for a, b in self.segments.tolist()
        ]
        self.tile = float(tile)
        lo = self.segments.min(axis=1) / self.tile
        hi = self.segments.max(axis=1) / self.tile
        i0, j0 = np.floor(lo).astype(np.int64).T
        i1, j1 = np.floor(hi).astype(np.int64).T
        buckets: dict[tuple[int, int], list[int]] = {}
        for k, (a0, b0, a1, b1) in enumerate(zip(i0.tolist(), j0.tolist(), i1.tolist(), j1.tolist(),
                                                 strict=True)):  # fmt: skip
            for i in range(a0, a1 + 1):
                for j in range(b0, b1 + 1):
                    buckets.setdefault((i, j), []).append(k)
        self._tiles = {key: np.array(ids, dtype=np.int64) for key, ids in buckets.items()}
        self._blocks: dict[tuple[int, int, int], np.ndarray] = {}
        self._query_space: pymunk.Space | None = None  # the walls overlap queries have needed
        self._in_query: set[int] = set()

    def __len__(self) -> int:
        return len(self.segment_list)

    def key(self, x: float, y: float) -> tuple[int, int]:
        """The tile holding world point (x, y) (metres)."""
        return math.floor(x / self.tile), math.floor(y / self.tile)

    def block(self, key: tuple[int, int], radius: int) -> np.ndarray:
        """Sorted indices of the segments touching the tiles within ``radius`` tiles of ``key``:
        every wall within ``radius * tile`` metres of any point of tile ``key``."""
        full = (key[0], key[1], radius)
        ids = self._blocks.get(full)
        if ids is None:
            parts = [
                self._tiles[(key[0] + di, key[1] + dj)]
                for di in range(-radius, radius + 1)
                for dj in range(-radius, radius + 1)
                if (key[0] + di, key[1] + dj) in self._tiles
            ]
            ids = np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
            self._blocks[full] = ids
        return ids


    def overlaps(self, shape: pymunk.Shape, x: float, y: float, reach: float) -> bool:
        """Whether ``shape`` (its bounding box cached at its place) touches a wall, every wall
        within ``reach`` metres of world point (x, y) counted.

        The query runs in one pymunk space per map, shared by every car, which keeps the walls
        queries have needed (each made once): a car's own space holds only the walls near where
        it drives, and its start tries add none to it.
        """
        if self._query_space is None:
            self._query_space = pymunk.Space()
        space = self._query_space
        radius = max(1, math.ceil(reach / self.tile))
        new = [k for k in self.block(self.key(x, y), radius).tolist() if k not in self._in_query]
        if new:
            segments = self.segment_list
            space.add(*[pymunk.Segment(space.static_body, *segments[k], 0.0) for k in new])
            self._in_query.update(new)
        return bool(space.shape_query(shape))


_CACHE: dict[int, tuple[weakref.ref, WallTiles]] = {}


def tiles_for(occupancy_map: OccupancyMap) -> WallTiles:
    """The `WallTiles` of a map object, built on first use and shared while it lives."""
    hit = _CACHE.get(id(occupancy_map))
    if hit is not None and hit[0]() is occupancy_map:
        return hit[1]
    tiles = WallTiles(occupancy_map)
    key = id(occupancy_map)
    _CACHE[key] = (weakref.ref(occupancy_map, lambda _ref, k=key: _CACHE.pop(k, None)), tiles)
    return tiles


class WallLoader:
    """Keeps the walls near one place in one car's pymunk space (see the module docstring).

    Args:
        space: the car's space; walls go onto its static body.
        tiles: the map's `WallTiles`.
    """

    def __init__(self, space: pymunk.Space, tiles: WallTiles) -> None:
        self.space = space
        self.tiles = tiles
        self._shapes: dict[int, pymunk.Segment] = {}
        self._loaded: dict[int, pymunk.Segment] = {}  # in insertion order
        self._block: tuple[tuple[int, int], int] | str | None = None

    def _shape(self, k: int) -> pymunk.Segment:
        wall = self._shapes.get(k)
        if wall is None:
            a, b = self.tiles.segment_list[k]
            wall = pymunk.Segment(self.space.static_body, a, b, 0.0)
            wall.collision_type = WALL_COLLISION_TYPE
            wall.friction = WALL_FRICTION
            self._shapes[k] = wall
        return wall

    def _block_ids(self, x: float, y: float, reach: float):
        """(block, its sorted segment indices) of the walls within ``reach`` m of (x, y)."""
        if math.isinf(reach):
            return "all", np.arange(len(self.tiles))
        radius = max(1, math.ceil(reach / self.tiles.tile))
        key = self.tiles.key(x, y)
        return (key, radius), self.tiles.block(key, radius)

    def _holds(self, block) -> bool:
        held = self._block
        if held == "all":
            return True
        return held is not None and block != "all" and held[0] == block[0] and block[1] <= held[1]

    def ensure(self, x: float, y: float, reach: float, keep: bool = False) -> None:
        """Make the space hold every wall within ``reach`` metres of world point (x, y) (all of
        the map's walls, for good, when ``reach`` is infinite).

        When the walls of another block are needed, all walls are taken out and the new block is
        put in in global order; with ``keep`` (the car touches, or lately touched, a wall: pymunk
        keeps that contact's impulses in the walls' arbiters) the walls in the space stay and only
        the missing ones are added.
        """
        block, ids = self._block_ids(x, y, reach)
        if self._holds(block):
            return
        if keep:
            self._add([k for k in ids.tolist() if k not in self._loaded])
        else:
            if self._loaded:
                self.space.remove(*self._loaded.values())
                self._loaded = {}
            self._add(ids.tolist())
        self._block = block

    def add_missing(self, x: float, y: float, reach: float) -> list[int]:
        """Add the walls within ``reach`` m of (x, y) that the space lacks (for a query away from
        the car); returns their indices for `remove()`. The walls already in stay untouched."""
        block, ids = self._block_ids(x, y, reach)
        if self._holds(block):
            return []
        extra = [k for k in ids.tolist() if k not in self._loaded]
        self._add(extra)
        return extra

    def remove(self, ids: list[int]) -> None:
        """Take walls added by `add_missing()` out again."""
        if ids:
            self.space.remove(*[self._loaded.pop(k) for k in ids])

    def _add(self, ids: list[int]) -> None:
        shapes = [self._shape(k) for k in ids]
        if shapes:
            self.space.add(*shapes)
            self._loaded.update(zip(ids, shapes, strict=True))

    @property
    def n_loaded(self) -> int:
        """Walls in the space now."""
        return len(self._loaded)
