"""Occupancy grid maps: the grid and its frames, the ROS map_server loader, the bundled maps."""

from racecar_sim.maps.bundled import DEFAULT_MAP, bundled, bundled_names, resolve_map
from racecar_sim.maps.grid import MapError, OccupancyMap
from racecar_sim.maps.loader import load_map

__all__ = [
    "DEFAULT_MAP",
    "MapError",
    "OccupancyMap",
    "bundled",
    "bundled_names",
    "load_map",
    "resolve_map",
]
