"""Searches in a row that confirm the filter's place after a jump: the ``lost`` flag's count
([LostParams.search_confirmations][mcl.filter.lost_params.LostParams]).

After a kidnap the car can be found at once on a place the old map explains less well than the
one it left, and the fit alone would keep the flag up over it. Each search the flag starts
([GlobalSearch][mcl.filter.global_search.GlobalSearch]) that settles on the filter's own place
counts one; ``needed`` in a row find the car. A search that settles elsewhere on a place fitting
as well as the filter's, or better, breaks the row (the scans leave two places open). One that
settles on a place fitting *worse* (``GlobalSearch.compare`` returned -1) neither counts nor
breaks it: a worse rival says nothing against the filter's place, and a cluttered world's
look-alikes would otherwise keep a found car flagged.
"""

from __future__ import annotations

__all__ = ["SearchConfirmations"]


class SearchConfirmations:
    """The count of searches in a row settled on the filter's place (module docstring).

    Args:
        needed: searches in a row that confirm the place; 0 never confirms.

    Attributes:
        count: searches settled on the filter's place since the row was last broken.
    """

    def __init__(self, needed: int) -> None:
        self.needed = needed
        self.count = 0

    def restart(self) -> None:
        """Start the row again (a new jump, or the car found)."""
        self.count = 0

    def settled_elsewhere(self, verdict: int) -> None:
        """A search settled on another place; ``verdict`` is ``GlobalSearch.compare``'s (1: it
        fits better, 0: as well, -1: worse). Only a place fitting as well or better breaks the
        row."""
        if verdict >= 0:
            self.count = 0

    def agreed(self) -> bool:
        """One more search settled on the filter's place; True once ``needed`` did in a row."""
        self.count += 1
        return self.needed > 0 and self.count >= self.needed
