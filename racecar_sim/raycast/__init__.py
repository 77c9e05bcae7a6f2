"""Ray casting on occupancy grids: one API (`RayCaster`) for the lidar and for particles.

``caster.py`` holds the API and the in-process cache, ``kernels.py`` the numba per-ray kernels
(exact grid traversal with distance-field jumps, sphere tracing), ``lut.py`` the lookup-table method's
query (its per-beam loops in ``lut_beams.py``, exact fallbacks in ``fallback.py``, threads in
``shared_work.py``), ``lut_table.py`` the table's format, ``lut_build.py`` its build and
``lut_flags.py`` its planar flags.
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
