"""Hostile map files for the tests: an alias bomb, PNG headers of huge images, tiny images.

Every file is small on disk; what is hostile is what a careless loader would make of it.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np

__all__ = ["alias_bomb", "fake_png", "map_yaml", "png_header", "small_png"]


def png_header(width: int, height: int) -> bytes:
    """The signature and IHDR chunk of an 8-bit grey PNG of ``width`` x ``height`` pixels."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", len(ihdr))
        + chunk
        + struct.pack(">I", zlib.crc32(chunk) & 0xFFFFFFFF)
    )


def fake_png(path: Path, width: int, height: int) -> Path:
    """A PNG whose header says ``width`` x ``height`` and whose data is cut short (a few bytes)."""
    path.write_bytes(png_header(width, height) + b"\x00" * 64)
    return path


def small_png(path: Path, image: np.ndarray) -> Path:
    """Write ``image`` (uint8) as a PNG."""
    cv2.imwrite(str(path), np.asarray(image, dtype=np.uint8))
    return path


def map_yaml(folder: Path, image: str, name: str = "map", **keys: object) -> Path:
    """A map_server YAML next to ``image`` with the given keys (values written as YAML text)."""
    lines = {"image": image, "resolution": "0.05", "origin": "[0.0, 0.0, 0.0]", **keys}
    path = folder / f"{name}.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in lines.items()))
    return path


def alias_bomb(levels: int = 9, width: int = 9) -> str:
    """A "billion laughs" YAML value: ``levels`` levels of ``width`` aliases each (9 x 9: 9**9)."""
    lines = [f"a0: &a0 [{', '.join(['lol'] * width)}]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]")
    return "\n".join(lines) + "\n"
