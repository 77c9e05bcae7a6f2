"""The ``--filter-map`` flag of ``drive`` and ``experiment``: the map must cover the world
``--map`` ([check_filter_map][mcl.wrappers.checks.check_filter_map]), checked before any run."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mcl.cli.common import Parser

__all__ = ["check_filter_map"]


def check_filter_map(
    parser: Parser, map_spec: str, filter_spec: str, env: Sequence[tuple[str, Any]] = ()
) -> None:
    """Stop naming ``--filter-map`` (exit code 2) when it does not cover the world ``--map``;
    both specs load (``check_map`` passed), with the ``max_map_cells`` of the ``env`` settings."""
    from mcl.wrappers.checks import check_filter_map as check_cover
    from racecar_sim.maps import resolve_map

    cells = dict(env).get("max_map_cells")
    try:
        check_cover("", resolve_map(filter_spec, cells), resolve_map(map_spec, cells))
    except ValueError as exc:
        parser.fail("--filter-map", str(exc))
