"""What a replay writes: trajectory.csv, trajectory.png, scan_fit.png and replay.mp4.

- ``trajectory.csv``: one row per scan, the columns of [`mcl.experiments.replay.COLUMNS`][mcl.experiments.replay.COLUMNS]
  (time in seconds since the bag's first message; the base_link estimate in the map's world frame;
  position_sd metres, heading_sd radians; ambiguous 0/1; scan_fit a fraction), plus
  ``position_error,heading_error`` when the bag has ``/ground_truth``.
- ``trajectory.png``: the map around the drive (walls dark, free space light), the estimated path
  (the search apart), every k-th scan's end points drawn from the estimate once the filter has
  found the car (and the true path when known, dashed over the estimate); "not found" in the
  title when the estimate never fitted the scans to the map.
- ``scan_fit.png``: scan_fit and the particle count against time.
- ``replay.mp4``: the map, the particles, the scan from the estimate, and a legend, at ``fps``
  frames per second of recording (PNG frames when OpenCV cannot write mp4).
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mcl.experiments.frame_text import draw_legend
from mcl.experiments.plots import save_figure
from mcl.experiments.replay import COLUMNS, FIT_WINDOW_S, FOUND_SD, GOOD_FIT, ReplayResult
from mcl.experiments.video import FrameWriter
from racecar_sim.file_guard import claim_folder, writable
from racecar_sim.maps import OccupancyMap

__all__ = [
    "plot_scan_fit",
    "plot_trajectory",
    "write_outputs",
    "write_trajectory_csv",
    "write_video",
]


def write_trajectory_csv(result: ReplayResult, path: str | os.PathLike[str]) -> Path:
    """trajectory.csv (module docstring)."""
    path = Path(path)
    header = list(COLUMNS)
    extra = result.position_error is not None
    if extra:
        header += ["position_error", "heading_error"]
    with writable(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i, row in enumerate(result.rows):
            out = [f"{row[0]:.6f}", *(f"{v:.6f}" for v in row[1:4]), str(int(row[4]))]
            out += [f"{row[5]:.6f}", f"{row[6]:.6f}", str(int(row[7])), f"{row[8]:.4f}"]
            if extra:
                assert result.position_error is not None and result.heading_error is not None
                out += [f"{result.position_error[i]:.6f}", f"{result.heading_error[i]:.6f}"]
            w.writerow(out)
    return path


def _end_points(result: ReplayResult, i: int) -> np.ndarray:
    """(K, 2) world end points of scan i's valid beams drawn from the estimate's lidar."""
    d = result.data
    x, y, th = result.rows[i, 1:4]
    r = d.scans[i]
    ok = np.isfinite(r)
    lx, ly = x + d.mount_offset * math.cos(th), y + d.mount_offset * math.sin(th)
    a = th + d.angles[ok]
    return np.column_stack([lx + r[ok] * np.cos(a), ly + r[ok] * np.sin(a)])


def _view(result: ReplayResult, margin: float = 6.0) -> tuple[float, float, float, float]:
    xy = result.rows[:, 1:3]
    keep = result.column("position_sd") < 1.0
    pts = xy[keep] if keep.any() else xy
    return (
        float(pts[:, 0].min() - margin),
        float(pts[:, 0].max() + margin),
        float(pts[:, 1].min() - margin),
        float(pts[:, 1].max() + margin),
    )


def map_image(
    m: OccupancyMap, view: tuple[float, float, float, float]
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The map inside ``view`` (x0, x1, y0, y1 in metres, world frame) as an RGB float image on a
    world-aligned raster at the map's resolution (any origin yaw): free space light, walls (the
    non-free cells within 0.15 m of free space) dark, the rest (unknown, solid) mid grey. Returns
    the image and its ``imshow`` extent."""
    x0, x1, y0, y1 = view
    res = float(m.resolution)
    xs = np.arange(x0 + res / 2, x1, res)
    ys = np.arange(y1 - res / 2, y0, -res)  # image rows top-down
    gx, gy = np.meshgrid(xs, ys)
    free = m.is_free(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)
    reach = max(1, round(0.15 / res))
    near = cv2.dilate(free.astype(np.uint8), np.ones((2 * reach + 1,) * 2, np.uint8)) > 0
    img = np.full((*free.shape, 3), 0.72)
    img[free] = 0.97
    img[~free & near] = 0.18
    return img, (x0, x0 + xs.size * res, y1 - ys.size * res, y1)


def plot_trajectory(
    result: ReplayResult, occupancy_map: OccupancyMap, path: str | os.PathLike[str], every: int = 40
) -> Path:
    """trajectory.png: the map (walls dark, free space light), the ground truth when known (drawn
    over the estimate, dashed, so that both show where they agree), the path, and every
    ``every``-th scan's end points drawn from the estimate once the filter has found the car
    (position sd < 0.5 m); scans from the search, drawn from a wrong pose, are left out. When the
    filter never found the car ([found_at][mcl.experiments.replay.ReplayResult.found_at] is None:
    a wrong map, frame or start) the title says "not found" and no scan is drawn."""
    view = _view(result)
    fig, ax = plt.subplots(figsize=(8, 8))
    img, extent = map_image(occupancy_map, view)
    ax.imshow(img, extent=extent, interpolation="nearest", zorder=0)
    found_at = result.found_at()
    found = result.column("position_sd") < FOUND_SD
    if found_at is None:
        found[:] = False
    shown = [i for i in range(0, len(result.rows), every) if found[i]]
    for n, i in enumerate(shown):
        ep = _end_points(result, i)
        label = f"scan end points from the estimate ({len(shown)} scans)" if n == 0 else None
        ax.plot(ep[:, 0], ep[:, 1], ".", ms=1.5, color="tab:blue", alpha=0.5, label=label)
    d = result.data
    x, y = result.column("x"), result.column("y")
    if not found.all():
        searching = (
            "estimate while searching (sd >= 0.5 m)"
            if found_at is not None
            else f"estimate, never fitting the map (scan_fit <= {result.best_fit():.2f} over 1 s)"
        )
        ax.plot(
            np.where(found, np.nan, x), np.where(found, np.nan, y), "--", color="tab:purple",
            lw=0.9, label=searching, zorder=2,
        )  # fmt: skip
    if found.any():
        ax.plot(
            np.where(found, x, np.nan),
            np.where(found, y, np.nan),
            "-",
            color="tab:orange",
            lw=2.6,
            label="estimate (base_link, position sd < 0.5 m)",
            zorder=2,
        )
    if d.truth is not None:  # over the estimate, thinner and dashed: both show
        ax.plot(d.truth[:, 0], d.truth[:, 1], "--", color="black", lw=1.2, label="ground truth",
                zorder=3)  # fmt: skip
    ax.set_xlim(view[0], view[1])
    ax.set_ylim(view[2], view[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, map frame)")
    ax.set_ylabel("y (m)")
    if found_at is None:
        ax.set_title(
            f"{d.path.name}\nNOT FOUND: scan_fit never reached {GOOD_FIT:g} over "
            f"{FIT_WINDOW_S:g} s (wrong map, frame or start?)",
            color="tab:red",
        )
    else:
        ax.set_title(
            f"{d.path.name}\nfound at {found_at:.2f} s; the estimate and every {every}th scan "
            "once found"
        )
    ax.legend(loc="best", fontsize=8, markerscale=6)
    return save_figure(fig, path)


def plot_scan_fit(result: ReplayResult, path: str | os.PathLike[str]) -> Path:
    """scan_fit.png: scan_fit and the particle count against time."""
    t = result.column("time")
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax1.plot(t, result.column("scan_fit"), color="tab:blue")
    ax1.set_ylabel("scan_fit (beams within 0.15 m)")
    ax1.set_ylim(0, 1)
    ax1.grid(alpha=0.3)
    ax2.semilogy(t, result.column("n_particles"), color="tab:green")
    ax2.set_ylabel("particles")
    ax2.set_xlabel("time since the bag's first message (s)")
    ax2.grid(alpha=0.3)
    ax1.set_title(result.data.path.name)
    return save_figure(fig, path)


REPLAY_LEGEND_BGR = (
    ("particles", (0, 160, 0), "dots"),
    ("scan drawn from the estimate", (0, 0, 220), "dots"),
    ("estimate (base_link)", (0, 140, 255), "arrow"),
)
"""The video's legend: what its frames draw, in their colours (the frames are drawn in BGR)."""


def write_video(
    result: ReplayResult,
    occupancy_map: OccupancyMap,
    path: str | os.PathLike[str],
    fps: float = 10.0,
    px_per_m: float = 30.0,
) -> FrameWriter:
    """replay.mp4: one frame per 1/fps s of recording (module docstring)."""
    view = _view(result)
    x0, x1, y0, y1 = view
    w, h = int((x1 - x0) * px_per_m), int((y1 - y0) * px_per_m)
    img, _ = map_image(occupancy_map, view)
    base = cv2.resize((255 * img).astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST)

    def px(xy: np.ndarray) -> np.ndarray:
        u = (xy[:, 0] - x0) * px_per_m
        v = (y1 - xy[:, 1]) * px_per_m
        return np.column_stack([u, v]).astype(np.int32)

    times = result.column("time")
    with FrameWriter(path, fps) as writer:
        for t in np.arange(0.0, result.duration, 1.0 / fps):
            i = int(np.searchsorted(times, t, side="right")) - 1
            frame = base.copy()
            if i >= 0:
                for u, v in px(result.particles[i][:, :2]):
                    cv2.circle(frame, (int(u), int(v)), 1, (0, 160, 0), -1)
                for u, v in px(_end_points(result, i)):
                    cv2.circle(frame, (int(u), int(v)), 1, (0, 0, 220), -1)
                x, y, th = result.rows[i, 1:4]
                p0 = px(np.array([[x, y]]))[0]
                p1 = px(np.array([[x + 0.6 * math.cos(th), y + 0.6 * math.sin(th)]]))[0]
                cv2.arrowedLine(
                    frame, tuple(int(v) for v in p0), tuple(int(v) for v in p1), (0, 140, 255), 2
                )
                text = (
                    f"t {t:5.2f} s  fit {result.rows[i, 8]:.2f}  "
                    f"n {int(result.rows[i, 4])}  sd {result.rows[i, 5]:.2f} m"
                )
                cv2.putText(
                    frame, text, (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA
                )
            draw_legend(frame, REPLAY_LEGEND_BGR, "bottom-left")
            writer.write(frame[:, :, ::-1].copy())
    return writer


def write_outputs(
    result: ReplayResult,
    occupancy_map: OccupancyMap,
    out: str | os.PathLike[str],
    every: int = 40,
    video_fps: float = 10.0,
) -> list[Path]:
    """Every file of the module docstring into folder ``out``; returns their paths."""
    out = Path(out)
    claim_folder(out)
    paths = [
        write_trajectory_csv(result, out / "trajectory.csv"),
        plot_trajectory(result, occupancy_map, out / "trajectory.png", every),
        plot_scan_fit(result, out / "scan_fit.png"),
    ]
    if video_fps > 0:
        writer = write_video(result, occupancy_map, out / "replay.mp4", video_fps)
        if writer.path is not None:
            paths.append(Path(writer.path))
    return paths
