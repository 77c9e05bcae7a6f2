"""Odometry noise from a recording: the odometry's motion against the reference poses' motion
over short windows between well-localized scans.

For each window of ``window`` seconds the mean car-frame twist is computed twice: from the
reference poses (``relative(base_a, base_b) / T``) and from the recorded twists integrated over the
same time. Per component (vx, vy, omega) the error ``e = odom - reference`` is modelled as

    e = scale_bias * true + offset + noise,   var(noise) = proportional² true² + additive²,

the simulator's [`OdometryNoise`][racecar_sim.settings.config.OdometryNoise] form plus a bias. The window errors are
the average of the per-step noise over the window; the per-step standard deviations the simulator
needs (independent draws every ``sim_dt`` seconds) follow by ``sd_step = sd_window * sqrt(T / sim_dt)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from mcl.calibration.reference_poses import ReferencePoses, integrate_twist, relative
from mcl.io.bag_reader import BagData

__all__ = ["OdometryFit", "best_lag", "fit_odometry", "window_twists"]


@dataclass(frozen=True)
class OdometryFit:
    """Odometry error model per component [vx, vy, omega].

    Attributes:
        scale_bias: (3,) relative bias: odometry reads (1 + scale_bias) x the true value.
        offset: (3,) additive bias (m/s, m/s, rad/s).
        proportional: (3,) window-level relative standard deviation.
        additive: (3,) window-level additive standard deviation (m/s, m/s, rad/s).
        window: seconds per window.
        n_windows: windows used.
        speed_rmse: (3,) root mean square of the window errors.
        lag: seconds the odometry's stamps were shifted by (positive: the odometry leads the
            motion, e.g. an angular rate computed from the steering *command*).
    """

    scale_bias: tuple[float, float, float]
    offset: tuple[float, float, float]
    proportional: tuple[float, float, float]
    additive: tuple[float, float, float]
    window: float
    n_windows: int
    speed_rmse: tuple[float, float, float]
    lag: float = 0.0

    def per_step(self, sim_dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(proportional, additive) for independent draws every ``sim_dt`` seconds that give the
        same window-level spread (the average of n draws has 1/sqrt(n) of their spread)."""
        k = math.sqrt(self.window / sim_dt)
        return tuple(p * k for p in self.proportional), tuple(a * k for a in self.additive)


def window_twists(
    rec: BagData, poses: ReferencePoses, window: float, min_fit: float
) -> tuple[np.ndarray, np.ndarray]:
    """(reference, odometry) mean twists (W, 3) over non-overlapping windows of ``window`` s whose
    end scans both fit the map (``fit15 >= min_fit``)."""
    ref, odo = [], []
    t = rec.scan_stamps
    k = 0
    while k < len(t) - 1:
        j = int(np.searchsorted(t, t[k] + window))
        if j >= len(t):
            break
        if poses.fit15[k] >= min_fit and poses.fit15[j] >= min_fit:
            T = t[j] - t[k]
            d_ref = relative(poses.base[k], poses.base[j])
            d_odo = integrate_twist(rec.odom_stamps, rec.odom_twist, t[k], t[j])
            ref.append(d_ref / T)
            odo.append(d_odo / T)
        k = j
    return np.asarray(ref).reshape(-1, 3), np.asarray(odo).reshape(-1, 3)


def best_lag(
    recs: list[tuple[BagData, ReferencePoses]],
    window: float = 0.25,
    min_fit: float = 0.7,
    lags: np.ndarray | None = None,
) -> float:
    """The shift (s) of the odometry stamps that minimises the window errors (vx and omega rmse,
    each relative to its value at no shift)."""
    lags = np.arange(-0.2, 0.2001, 0.01) if lags is None else np.asarray(lags)
    base = np.array(fit_odometry(recs, window, min_fit).speed_rmse)
    cost = []
    for lag in lags:
        f = fit_odometry(recs, window, min_fit, lag=float(lag))
        r = np.array(f.speed_rmse)
        cost.append(r[0] / base[0] + r[2] / base[2])
    return float(lags[int(np.argmin(cost))])


def fit_odometry(
    recs: list[tuple[BagData, ReferencePoses]],
    window: float = 0.25,
    min_fit: float = 0.7,
    lag: float = 0.0,
    pose_sd: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> OdometryFit:
    """Fit the odometry error model over all windows of all recordings.

    ``pose_sd`` (metres, metres, radians): the reference poses' own jitter (e.g. over a stop);
    its share of the window spread, 2 pose_sd² / T², is taken off the additive variance.

    Raises:
        ValueError: fewer than 10 usable windows.
    """
    shifted = [(replace(r, odom_stamps=r.odom_stamps + lag), p) for r, p in recs]
    parts = [window_twists(r, p, window, min_fit) for r, p in shifted]
    ref = np.vstack([a for a, _ in parts])
    odo = np.vstack([b for _, b in parts])
    if len(ref) < 10:
        raise ValueError(f"need at least 10 well-localized windows, got {len(ref)}")
    scale, off, prop, add, rmse = [], [], [], [], []
    for c in range(3):
        x, e = ref[:, c], odo[:, c] - ref[:, c]
        moving = np.abs(x) > 1e-3
        if (
            c == 1 or moving.sum() < 5
        ):  # vy: the true lateral speed is ~0, fit the spread only  # no signal to scale (vy reads 0): offset and spread only
            s, o = 0.0, float(e.mean())
        else:
            A = np.column_stack([x, np.ones_like(x)])
            s, o = (float(v) for v in np.linalg.lstsq(A, e, rcond=None)[0])
        r = e - s * x - o
        if c == 1:
            scale.append(0.0)
            off.append(o)
            prop.append(0.0)
            add.append(float(np.sqrt(max(np.mean(r * r) - 2.0 * pose_sd[c] ** 2 / window**2, 0.0))))
            rmse.append(float(np.sqrt(np.mean(e * e))))
            continue
        # var(r) = p² x² + a²: least squares on the squared residuals, both terms >= 0
        A = np.column_stack([x * x, np.ones_like(x)])
        coef = np.linalg.lstsq(A, r * r, rcond=None)[0]
        coef[1] = coef[1] - 2.0 * pose_sd[c] ** 2 / window**2
        if coef[0] < 0:
            coef = np.array([0.0, float(np.mean(r * r))])
        if coef[1] < 0:
            coef = np.array([float((x * x * r * r).sum() / max((x**4).sum(), 1e-12)), 0.0])
        scale.append(s)
        off.append(o)
        prop.append(math.sqrt(coef[0]))
        add.append(math.sqrt(coef[1]))
        rmse.append(float(np.sqrt(np.mean(e * e))))
    return OdometryFit(
        tuple(scale), tuple(off), tuple(prop), tuple(add), window, len(ref), tuple(rmse), lag
    )  # type: ignore[arg-type]
