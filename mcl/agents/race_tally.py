"""Count what a race agent did in an episode: overtakes, being overtaken, wall and car contacts.

The counts are read from the race's per-step info of the agent's car (``RacecarRace-v0``'s car 0,
[`racecar_sim.race.env.RaceEnv`][racecar_sim.race.env.RaceEnv]'s keys), so any driver can be scored the same way:

* **overtakes**: the sum over steps of the agent's *rank gains*, ``max(0, rank_before -
  rank_after)``. ``rank`` is the race order by distance along the centerline since the start line,
  unwrapped (`racecar_sim.world.laps`), so passing a car ahead in race order is one overtake,
  lapping a car that is already behind in race order is none, and passing a car that stopped
  (crashed) counts like any other. **overtaken** is the same for rank losses. Their difference is
  the rank gained over the episode (``start_rank - rank``). Two changes in one step (the agent
  passes one car while another passes it) cancel: the count is of net rank changes per step.
* **wall contacts** / **car contacts**: separate contacts, i.e. runs of consecutive steps whose
  ``info["contacts"]`` names ``"wall"`` / any ``"car_<i>"`` (a car pushed along a wall for 40
  steps is one wall contact). ``wall_steps`` / ``car_steps`` count the steps themselves.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

__all__ = ["RaceTally"]


@dataclass
class RaceTally:
    """The running counts of one episode (see the module doc); `begin()` then `update()`
    once per step with the agent's info."""

    start_rank: int = 0
    rank: int = 0
    overtakes: int = 0
    overtaken: int = 0
    wall_contacts: int = 0
    car_contacts: int = 0
    wall_steps: int = 0
    car_steps: int = 0
    _on_wall: bool = False
    _on_car: bool = False

    def begin(self, info: Mapping[str, Any]) -> None:
        """Start an episode from the reset's info (its ``rank``)."""
        for field in fields(self):
            setattr(self, field.name, field.default)
        self.start_rank = self.rank = int(info["rank"])

    def update(self, info: Mapping[str, Any]) -> None:
        """Count one step from its info (``rank`` and ``contacts``)."""
        rank = int(info["rank"])
        self.overtakes += max(0, self.rank - rank)
        self.overtaken += max(0, rank - self.rank)
        self.rank = rank
        contacts = info.get("contacts", ())
        wall = "wall" in contacts
        car = any(str(c).startswith("car_") for c in contacts)
        self.wall_contacts += wall and not self._on_wall
        self.car_contacts += car and not self._on_car
        self.wall_steps += wall
        self.car_steps += car
        self._on_wall, self._on_car = wall, car

    def counts(self) -> dict[str, int]:
        """The counts as a plain dict (no private state)."""
        return {k: int(v) for k, v in asdict(self).items() if not k.startswith("_")}
