"""The whole calibration: bags -> reference poses -> beam model (EM), failure statistics and
odometry noise -> the settings of a simulator noise profile.

``scripts/calibrate_noise.py`` (``racecar-sim calibrate-noise``) is the command line over
`calibrate()` and `profile_document()`.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mcl.calibration.beam_em import BeamModelFit, fit_beam_model
from mcl.calibration.judge import judged_recording
from mcl.calibration.odometry_fit import OdometryFit, best_lag, fit_odometry
from mcl.calibration.reference_poses import (
    ReferencePoses,
    poses_from_trajectory,
    track_recording,
)
from mcl.calibration.room_split import (
    BodyBlock,
    body_block,
    hit_correlation,
    room_stats,
    sensor_beams,
)
from mcl.calibration.scan_match import ScanMatcher
from mcl.calibration.scan_stats import RANGE_BINS, ScanFailureStats, failure_stats
from mcl.io.bag_reader import BagData, read_bag
from racecar_sim.file_guard import starts_with, writable
from racecar_sim.maps import load_map

__all__ = [
    "PROFILE_HEADER",
    "Calibration",
    "calibrate",
    "hit_sigma_for_ratio",
    "is_written_profile",
    "profile_document",
    "write_profile",
]

LIDAR_MAX_RANGE = 30.0
"""Metres: the Hokuyo's range_max in the shared bags, also the simulated lidar's range."""


@dataclass(frozen=True)
class Calibration:
    """Everything fitted from the bags.

    Attributes:
        bags: file names used.
        poses: the reference poses of each bag.
        beam: the table-6.2 EM fit over every beam with a mapped surface.
        failures: run lengths, drop-outs by range, long excess, mixed pixels, over every beam
            with a mapped surface (for the record).
        sensor: the same over the beams that show the sensor only
            ([`mcl.calibration.room_split.sensor_beams()`][mcl.calibration.room_split.sensor_beams]): what the profile simulates.
        hit_corr: correlation of neighbouring sensor beams' hit errors.
        noreturns: failure statistics over every mapped beam off the body: the no-returns by
            range (a drop-out is the sensor's wherever the beam goes; an opening's or a box's
            beam drops out at the rate of its own range).
        body: the beams the car's own body blocks.
        per_bag: residual fractions of each bag, and what its room adds (``room``).
        odometry: the odometry error model (at the best lag).
        pose_source: how the reference poses were found.
    """

    bags: tuple[str, ...]
    poses: tuple[ReferencePoses, ...]
    beam: BeamModelFit
    failures: ScanFailureStats
    sensor: ScanFailureStats
    hit_corr: float
    noreturns: ScanFailureStats
    body: BodyBlock
    per_bag: dict[str, dict[str, Any]]
    odometry: OdometryFit
    pose_source: str


def _erf_ratio(sigma: float, bias: float) -> float:
    def mass(t: float) -> float:
        s = sigma * math.sqrt(2.0)
        return 0.5 * (math.erf((t - bias) / s) - math.erf((-t - bias) / s))

    return mass(0.05) / mass(0.15)


def hit_sigma_for_ratio(ratio: float, bias: float) -> float:
    """Metres: the Gaussian sigma for which P(|e| <= 5 cm) / P(|e| <= 15 cm) = ``ratio``, where
    e ~ N(bias, sigma²) (bisection; the ratio falls as sigma grows)."""
    lo, hi = 1e-4, 1.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if _erf_ratio(mid, bias) > ratio:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def calibrate(
    bags: list[str | os.PathLike[str]],
    map_path: str | os.PathLike[str],
    mount_offset: float = 0.275,
    start_guesses: list[np.ndarray | None] | None = None,
    progress: bool = False,
    pose_files: list[str | os.PathLike[str]] | None = None,
) -> Calibration:
    """Fit the noise of the recorded lidar and odometry on ``map_path`` (see the module doc).

    ``start_guesses``: per bag, a lidar pose to refine instead of the global search (None = search).
    ``pose_files``: per bag, a replay's ``trajectory.csv`` whose poses are used instead of scan
    matching.
    """
    occ = load_map(map_path)
    recs: list[BagData] = []
    poses: list[ReferencePoses] = []
    z_all, zs_all, keep_all, per_bag = [], [], [], {}
    guesses = start_guesses or [None] * len(bags)
    files = pose_files or [None] * len(bags)
    for bag, guess, pose_file in zip(bags, guesses, files, strict=True):
        rec = read_bag(bag)
        matcher = ScanMatcher(occ, rec.angles, LIDAR_MAX_RANGE)
        if progress:
            print(f"{rec.name}: {len(rec.scans)} scans, locating...", flush=True)
        if pose_file is not None:
            rp = poses_from_trajectory(rec, matcher, pose_file, mount_offset)
        else:
            rp = track_recording(rec, matcher, mount_offset, start_guess=guess)
        # each (de-skewed) scan against the exact cast from its pose, refined once more
        z, cast = judged_recording(rec, rp, matcher, mount_offset)
        spacing = float(np.median(np.diff(rec.angles)))
        z_all.append(z)
        zs_all.append(cast)
        keep_all.append(sensor_beams(z, cast, spacing, LIDAR_MAX_RANGE))
        per_bag[rec.name] = failure_stats(z, cast, LIDAR_MAX_RANGE).fractions.as_dict()
        per_bag[rec.name]["mean_fit15"] = float(rp.fit15.mean())
        recs.append(rec)
        poses.append(rp)
    z = np.vstack(z_all)
    zs = np.vstack(zs_all)
    body = body_block(z)
    off_body = ~body.mask(z.shape[1])[None, :]
    keep = np.vstack(keep_all) & off_body
    for rec, zb, cb in zip(recs, z_all, zs_all, strict=True):
        spacing = float(np.median(np.diff(rec.angles)))
        room = room_stats(zb, np.where(off_body, cb, np.inf), spacing, LIDAR_MAX_RANGE)
        per_bag[rec.name]["room"] = room.as_dict()
    pairs = list(zip(recs, poses, strict=True))
    lag = best_lag(pairs)
    jitter = stationary_jitter(pairs)
    return Calibration(
        bags=tuple(r.name for r in recs),
        poses=tuple(poses),
        beam=fit_beam_model(z, zs, LIDAR_MAX_RANGE),
        failures=failure_stats(z, zs, LIDAR_MAX_RANGE),
        sensor=failure_stats(z, np.where(keep, zs, np.inf), LIDAR_MAX_RANGE),
        hit_corr=hit_correlation(z, zs, keep),
        noreturns=failure_stats(z, np.where(off_body, zs, np.inf), LIDAR_MAX_RANGE),
        body=body,
        per_bag=per_bag,
        odometry=fit_odometry(pairs, lag=lag, pose_sd=jitter),
        pose_source=(
            "replay trajectories (racecar-sim replay): " + ", ".join(str(f) for f in pose_files)
            if pose_files
            else "scan matching (mcl.calibration.scan_match), de-skewed with the odometry"
        ),
    )


def stationary_jitter(
    pairs: list[tuple[BagData, ReferencePoses]], min_scans: int = 20
) -> tuple[float, float, float]:
    """(x m, y m, theta rad) standard deviation of the reference base poses while the car stands
    still (odometry speed below 1 cm/s for ``min_scans`` scans or more): the poses' own noise."""
    parts = []
    for rec, rp in pairs:
        idx = np.searchsorted(rec.odom_stamps, rec.scan_stamps, side="right") - 1
        still = np.abs(rec.odom_twist[np.clip(idx, 0, None), 0]) < 0.01
        padded = np.r_[False, still, False].astype(np.int8)
        d = np.diff(padded)
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
            if b - a >= min_scans:
                seg = rp.base[a:b]
                parts.append(seg - seg.mean(axis=0))
    if not parts:
        return (0.0, 0.0, 0.0)
    dev = np.vstack(parts)
    return tuple(float(v) for v in dev.std(axis=0))  # type: ignore[return-value]


def _r(v: float, nd: int = 4) -> float:
    return float(round(float(v), nd))


def _rounded(d: dict[str, Any]) -> dict[str, Any]:
    return {k: _rounded(v) if isinstance(v, dict) else _r(v) for k, v in d.items()}


def _failures_record(f: ScanFailureStats) -> dict[str, Any]:
    return {
        "run_length": {k: _r(v, 2) for k, v in f.run_length.items()},
        "next_same": {k: _r(v, 3) for k, v in f.next_same.items()},
        "hit_sigma_by_range": [None if math.isnan(v) else _r(v) for v in f.hit_sigma_by_range],
        "mixed_at_edges": _r(f.mixed_at_edges),
        "edge_fraction": _r(f.edge_fraction),
        "short_ratio": _r(f.short_ratio, 3),
    }


def profile_document(cal: Calibration, sim_dt: float = 0.025) -> dict[str, Any]:
    """The noise profile (YAML-ready mapping): ``settings`` for RacecarEnv and ``fit`` for the record."""
    f = cal.sensor
    fr = f.fractions
    hit_bias = f.hit_bias
    sigma = hit_sigma_for_ratio(fr.within5 / fr.within15, hit_bias)
    nr = cal.noreturns
    probs = [min(p, 0.95) for p in nr.noreturn_by_range]
    body = cal.body
    od = cal.odometry
    prop, add = od.per_step(sim_dt)
    settings = {
        "max_range": LIDAR_MAX_RANGE,
        "range_sigma": 0.0,
        "p_short": 0.0,
        "p_max": 0.0,
        "p_rand": 0.0,
        "scan_effects": {
            "hit_bias": _r(hit_bias),
            "hit_sigma": _r(sigma),
            "hit_corr": _r(cal.hit_corr, 3),
            "short_fraction": _r(fr.short / (1.0 - fr.noreturn)),  # of the sensor's beams
            "short_run": _r(f.run_length["short"], 2),
            "short_ratio_min": _r(max(0.0, 2 * f.short_ratio - 1), 3),
            "long_fraction": _r(fr.long / (1.0 - fr.noreturn)),
            "long_run": _r(f.run_length["long"], 2),
            "long_excess": _r(f.long_excess),
            "noreturn_edges": [float(e) for e in RANGE_BINS],
            "noreturn_probability": [_r(p) for p in probs],
            "noreturn_run": _r(nr.run_length["noreturn"], 2),
            "body_first": _r(body.first),
            "body_last": _r(body.last),
            "body_probability": _r(body.probability, 3),
            "body_range": _r(body.range, 3),
        },
        "odom_proportional": [_r(v) for v in prop],
        "odom_additive": [_r(v) for v in add],
        "odom_bias": {
            "scale": [_r(v) for v in od.scale_bias],
            "offset": [_r(v) for v in od.offset],
        },
        # The odometry's measured lead over the motion (a lag, negative, has no causal model here).
        "odom_lead": _r(max(od.lag, 0.0), 3),
    }
    beam = asdict(cal.beam)
    return {
        "name": "mit_racecar",
        "description": (
            "The MIT RSS racecar's Hokuyo lidar and VESC odometry, fitted on the two shared "
            "Stata basement recordings (2022-03-29) at scan-matched poses on stata_basement.yaml."
        ),
        "source": {
            "bags": list(cal.bags),
            "poses": cal.pose_source,
            "scans": int(sum(len(p.lidar) for p in cal.poses)),
            "sim_dt": sim_dt,
        },
        "settings": settings,
        "fit": {
            "beam_model_em": {
                k: (_r(v, 5) if isinstance(v, float) else v) for k, v in beam.items()
            },
            "residuals": {k: _r(v) for k, v in cal.failures.fractions.as_dict().items()},
            "residuals_sensor": {k: _r(v) for k, v in fr.as_dict().items()},
            "residuals_per_bag": {b: _rounded(d) for b, d in cal.per_bag.items()},
            "failures": _failures_record(cal.failures),
            "failures_sensor": _failures_record(f),
            "body": {k: _r(v) for k, v in asdict(body).items()},
            "odometry": {
                "lag_s": _r(od.lag, 3),
                "window_s": od.window,
                "windows": od.n_windows,
                "scale_bias": [_r(v) for v in od.scale_bias],
                "offset": [_r(v) for v in od.offset],
                "window_proportional": [_r(v) for v in od.proportional],
                "window_additive": [_r(v) for v in od.additive],
                "window_rmse": [_r(v) for v in od.speed_rmse],
            },
        },
    }


PROFILE_HEADER = (
    "# Written by scripts/calibrate_noise.py; numbers and origin in docs/honest_noise.md.\n"
)
"""The first line of every profile written here (how an earlier one is recognised)."""


def is_written_profile(path: Path) -> bool:
    """Whether the file ``path`` is a profile
    [write_profile][mcl.calibration.pipeline.write_profile] wrote (its first line)."""
    return starts_with(PROFILE_HEADER.encode())(path)


def write_profile(doc: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Write the profile ``doc`` as YAML to ``path`` (parents created).

    Raises:
        FileExistsError: ``path`` exists and is not a profile written here
            ([NotOurs][racecar_sim.file_guard.NotOurs]).
    """
    import yaml

    path = writable(path, is_written_profile)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(PROFILE_HEADER + yaml.safe_dump(doc, sort_keys=False, width=100))
    return path
