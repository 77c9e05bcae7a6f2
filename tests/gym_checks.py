"""Gymnasium's ``check_env`` with its known recommendations accounted for, so that a passing check
prints nothing (Gymnasium's warnings carry terminal colour codes) and an unexpected warning fails.

The recommendations our envs do not follow, on purpose: the action box is in physical units
([steer rad, speed m/s], not [-1, 1]), the odometry twist is unbounded (-inf, inf), and our
wrappers (``LocalizationWrapper``) are checked as wrappers, not unwrapped."""

from __future__ import annotations

import gc
import warnings
from typing import Any

from gymnasium.utils.env_checker import check_env

__all__ = ["DESIGN_RECOMMENDATIONS", "check_env_as_designed"]

DESIGN_RECOMMENDATIONS = (
    "we recommend using a symmetric and normalized space",
    "A Box observation space minimum value is -infinity",
    "A Box observation space maximum value is infinity",
    "is different from the unwrapped version",
)
"""Parts of the check's warnings that our spaces draw by design (module doc)."""


def check_env_as_designed(env: Any, **kwargs: Any) -> None:
    """``check_env(env, **kwargs)``; fails on any warning but :data:`DESIGN_RECOMMENDATIONS`.

    Garbage that earlier tests in the same worker left (an event loop never closed, say) is
    collected first, so that its ``ResourceWarning`` is not taken for one of the env's."""
    gc.collect()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, **kwargs)
    unexpected = [
        str(w.message) for w in caught
        if not any(known in str(w.message) for known in DESIGN_RECOMMENDATIONS)
    ]  # fmt: skip
    assert unexpected == [], unexpected
