"""OpenCV drawing of the map, the car, lidar hits, particles and poses into RGB images.

Reads state, never writes it. Images are RGB ``uint8`` arrays (H, W, 3) in the map image's own
orientation (grid frame: row 0 at the top), scaled by ``scale`` pixels per map cell. Pixel
coordinates are OpenCV points ``(x, y)`` = (column, row) of the image.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from racecar_sim.maps import OccupancyMap

__all__ = [
    "CAR_COLOUR",
    "ESTIMATE_COLOUR",
    "FREE_COLOUR",
    "OCCUPIED_COLOUR",
    "PARTICLE_COLOUR",
    "SCAN_COLOUR",
    "CarRendering",
    "MapRenderer",
    "RenderHook",
    "warn_no_render_mode",
]

Colour = tuple[int, int, int]

FREE_COLOUR: Colour = (255, 255, 255)
OCCUPIED_COLOUR: Colour = (60, 60, 60)
CAR_COLOUR: Colour = (220, 30, 30)
SCAN_COLOUR: Colour = (0, 120, 255)
PARTICLE_COLOUR: Colour = (40, 170, 40)
ESTIMATE_COLOUR: Colour = (255, 150, 0)

_MAX_SIZE = 1000  # pixels, default cap of the longer image side
_MAX_SCALE = 2.0  # pixels per cell, default upper limit for small maps
_DOT = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])  # a 2x2 pixel dot for scan hits


def _as_points(xy: np.ndarray, name: str, width: int) -> np.ndarray:
    arr = np.asarray(xy, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] < width:
        raise ValueError(f"{name} must have shape (N, {width}), got {np.shape(xy)}")
    return arr


class MapRenderer:
    """Draws on a scaled copy of an occupancy map.

    Args:
        occupancy_map: the map to draw.
        scale: pixels per map cell. By default the longer side is fitted into ``max_size``
            pixels, with at most 2 pixels per cell for small maps.
        max_size: pixels, cap of the longer image side used when ``scale`` is None.

    Attributes:
        scale: pixels per map cell.
        size: (width, height) of the images in pixels.
    """

    def __init__(
        self, occupancy_map: OccupancyMap, scale: float | None = None, max_size: int = _MAX_SIZE
    ) -> None:
        if scale is None:
            scale = min(_MAX_SCALE, max_size / max(occupancy_map.shape))
        if not (isinstance(scale, int | float) and math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive number of pixels per cell, got {scale!r}")
        self.map = occupancy_map
        self.scale = float(scale)
        width = max(1, round(occupancy_map.width * self.scale))
        height = max(1, round(occupancy_map.height * self.scale))
        self.size = (width, height)
        grey = np.where(occupancy_map.occupied, 0, 255).astype(np.uint8)
        interp = cv2.INTER_AREA if self.scale < 1.0 else cv2.INTER_NEAREST
        grey = cv2.resize(grey, self.size, interpolation=interp).astype(np.float64) / 255.0
        free = np.array(FREE_COLOUR, dtype=np.float64)
        occ = np.array(OCCUPIED_COLOUR, dtype=np.float64)
        base = occ + grey[..., None] * (free - occ)
        self._base = np.ascontiguousarray(np.round(base).astype(np.uint8))
        self._base.setflags(write=False)
        self._px_per_m = self.scale / occupancy_map.resolution
        self._height_px = occupancy_map.height * self.scale  # unrounded, for exact geometry

    # ------------------------------------------------------------------ geometry
    def world_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """World points (…, 2) in metres -> int32 pixel points (…, 2) as (x, y) = (column, row).

        Points off the map give pixels outside the image; drawing helpers skip or clip them.
        """
        uv = self.map.world_to_map(xy)
        px = uv[..., 0] * self._px_per_m
        py = self._height_px - uv[..., 1] * self._px_per_m
        return np.stack([np.floor(px), np.floor(py)], axis=-1).astype(np.int32)

    def base(self) -> np.ndarray:
        """A fresh RGB uint8 (H, W, 3) image of the map alone (free light, occupied dark)."""
        return self._base.copy()

    # ------------------------------------------------------------------ drawing
    def _put_points(self, img: np.ndarray, pixels: np.ndarray, colour: Colour) -> None:
        """Colour the in-image pixels of int (N, 2) (x, y) points."""
        h, w = img.shape[:2]
        keep = (pixels[:, 0] >= 0) & (pixels[:, 0] < w) & (pixels[:, 1] >= 0) & (pixels[:, 1] < h)
        pixels = pixels[keep]
        img[pixels[:, 1], pixels[:, 0]] = colour

    def draw_car(self, img: np.ndarray, footprint: np.ndarray, colour: Colour = CAR_COLOUR) -> None:
        """Fill the car's footprint, (4, 2) world corners in metres, in place."""
        corners = _as_points(footprint, "footprint", 2)
        if corners.shape[0] < 3:
            raise ValueError(f"footprint needs at least 3 corners, got {corners.shape[0]}")
        cv2.fillPoly(img, [self.world_to_pixel(corners[:, :2])], colour, lineType=cv2.LINE_8)

    def draw_scan(
        self,
        img: np.ndarray,
        lidar_pose: np.ndarray,
        ranges: np.ndarray,
        angles: np.ndarray,
        colour: Colour = SCAN_COLOUR,
        max_range: float | None = None,
    ) -> None:
        """Mark the hit points of a scan in place.

        Args:
            img: RGB image to draw on.
            lidar_pose: world pose (3,) of the lidar [x, y, theta] (metres, radians).
            ranges: (M,) metres along each beam.
            angles: (M,) beam angles in the lidar's frame, radians.
            colour: RGB of the hit points.
            max_range: metres; beams at or beyond it (no return) are not drawn when given.
        """
        x, y, theta = np.asarray(lidar_pose, dtype=np.float64).reshape(3)
        r = np.asarray(ranges, dtype=np.float64).reshape(-1)
        a = np.asarray(angles, dtype=np.float64).reshape(-1)
        if r.shape != a.shape:
            raise ValueError(f"ranges {r.shape} and angles {a.shape} must have the same length")
        if max_range is not None:
            hit = r < max_range
            r, a = r[hit], a[hit]
        hits = np.column_stack([x + r * np.cos(theta + a), y + r * np.sin(theta + a)])
        pixels = self.world_to_pixel(hits)
        self._put_points(img, (pixels[:, None, :] + _DOT[None]).reshape(-1, 2), colour)

    def draw_particles(
        self, img: np.ndarray, particles: np.ndarray, colour: Colour = PARTICLE_COLOUR
    ) -> None:
        """Mark particle positions, (N, 3) world poses (or (N, 2) points), one pixel each."""
        pts = _as_points(particles, "particles", 2)
        self._put_points(img, self.world_to_pixel(pts[:, :2]), colour)

    def draw_pose(
        self,
        img: np.ndarray,
        pose: np.ndarray,
        colour: Colour = ESTIMATE_COLOUR,
        length: float = 0.5,
    ) -> None:
        """Draw a pose (3,) world [x, y, theta] as a dot with an arrow ``length`` metres long."""
        x, y, theta = np.asarray(pose, dtype=np.float64).reshape(3)
        tip = (x + length * math.cos(theta), y + length * math.sin(theta))
        p0, p1 = self.world_to_pixel(np.array([[x, y], tip])).tolist()
        radius = max(2, round(0.1 * self._px_per_m))
        cv2.circle(img, tuple(p0), radius, colour, thickness=-1, lineType=cv2.LINE_8)
        cv2.arrowedLine(img, tuple(p0), tuple(p1), colour, thickness=1, tipLength=0.3)


def warn_no_render_mode() -> None:
    """The warning of ``render()`` on an env made without a render mode (a plain warning:
    gym.logger.warn's colour codes end up in logs), pointing at the caller of ``render()``."""
    warnings.warn(
        "render() called without a render_mode; make the env with render_mode='rgb_array'",
        UserWarning,
        stacklevel=3,
    )


RenderHook = Callable[[np.ndarray, MapRenderer], None]
"""``fn(img, renderer) -> None``: draws overlays in place on the RGB frame being rendered."""


class CarRendering:
    """A car env's ``render()``: the map, the last scan's hits, obstacles, the car's footprint,
    then the render hooks; the base of [`RacecarEnv`][racecar_sim.env.RacecarEnv], which sets the
    fields (``map``, ``lidar``, ``physics``, ``obstacles``, the last scan and its pose)."""

    render_mode: str | None
    map: OccupancyMap
    lidar: Any
    lidar_params: Any
    physics: Any
    obstacles: Any
    last_scan: np.ndarray
    last_scan_pose: np.ndarray
    _render_hooks: list[RenderHook]
    _renderer: MapRenderer | None

    def render(self) -> np.ndarray | None:
        """RGB uint8 (H, W, 3) frame: map, last scan's hits, car footprint, then the render hooks.

        Returns None (with a warning) when the env was made without ``render_mode="rgb_array"``.
        """
        if self.render_mode is None:
            warn_no_render_mode()
            return None
        renderer = self.renderer
        img = renderer.base()
        renderer.draw_scan(
            img,
            self.lidar.mount_pose(self.last_scan_pose),
            self.last_scan,
            self.lidar.angles,
            max_range=self.lidar_params.max_range,
        )
        if self.obstacles is not None:
            self.obstacles.draw(img, renderer)
        renderer.draw_car(img, self.physics.footprint())
        for hook in self._render_hooks:
            hook(img, renderer)
        return img

    def close(self) -> None:
        """Release the renderer (the env stays usable)."""
        self._renderer = None

    # ------------------------------------------------------------------ rendering hooks
    @property
    def renderer(self) -> MapRenderer:
        """The `MapRenderer` of this env's map (made on first use)."""
        if self._renderer is None:
            self._renderer = MapRenderer(self.map)
        return self._renderer

    def add_render_hook(self, fn: RenderHook) -> None:
        """Call ``fn(img, renderer)`` at the end of every `render()` to draw overlays."""
        if not callable(fn):
            raise TypeError(f"render hook must be callable fn(img, renderer), got {fn!r}")
        self._render_hooks.append(fn)

    def remove_render_hook(self, fn: RenderHook) -> None:
        """Stop calling a hook added with `add_render_hook()`."""
        self._render_hooks.remove(fn)
