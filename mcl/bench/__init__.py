"""Benchmarks behind ``racecar-sim bench`` and ``scripts/bench_*.py``: rates and ratios measured in one run.

Each module has ``main(argv)``. The real Stata basement map and bags are read from ``../shared``
(`shared_dir()`): beside the source checkout the package runs from, or, for an installed
package, beside the current working directory.
"""

import importlib
from pathlib import Path

_bundled = importlib.import_module(
    "racecar_sim.maps.bundled"
)  # the module (maps.bundled is a function)


def checkout_maps_dir() -> Path | None:
    """[`racecar_sim.maps.bundled.checkout_maps_dir()`][racecar_sim.maps.bundled.checkout_maps_dir]: the checkout's maps/, None if installed."""
    return _bundled.checkout_maps_dir()


__all__ = ["SHARED", "STATA", "missing_map", "shared_dir", "stata_map"]


def shared_dir() -> Path:
    """``../shared``: the folder beside the source checkout this package runs from (found by
    [`racecar_sim.maps.bundled.checkout_maps_dir()`][racecar_sim.maps.bundled.checkout_maps_dir]); for a package installed from a wheel,
    beside the current working directory (run the benchmarks from a folder beside ``shared``'s)."""
    maps = checkout_maps_dir()
    top = maps.parent if maps is not None else Path.cwd()
    return top.parent / "shared"


def stata_map() -> Path:
    """The MIT Stata basement map YAML in `shared_dir()` (it may be absent)."""
    return shared_dir() / "maps" / "stata_basement.yaml"


def missing_map(flag: str, path: Path | str) -> str:
    """One line for a benchmark whose map YAML ``path`` (given with ``flag``) is not there."""
    where = "beside the checkout" if checkout_maps_dir() is not None else "beside this folder"
    return (
        f"{flag}: {path} not found (the default is the Stata map in ../shared/maps, {where}); "
        f"give {flag} MAP.yaml"
    )


SHARED = shared_dir()
"""``../shared`` when the benchmarks were imported (see `shared_dir()`)."""
STATA = stata_map()
"""The MIT Stata basement map, when ``../shared`` is present."""
