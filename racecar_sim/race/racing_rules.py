"""The numbers of the scripted racing driver's rules: gaps, lanes, giving way (SI units).

[RacingRules][racecar_sim.race.racing_rules.RacingRules] is a validated dataclass (each field's
bound and reason in [RACING_BOUNDS][racecar_sim.race.racing_rules.RACING_BOUNDS]), loadable from a
mapping (YAML): ``RacingRules(**yaml.safe_load(text))``. The rules themselves are in
[RacingDriver][racecar_sim.race.racing_driver.RacingDriver].
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from racecar_sim.settings.bounds import Bound, check

__all__ = ["RACING_BOUNDS", "RacingRules"]

RACING_BOUNDS: dict[str, Bound] = {
    "headway": Bound(0.0, 5.0, "s", "seconds of gap per m/s of the car's speed behind a car in "
                     "its lane; 5 s is a gap of 35 m at top speed"),
    "standstill_gap": Bound(0.0, 5.0, "m", "bumper to bumper when stopped behind a car"),
    "min_gap": Bound(0.0, 2.0, "m", "bumper to bumper below which the car stops"),
    "response": Bound(0.05, 5.0, "s", "time over which a gap error is closed; below 0.05 s it "
                      "outruns the car's acceleration at any step"),
    "side_gap": Bound(0.0, 2.0, "m", "between the sides of two cars side by side"),
    "wall_margin": Bound(0.0, 1.0, "m", "between a car's side and the track's edge"),
    "max_offset": Bound(0.0, 5.0, "m", "the farthest lane from the centerline"),
    "lane_step": Bound(0.01, 1.0, "m", "between the lanes considered; below 1 cm a step weighs "
                       "hundreds of lanes", low_open=False),
    "lateral_speed": Bound(0.05, 5.0, "m/s", "sideways speed of the line followed",),
    "merge_headway": Bound(0.0, 5.0, "s", "a lane change ahead of a car leaves standstill_gap "
                           "plus this times its speed"),
    "yield_range": Bound(0.0, 20.0, "m", "bumper to bumper behind within which the car makes "
                         "room for a car following it"),
    "yield_offset": Bound(0.0, 2.0, "m", "off the centerline while making room"),
    "reverse_speed": Bound(0.0, 2.0, "m/s", "backing off from a car pulled up too close to pull "
                           "out round it (0: never); the car's reverse limit is 2 m/s"),
    "pass_ease": Bound(0.0, 2.0, "m/s", "below its own speed a car drives while a faster one "
                       "passes beside it"),
    "brake": Bound(0.5, 20.0, "m/s^2", "planned braking for room running out and cars ahead"),
    "lookahead": Bound(0.1, 10.0, "m", "pure pursuit's look-ahead along the line"),
    "line_cost": Bound(0.0, 10.0, "m/s per m", "speed given up to drive on the line wanted"),
    "switch_cost": Bound(0.0, 10.0, "m/s per m", "speed a lane change must gain"),
    "horizon": Bound(1.0, 100.0, "m", "track ahead and behind in which cars count; room is "
                     "checked over the pass's length up to this"),
}
"""Field -> its bound (the racing rules' table, as ``racecar_sim.settings.bounds.BOUNDS`` is the env's)."""


@dataclass(frozen=True)
class RacingRules:
    """How the scripted racing driver keeps its distance, passes and gives way.

    Attributes:
        headway: seconds of gap per m/s of the car's own speed behind a car in its lane.
        standstill_gap: metres bumper to bumper when stopped behind a car.
        min_gap: metres bumper to bumper below which the car stops.
        response: seconds over which a gap error is closed.
        side_gap: metres between the sides of two cars side by side.
        wall_margin: metres between a car's side and the track's edge.
        max_offset: metres, the farthest lane from the centerline.
        lane_step: metres between the lanes considered.
        lateral_speed: m/s, sideways speed of the line followed.
        merge_headway: seconds; a lane change ahead of a car leaves ``standstill_gap`` plus
            this times its speed between the car's rear and the other's front.
        yield_range: metres bumper to bumper behind within which the car makes room.
        yield_offset: metres off the centerline while making room.
        reverse_speed: m/s of backing off from a car pulled up closer than ``standstill_gap``
            when it wants to pull out round it (0: never).
        pass_ease: m/s below its own speed a car drives while a faster one passes beside it.
        brake: m/s^2 of planned braking (for room running out and for the last check ahead).
        lookahead: metres of pure pursuit's look-ahead along the line.
        line_cost: m/s of speed given up per metre away from the line wanted.
        switch_cost: m/s of speed a lane change must gain per metre of change.
        horizon: metres of track ahead and behind in which other cars count; the room of a
            pass is checked over its length up to this.
    """

    headway: float = 0.5
    standstill_gap: float = 0.4
    min_gap: float = 0.15
    response: float = 0.5
    side_gap: float = 0.18
    wall_margin: float = 0.12
    max_offset: float = 0.6
    lane_step: float = 0.1
    lateral_speed: float = 0.8
    merge_headway: float = 0.3
    yield_range: float = 2.5
    yield_offset: float = 0.3
    reverse_speed: float = 0.5
    pass_ease: float = 0.3
    brake: float = 3.0
    lookahead: float = 1.0
    line_cost: float = 0.3
    switch_cost: float = 0.1
    horizon: float = 25.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = check("RacingRules", f.name, getattr(self, f.name), table=RACING_BOUNDS)
            object.__setattr__(self, f.name, float(value))
        if self.min_gap > self.standstill_gap:
            raise ValueError(
                f"RacingRules.min_gap = {self.min_gap:g} must not exceed "
                f"standstill_gap = {self.standstill_gap:g}"
            )
