"""Write rendered RGB frames to an mp4 (OpenCV, 'mp4v'), or to numbered PNGs when it cannot."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from racecar_sim.file_guard import writable

__all__ = ["FrameWriter"]


class FrameWriter:
    """Collects RGB uint8 frames (H, W, 3) of one size into ``path`` (an .mp4).

    The video writer is opened on the first frame (its size fixes the video's). When OpenCV cannot
    open an mp4 writer, the frames go to ``<path without suffix>_frames/frame_00000.png``, ... .
    Frames with odd sizes are padded by one row / column (many codecs need even sizes). An
    existing file is replaced only in racecar-sim's own folders
    ([writable][racecar_sim.file_guard.writable]; FileExistsError on the first frame otherwise).

    Attributes:
        path: the mp4, or the folder of PNG frames after a fallback (known after the first frame).
        kind: ``"mp4"`` or ``"png"`` once the first frame is written, None before.
        n_frames: frames written.
        fps: frames per second of the video.
    """

    def __init__(self, path: str | os.PathLike[str], fps: float, force_png: bool = False) -> None:
        if not (fps > 0):
            raise ValueError(f"fps must be positive, got {fps!r}")
        self.path = Path(path)
        self.fps = float(fps)
        self.n_frames = 0
        self._force_png = force_png
        self.kind: str | None = None
        self._writer: cv2.VideoWriter | None = None
        self._png_dir: Path | None = None
        self._size: tuple[int, int] | None = None

    def _open(self, width: int, height: int) -> None:
        writable(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if not self._force_png:
            fourcc = cv2.VideoWriter_fourcc(*"mp4v")
            writer = cv2.VideoWriter(str(self.path), fourcc, self.fps, (width, height))
            if writer.isOpened():
                self._writer = writer
                self.kind = "mp4"
                return
            writer.release()
        self._png_dir = self.path.with_name(self.path.stem + "_frames")
        self._png_dir.mkdir(parents=True, exist_ok=True)
        self.path = self._png_dir
        self.kind = "png"

    def write(self, frame: np.ndarray) -> None:
        """Append an RGB uint8 frame (H, W, 3).

        Raises:
            ValueError: the frame is not (H, W, 3) uint8, or its size differs from the first's.
        """
        img = np.asarray(frame)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise ValueError(f"frame must be an RGB uint8 (H, W, 3) array, got {img.shape}")
        h, w = img.shape[:2]
        if h % 2 or w % 2:
            img = np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        size = (img.shape[1], img.shape[0])
        if self._size is None:
            self._size = size
            self._open(*size)
        elif size != self._size:
            raise ValueError(f"frame size {size} differs from the first frame's {self._size}")
        bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
        if self._writer is not None:
            self._writer.write(bgr)
        else:
            assert self._png_dir is not None
            cv2.imwrite(str(writable(self._png_dir / f"frame_{self.n_frames:05d}.png")), bgr)
        self.n_frames += 1

    def close(self) -> None:
        """Finish the video (idempotent)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
