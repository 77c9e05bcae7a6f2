"""Maps updated from the drives that used them: the cells whose walls the world no longer has
([`mcl.mapping.update`][mcl.mapping.update]). Part of the lab: imports the filter, the wrappers
and the recorded drives of [`mcl.experiments.recorded`][mcl.experiments.recorded]."""

from mcl.mapping.params import MapUpdateParams
from mcl.mapping.see_through import DriveEvidence, drive_evidence
from mcl.mapping.update import MapUpdate, opened_cells, update_from_drives

__all__ = [
    "DriveEvidence",
    "MapUpdate",
    "MapUpdateParams",
    "drive_evidence",
    "opened_cells",
    "update_from_drives",
]
