"""racecar_sim: a fast headless 2D racecar simulator on ROS occupancy grid maps."""

from racecar_sim.maps import DEFAULT_MAP, MapError, OccupancyMap, bundled, load_map

__all__ = ["DEFAULT_MAP", "MapError", "OccupancyMap", "bundled", "load_map"]
__version__ = "0.1.0"
