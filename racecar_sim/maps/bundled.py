"""The bundled maps, found by name.

They live in the repository's top-level ``maps/`` folder (drawn by ``racecar-sim make-maps``); a
wheel carries them as package data in ``racecar_sim/maps/data`` (``setup.py`` copies them there at
build time). `maps_dir()` is the one place that decides which folder holds them.
"""

from __future__ import annotations

import os
from pathlib import Path

from racecar_sim.maps.grid import MapError, OccupancyMap
from racecar_sim.maps.limits import check_cells
from racecar_sim.maps.loader import load_map
from racecar_sim.settings.validation import short

__all__ = ["DEFAULT_MAP", "bundled", "bundled_names", "maps_dir", "resolve_map"]

DEFAULT_MAP = "basement_loop"
"""Name of the bundled map used when none is given."""


def checkout_maps_dir() -> Path | None:
    """The top-level ``maps/`` folder of the source checkout this package runs from (a clone, or
    an editable install of one), or None when the package is installed from a wheel."""
    top = Path(__file__).resolve().parents[2]
    if (top / "pyproject.toml").is_file() and (top / "maps").is_dir():
        return top / "maps"
    return None


def maps_dir() -> Path:
    """The folder holding the bundled maps (``NAME.yaml`` + ``NAME.png``).

    ``$RACECAR_SIM_MAPS`` when set; else the checkout's top-level ``maps/`` when the package runs
    from a source checkout (`checkout_maps_dir()`); else the package data an installed wheel
    carries, ``racecar_sim/maps/data``.
    """
    env = os.environ.get("RACECAR_SIM_MAPS")
    if env:
        return Path(env)
    checkout = checkout_maps_dir()
    if checkout is not None:
        return checkout
    return Path(__file__).resolve().parent / "data"


def bundled_names() -> list[str]:
    """Names of the bundled maps in `maps_dir()` (sorted)."""
    folder = maps_dir()
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.yaml"))


def bundled(name: str = DEFAULT_MAP) -> Path:
    """Path of a bundled map's YAML by name (e.g. ``"basement_loop"``).

    Raises:
        MapError: no bundled map has that name; the message lists the ones there are.
    """
    path = maps_dir() / f"{name}.yaml"
    if not path.is_file():
        raise MapError(f"no bundled map named {short(name)}; bundled maps: {', '.join(bundled_names())}")
    return path


def resolve_map(
    spec: str | os.PathLike[str] | OccupancyMap | None, max_cells: int | None = None
) -> OccupancyMap:
    """A map from a bundled name, a YAML path, an `OccupancyMap`, or None (the default).

    Raises:
        MapError: the map cannot be loaded, or has more cells than ``max_cells`` (None: the
            default limit, `racecar_sim.maps.limits.max_map_cells()`).
    """
    if isinstance(spec, OccupancyMap):
        check_cells(f"map {spec.name!r}", spec.width, spec.height, max_cells)
        return spec
    if spec is None:
        return load_map(bundled(DEFAULT_MAP), max_cells)
    if not isinstance(spec, str | os.PathLike):
        raise MapError(f"map must be a bundled name, a YAML path or an OccupancyMap, got {short(spec)}")
    text = os.fspath(spec)
    try:
        if text.endswith((".yaml", ".yml")) or os.sep in text or Path(text).is_file():
            return load_map(text, max_cells)
        return load_map(bundled(text), max_cells)
    except OSError as exc:  # a name too long for a path, a folder given as the image, ...
        raise MapError(f"map {short(text)}: {exc.strerror or exc}") from None
