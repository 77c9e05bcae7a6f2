"""The checks the particle filter runs on each scan beside its weighing, none of which needs the
map's verdict on the pose: the [standstill][mcl.filter.standstill.Standstill] check (wheels that
turn while the car stands), the [turn check][mcl.filter.scan_turn.TurnCheck] (an estimate that did
not turn with the car), and the scans a [scale learned from scans][mcl.filter.scan_scale.ScanScale]
is given; and the confirmed poses a scale learned from the map is given.

[`ScanChecks`][mcl.filter.scan_checks.ScanChecks] is a base of
[`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter], which holds the particles and the
fields used here. Frames and units: world poses [x, y, theta] (metres, radians); scans in metres.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mcl.filter.angles import wrap_angle
from mcl.filter.belief import Belief
from mcl.filter.motion_model import carry
from mcl.filter.odometry_scale import OdometryScale
from mcl.filter.scan_continuity import scan_bearings
from mcl.filter.scan_fit import ScanFit
from mcl.filter.scan_turn import TurnCheck
from mcl.filter.standstill import Standstill
from racecar_sim.maps import OccupancyMap

__all__ = ["ScanChecks"]


class ScanChecks(Belief):
    """The per-scan checks of the particle filter (module docstring; fields set by
    [`ParticleFilter`][mcl.filter.particle_filter.ParticleFilter])."""

    map: OccupancyMap
    sensor_model: Any
    searching: bool
    odometry_scale: OdometryScale
    standstill: Standstill
    turn_check: TurnCheck
    _scale_fit: ScanFit

    def _confirm_scale(self, scan: np.ndarray) -> None:
        """Give the learned odometry scale the corrected estimate, its spread and the scan's fit
        there (skip_short: beams short of the map are furniture, people, cars)."""
        if self.odometry_scale.learning:
            estimate, covariance = self.estimate(), self.covariance()
            spread = math.sqrt(max(0.0, covariance[0, 0] + covariance[1, 1]))
            fit = self._scale_fit.at(self.sensor_model, self.map, estimate, scan)
            self.odometry_scale.confirm(estimate, spread, fit)

    def _check_scans(self, scan: np.ndarray) -> None:
        """Give the scan to the standstill check, the turn check and a scale learned from scans
        (before the filter uses it); take back what the filter predicted beyond a car found
        standing; turn the cloud when the turn check says the estimate did not turn."""
        due, scales, turns = self.standstill.due(), self.odometry_scale.wants_scans, self.turn_check
        turn_due = turns.due() and not self.searching
        if due or scales or turn_due:  # only then the scan's bearings and the lidar's mount
            sm = self.sensor_model
            z = np.asarray(scan, dtype=np.float64).reshape(-1)
            mount, angles = sm.lidar_poses(np.zeros((1, 3)))[0], scan_bearings(sm, z.size)
            if scales:
                self.odometry_scale.observe_scan(z, angles, mount, float(sm.max_range))
        if due:
            estimate = self.estimate() if self.standstill.params.take_back else None
            self.standstill.observe(z, angles, mount, float(sm.max_range), estimate)
            back = self.standstill.take_back()
            if back is not None and estimate is not None:  # the wheels drove on: move back
                self._particles = carry(self._require()[0], estimate, back)
                self.odometry_scale.drop_bridge()  # its path holds the motion taken back
        if self.searching:  # the estimate's turn means nothing while the cloud searches
            turns.restart()
        elif not turn_due:
            turns.skip_scan()
        elif turn := turns.observe(z, angles, mount, float(sm.max_range), float(self.estimate()[2])):
            particles = self._require()[0].copy()  # the scans and the wheels turned, the estimate
            particles[:, 2] = wrap_angle(particles[:, 2] + turn)  # did not: turn the cloud
            self._particles = particles
