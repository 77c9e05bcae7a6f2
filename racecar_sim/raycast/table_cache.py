"""The module-level cache of prepared maps (distance fields, lookup tables) shared by ray casters.

Casters built for the same map content and range share one prepared field or table: the key is a
content hash of the occupancy grid (`digest()`) plus the method's build parameters, so two
[`RayCaster`][racecar_sim.raycast.RayCaster] on the same map (e.g. the filter's and a benchmark's) build
once. Least recently used entries go first once the cache holds more than `CACHE_BYTES`.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from typing import Any

import numpy as np

__all__ = ["CACHE_BYTES", "cached", "clear_cache", "digest"]

CACHE_BYTES = 1_000_000_000
"""Bytes of prepared data (fields, tables) the cache may hold."""

_cache: OrderedDict[tuple, Any] = OrderedDict()
_cache_lock = threading.Lock()


def clear_cache() -> None:
    """Forget every prepared map (frees the tables)."""
    with _cache_lock:
        _cache.clear()


def digest(occupied: np.ndarray) -> str:
    """Content hash of an occupancy grid (shape included)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(repr(occupied.shape).encode())
    h.update(np.ascontiguousarray(occupied, dtype=np.uint8).tobytes())
    return h.hexdigest()


def cached(key: tuple, make, use_cache: bool):
    """The value for ``key`` from the cache, else ``make()`` (stored when ``use_cache``)."""
    if use_cache:
        with _cache_lock:
            if key in _cache:
                _cache.move_to_end(key)
                return _cache[key]
    value = make()
    if use_cache:
        with _cache_lock:
            _cache[key] = value
            _cache.move_to_end(key)
            while len(_cache) > 1 and sum(v.nbytes for v in _cache.values()) > CACHE_BYTES:
                _cache.popitem(last=False)
    return value
