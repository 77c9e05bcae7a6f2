"""Named scenes: what the room puts in front of (and behind) the map's walls, as geometry the
filter's map does not have ([`racecar_sim.world.obstacle_params.ObstacleParams`][racecar_sim.world.obstacle_params.ObstacleParams] settings).

* ``"none"``: the map and nothing else (the ideal world; also what ``scene=None`` means).
* ``"clean"``: a clean corridor, like the clean stretches of the shared recordings: no people and
  little furniture, but openings in the mapped walls (glass, open doors, walls set back from
  where the map draws them) at the rate those stretches show them.
* ``"cluttered"``: bag 2's corridor: the same openings, furniture against the walls and people
  about.

The numbers are measured on the shared bags (``mcl.calibration.room_stats``; the docs page
"Honest noise"): the fraction of beams on a mapped wall that belong to wide runs of long returns
(openings) or of short returns (furniture, people), and the sizes of those runs. A scene's
obstacles are placed per reset from the env's seed ([`racecar_sim.world.obstacles`][racecar_sim.world.obstacles]).
"""

from __future__ import annotations

from typing import Any

__all__ = ["SCENES", "scene_obstacles"]

_OPENINGS = {"openings": 0.07, "opening_width": (0.6, 1.6), "opening_depth": 0.39}

SCENES: dict[str, dict[str, Any]] = {
    "none": {},
    "clean": {**_OPENINGS, "furniture": 0.005},
    "cluttered": {
        **_OPENINGS,
        "furniture": 0.09,
        "furniture_width": (0.4, 1.6),
        "furniture_depth": (0.3, 0.8),
        "crowd": 1.5,
    },
}
"""Scene name -> obstacle settings (fields of [`racecar_sim.world.obstacle_params.ObstacleParams`][racecar_sim.world.obstacle_params.ObstacleParams])."""


def scene_obstacles(scene: str | None, obstacles: Any) -> Any:
    """The ``obstacles`` setting of an env with ``scene``: the scene's obstacle settings under the
    explicit ``obstacles`` (None, a mapping or an ObstacleParams, which then wins whole).

    Raises:
        ValueError: an unknown scene name (lists the known ones).
    """
    if scene is None:
        return obstacles
    if not isinstance(scene, str) or scene not in SCENES:
        raise ValueError(f"scene must be one of {sorted(SCENES)}, got {scene!r}")
    base = SCENES[scene]
    if not base or obstacles is None:
        return dict(base) if base else obstacles
    if isinstance(obstacles, dict):
        return {**base, **obstacles}
    return obstacles
