"""The loop an agent drives: [`racecar_sim.race.track.Track`][racecar_sim.race.track.Track] (the race's track class).

Progress along the loop (the agent's reward and its lap times) is the arc length ``s`` of the
point of the loop nearest the car, in metres from the loop's first point, increasing in the
driving direction. The class and the loop recorder live in the simulator
([`racecar_sim.race.track`][racecar_sim.race.track]), which races use too; this module keeps the agents' import path.
"""

from __future__ import annotations

from racecar_sim.race.loops import track_for_map
from racecar_sim.race.track import LOOP_STARTS, Track

__all__ = ["LOOP_STARTS", "Track", "loop_maps", "track_for_map"]


def loop_maps() -> list[str]:
    """The bundled maps whose loop start is known (`track_for_map()` needs no ``start``)."""
    return sorted(LOOP_STARTS)
