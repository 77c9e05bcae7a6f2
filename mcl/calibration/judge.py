"""One judge for real and simulated scans: residual fractions against exact casts from poses
refined by a robust scan match (not the filter's beam model).

Each scan's lidar pose is refined by [`ScanMatcher.refine()`][ScanMatcher.refine] (pattern search on a
Geman-McClure loss, 5 cm) from a starting pose: the tracked reference pose for a real scan, the
true pose for a simulated one. The scan is then compared with the exact cast from that pose,
beam by beam: pass the pair to [`residual_fractions()`][mcl.calibration.scan_stats.residual_fractions]. A real sweep is de-skewed
with the odometry first, so that its beams and the cast share the pose's time; a simulated scan
has no skew.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mcl.calibration.reference_poses import ReferencePoses, scan_beams
from mcl.calibration.scan_match import ScanMatcher
from mcl.io.bag_reader import BagData

__all__ = ["judged_recording", "judged_simulation"]

_REFINE_STEP = (0.01, 0.005)
"""(metres, radians): first step of the refinement; the starting poses are centimetres off."""


def judged_recording(
    rec: BagData, poses: ReferencePoses, matcher: ScanMatcher, mount: float = 0.275
) -> tuple[np.ndarray, np.ndarray]:
    """(z, z_star) (S, B) metres: each de-skewed real scan and the exact cast from its refined
    lidar pose (NaN readings are no-returns)."""
    z = np.empty((len(rec.scans), rec.angles.size))
    zs = np.empty_like(z)
    for k in range(len(rec.scans)):
        r, a = scan_beams(rec, k, mount, poses.deskewed)
        matcher.angles = a
        pose, _ = matcher.refine(poses.lidar[k], r, _REFINE_STEP)
        z[k] = r
        zs[k] = matcher.caster.cast(pose, a)[0]
    matcher.angles = rec.angles
    return z, zs


def judged_simulation(
    scan_at: Callable[[int], tuple[np.ndarray, np.ndarray] | None],
    n: int,
    matcher: ScanMatcher,
) -> tuple[np.ndarray, np.ndarray]:
    """(z, z_star) (S, B) metres of ``n`` simulated scans: ``scan_at(i)`` returns (ranges (B,)
    with NaN for no-returns, true lidar pose (3,)) or None to skip; each is judged from its
    refined pose like a real scan."""
    z, zs = [], []
    for i in range(n):
        got = scan_at(i)
        if got is None:
            continue
        r, true_pose = got
        pose, _ = matcher.refine(true_pose, r, _REFINE_STEP)
        z.append(r)
        zs.append(matcher.caster.cast(pose, matcher.angles)[0])
    return np.array(z), np.array(zs)
