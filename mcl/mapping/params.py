"""Settings of the map update ([`mcl.mapping.update`][mcl.mapping.update]): which returns count
as seen through a wall of the map, and how many scans and drives must agree before a cell opens.

Units: metres, cells, counts of scans and drives.
"""

from __future__ import annotations

from dataclasses import dataclass

from racecar_sim.settings.validation import check_number

__all__ = ["MapUpdateParams"]


@dataclass(frozen=True)
class MapUpdateParams:
    """When a cell the map draws as wall is opened by the drives' scans.

    A beam *sees through* the map when its return lies more than ``margin`` beyond the first
    blocked cell on its way (cast in the old map from the drive's pose) and, if it ends in a
    blocked cell, ends at least ``min_depth`` inside the map's walls (a wall still standing,
    seen from a pose a few centimetres off, ends near its face). The blocked cells it crossed,
    up to ``end_margin`` before its return, are *passed*.

    Attributes:
        margin: metres a return must lie beyond the map's first wall to count.
        min_depth: metres inside the map's walls (from their nearest free cell) a return that
            ends in a blocked cell must end.
        end_margin: metres before the return where the passed cells stop.
        reach: metres; longer returns are not used (a heading error of 0.02 rad moves a return
            at 5 m by 0.1 m).
        smooth: metres; a return is used only when both neighbouring beams return within this
            of it (the edges of a run of returns mix two surfaces).
        scans_needed: scans of one drive that must pass a cell for that drive to vote for it.
        drives_needed: drives that must vote for a cell before it opens: the openings of one
            drive (an open door, a person's gap, a pose error) are not the map's.
        pass_ratio: a cell opens only where it was passed at least this many times as often as
            a return ended in it (returns end on what stands).
        close_cells: width in cells of the square that closes the opened set (a morphological
            closing, kept to the map's blocked cells), and the opened set then takes the wall
            cells between it and the map's free space: a recess opened all but its face is not
            seen at all (0: neither).
    """

    margin: float = 0.25
    min_depth: float = 0.25
    end_margin: float = 0.1
    reach: float = 5.0
    smooth: float = 0.1
    scans_needed: int = 3
    drives_needed: int = 6
    pass_ratio: float = 3.0
    close_cells: int = 5

    def __post_init__(self) -> None:
        owner = "MapUpdateParams"
        for name in ("margin", "min_depth", "end_margin", "smooth"):
            check_number(owner, name, getattr(self, name), low=0.0, high=10.0)
        check_number(owner, "reach", self.reach, low=0.0, high=1000.0, low_open=True)
        check_number(owner, "pass_ratio", self.pass_ratio, low=0.0, high=1000.0)
        for name in ("scans_needed", "drives_needed"):
            check_number(owner, name, getattr(self, name), low=1, high=1_000_000, integer=True)
        check_number(owner, "close_cells", self.close_cells, low=0, high=101, integer=True)
