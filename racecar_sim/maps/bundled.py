"""The maps shipped with the package (package data in ``racecar_sim/maps/data``), found by name."""

from __future__ import annotations

import os
from pathlib import Path

from racecar_sim.maps.grid import MapError, OccupancyMap
from racecar_sim.maps.loader import load_map

__all__ = ["DEFAULT_MAP", "bundled", "bundled_names", "resolve_map"]

DEFAULT_MAP = "basement_loop"
"""Name of the bundled map used when none is given."""

def _bundled_dir() -> Path:
    env = os.environ.get("RACECAR_SIM_MAPS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent / "data"


def bundled_names() -> list[str]:
    """Names of the maps shipped in the package's ``racecar_sim/maps/data`` folder (sorted)."""
    folder = _bundled_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.yaml"))


def bundled(name: str = DEFAULT_MAP) -> Path:
    """Path of a bundled map's YAML by name (e.g. ``"basement_loop"``).

    Raises:
        MapError: no bundled map has that name; the message lists the ones there are.
    """
    path = _bundled_dir() / f"{name}.yaml"
    if not path.is_file():
        raise MapError(f"no bundled map named {name!r}; bundled maps: {', '.join(bundled_names())}")
    return path


def resolve_map(spec: str | os.PathLike[str] | OccupancyMap | None) -> OccupancyMap:
    """A map from a bundled name, a YAML path, an :class:`OccupancyMap`, or None (the default)."""
    if isinstance(spec, OccupancyMap):
        return spec
    if spec is None:
        return load_map(bundled(DEFAULT_MAP))
    text = os.fspath(spec)
    if text.endswith((".yaml", ".yml")) or os.sep in text or Path(text).is_file():
        return load_map(text)
    return load_map(bundled(text))
