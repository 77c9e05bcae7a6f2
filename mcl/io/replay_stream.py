"""Stream a replay ([replay][mcl.experiments.replay.replay]) to Foxglove as it runs: at every scan
the scan, the odometry integrated since the start, the filter's estimate and particles, and the
transforms, on the topics of the MCAP recording ([BagRecorder][mcl.io.bag_writer.BagRecorder]),
stamped with the bag's own times (its log times, ns since the Unix epoch:
[BagData.start_ns][mcl.io.bag_reader.BagData] plus each scan's time)."""

from __future__ import annotations

import numpy as np

from mcl.filter.motion_model import compose
from mcl.io.bag_reader import BagData
from mcl.io.bag_writer import EPOCH_NS, BagRecorder
from mcl.io.live import LiveServer
from racecar_sim.maps import OccupancyMap

__all__ = ["ReplayStream"]


class ReplayStream:
    """The ``on_scan`` hook of [replay][mcl.experiments.replay.replay] that streams to ``live``.

    Args:
        data: the bag being replayed (its beam angles, range, mount and start time).
        occupancy_map: the filter's map (sent once on ``/map``).
        live: the Foxglove server ([start_live][mcl.io.bag_writer.start_live]).
    """

    def __init__(self, data: BagData, occupancy_map: OccupancyMap, live: LiveServer) -> None:
        period = float(np.median(np.diff(data.scan_times))) if data.n_scans > 1 else 0.025
        self.recorder = BagRecorder(
            None, occupancy_map, data.angles, float(data.range_max), data.mount_offset,
            period, live=live, epoch_ns=data.start_ns or EPOCH_NS,  # 0: a BagData made by hand
        )  # fmt: skip
        self.recorder.write_static(0.0)
        self.data = data
        self._odom = np.zeros(3)
        self._t_last = 0.0

    def __call__(self, i: int, t: float, moved: np.ndarray, pf) -> None:
        """After scan ``i`` at ``t`` s: ``moved`` is the odometry's motion since the last scan
        (car frame: dx m, dy m, dtheta rad), ``pf`` the filter after the correction."""
        rec = self.recorder
        dt = t - self._t_last
        twist = np.asarray(moved, dtype=np.float64) / dt if dt > 0 else np.zeros(3)
        self._odom = compose(self._odom[None], np.asarray(moved, dtype=np.float64)[None])[0]
        self._t_last = t
        rec.write_odom(t, self._odom, twist)
        rec.write_scan(t, self.data.scans[i])
        rec.write_estimate(t, pf.estimate(), pf.covariance(), pf.particles)
