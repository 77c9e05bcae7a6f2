"""Ray casting on occupancy grids: one API (:class:`RayCaster`) for the lidar and for particles.

``caster.py`` holds the API and the in-process cache, ``kernels.py`` the numba per-ray kernels
(exact grid traversal with distance-field jumps, sphere tracing), ``lut.py`` the lookup-table method's
query and ``lut_build.py`` its table.
"""

from racecar_sim.raycast.caster import (
    CACHE_BYTES,
    METHODS,
    LutParams,
    MarchParams,
    RayCaster,
    clear_cache,
)

__all__ = ["CACHE_BYTES", "METHODS", "LutParams", "MarchParams", "RayCaster", "clear_cache"]
