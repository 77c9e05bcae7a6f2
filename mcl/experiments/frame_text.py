"""Text and legends on video frames (RGB uint8 images, OpenCV pixel points ``(x, y)`` = (column,
row)): a label readable on any background, and a legend box whose swatches are drawn the way the
frame draws what they stand for (a filled box, dots, an arrow)."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

__all__ = ["LEGEND_KINDS", "draw_legend", "put_label"]

Colour = tuple[int, int, int]
FONT = cv2.FONT_HERSHEY_SIMPLEX
LEGEND_KINDS = ("box", "dots", "arrow", "line")
"""Swatches of a legend entry."""


_OUTLINE_SHIFTS = tuple(
    (dx, dy) for dx in range(-2, 3) for dy in range(-2, 3) if 0 < dx * dx + dy * dy <= 5
)


def put_label(
    img: np.ndarray,
    text: str,
    org: tuple[int, int],
    colour: Colour = (0, 0, 0),
    scale: float = 0.45,
    outline: Colour | None = (255, 255, 255),
    thickness: int = 1,
) -> None:
    """Write ``text`` with its baseline's left end at ``org`` (in place), in ``colour`` over an
    ``outline`` two pixels wide (None: no outline)."""
    org = (int(org[0]), int(org[1]))
    if outline is not None:  # the text shifted around by up to 2 px (a thick stroke is not an
        # outline in every OpenCV: 5.x draws its own font, whose strokes widen differently)
        for dx, dy in _OUTLINE_SHIFTS:
            at = (org[0] + dx, org[1] + dy)
            cv2.putText(img, text, at, FONT, scale, outline, thickness, cv2.LINE_AA)
    cv2.putText(img, text, org, FONT, scale, colour, thickness, cv2.LINE_AA)


def _swatch(img: np.ndarray, kind: str, x: int, y: int, colour: Colour) -> None:
    """A 16 x 10 pixel swatch with its top-left corner at (x, y)."""
    if kind == "box":
        cv2.rectangle(img, (x, y), (x + 16, y + 10), colour, -1)
    elif kind == "dots":
        for dx, dy in ((2, 2), (8, 6), (13, 1), (4, 8), (12, 9)):
            cv2.rectangle(img, (x + dx, y + dy), (x + dx + 1, y + dy + 1), colour, -1)
    elif kind == "arrow":
        cv2.circle(img, (x + 3, y + 5), 3, colour, -1)
        cv2.arrowedLine(img, (x + 3, y + 5), (x + 16, y + 5), colour, 1, tipLength=0.4)
    elif kind == "line":
        cv2.line(img, (x, y + 5), (x + 16, y + 5), colour, 1, cv2.LINE_8)
    else:
        raise ValueError(f"legend swatch {kind!r}: one of {LEGEND_KINDS}")


def draw_legend(
    img: np.ndarray,
    entries: Sequence[tuple[str, Colour, str]],
    corner: str = "bottom-left",
    scale: float = 0.42,
) -> tuple[int, int, int, int]:
    """Draw a legend box of ``entries`` (text, RGB colour, swatch kind of
    [`LEGEND_KINDS`][mcl.experiments.frame_text.LEGEND_KINDS]) in a ``corner`` of ``img``
    (``"top-left"``, ``"top-right"``, ``"bottom-left"``, ``"bottom-right"``), in place; returns the
    box (x0, y0, x1, y1) in pixels."""
    if not entries:
        raise ValueError("a legend needs at least one entry")
    row, pad = 16, 6
    width = pad * 2 + 22 + max(cv2.getTextSize(t, FONT, scale, 1)[0][0] for t, _, _ in entries)
    height = pad * 2 + row * len(entries)
    h, w = img.shape[:2]
    x0 = pad if "left" in corner else max(0, w - width - pad)
    y0 = pad if "top" in corner else max(0, h - height - pad)
    x1, y1 = min(w - 1, x0 + width), min(h - 1, y0 + height)
    region = img[y0:y1, x0:x1]
    region[...] = (0.2 * region + 0.8 * 255).astype(np.uint8)  # a light box the map shows through
    cv2.rectangle(img, (x0, y0), (x1, y1), (120, 120, 120), 1)
    for k, (text, colour, kind) in enumerate(entries):
        y = y0 + pad + k * row
        _swatch(img, kind, x0 + pad, y + 2, colour)
        put_label(img, text, (x0 + pad + 22, y + 11), (0, 0, 0), scale, outline=None)
    return x0, y0, x1, y1
