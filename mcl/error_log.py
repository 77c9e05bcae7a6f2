"""Per-step localization error log: a CSV written row by row and flushed, and its reader.

Columns (:data:`HEADER`), one row per env step:

``step`` (1, 2, ... since reset), ``time`` (seconds since reset), ``x_true, y_true, theta_true``
(true world pose of the rear axle, metres, radians), ``x_est, y_est, theta_est`` (the filter's
estimate, same frame and units), ``position_error`` (metres), ``heading_error`` (radians, wrapped
to [-pi, pi), estimate minus truth), ``n_eff`` (effective sample size after the step's weight
update, before any resampling), ``update_s`` (seconds of wall time the filter update took).

Every row is flushed to the operating system as soon as it is written, so a run that is killed
(even with SIGKILL) leaves a file holding every row completed before it died. The reader ignores a
last line that was cut short.
"""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["HEADER", "ErrorLog", "ErrorLogWriter", "count_rows", "read_error_log"]

HEADER: tuple[str, ...] = (
    "step",
    "time",
    "x_true",
    "y_true",
    "theta_true",
    "x_est",
    "y_est",
    "theta_est",
    "position_error",
    "heading_error",
    "n_eff",
    "update_s",
)
"""The CSV columns, in order."""

_HEADER_LINE = ",".join(HEADER)


def _fmt(value: float) -> str:
    """A float with enough digits to round-trip poses to well below a micrometre."""
    v = float(value)
    if math.isnan(v):
        return "nan"
    return f"{v:.10g}"


class ErrorLogWriter:
    """Writes the error log to ``path`` (created with its parents, truncated), flushing each row.

    Usable as a context manager. The header is written (and flushed) on opening.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: io.TextIOWrapper | None = open(
            self.path, "w", encoding="utf-8", newline="", buffering=1
        )
        self._write_line(_HEADER_LINE)
        self.n_rows = 0

    def _write_line(self, line: str) -> None:
        if self._file is None:
            raise ValueError(f"error log {self.path} is closed")
        self._file.write(line + "\n")  # one write per row: a kill cannot split a row's fields
        self._file.flush()

    def write(
        self,
        step: int,
        time: float,
        true_pose: np.ndarray,
        estimate: np.ndarray,
        position_error: float,
        heading_error: float,
        n_eff: float,
        update_s: float,
    ) -> None:
        """Append one row (see the module docstring for units and frames) and flush it."""
        values = (
            float(time),
            *np.asarray(true_pose, dtype=np.float64).reshape(3),
            *np.asarray(estimate, dtype=np.float64).reshape(3),
            position_error,
            heading_error,
            n_eff,
            update_s,
        )
        self._write_line(",".join([str(int(step)), *(_fmt(v) for v in values)]))
        self.n_rows += 1

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._file is None

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> ErrorLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class ErrorLog:
    """The columns of an error log as float64 arrays (``step`` as int64), all of length n.

    Attributes are named as in :data:`HEADER`; ``truncated`` tells whether a cut-short last line
    was dropped.
    """

    step: np.ndarray
    time: np.ndarray
    x_true: np.ndarray
    y_true: np.ndarray
    theta_true: np.ndarray
    x_est: np.ndarray
    y_est: np.ndarray
    theta_est: np.ndarray
    position_error: np.ndarray
    heading_error: np.ndarray
    n_eff: np.ndarray
    update_s: np.ndarray
    truncated: bool = False

    def __len__(self) -> int:
        return int(self.step.shape[0])

    @property
    def true_poses(self) -> np.ndarray:
        """(n, 3) true world poses [x, y, theta]."""
        return np.column_stack([self.x_true, self.y_true, self.theta_true])

    @property
    def estimates(self) -> np.ndarray:
        """(n, 3) estimated world poses [x, y, theta]."""
        return np.column_stack([self.x_est, self.y_est, self.theta_est])


def _split_rows(path: Path) -> tuple[list[list[str]], bool]:
    """Data rows of a log as lists of fields, and whether a cut-short last line was dropped."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"error log {path} not found") from None
    lines = text.split("\n")
    if not lines or lines[0].strip() != _HEADER_LINE:
        raise ValueError(
            f"error log {path}: first line {lines[0][:200]!r} is not the header {_HEADER_LINE!r}"
        )
    # A complete row ends with "\n", so the piece after the last "\n" is either empty or cut short.
    body, tail = lines[1:-1], lines[-1]
    truncated = tail != ""
    rows = [line.split(",") for line in body if line]
    for i, row in enumerate(rows):
        if len(row) != len(HEADER):
            raise ValueError(
                f"error log {path}: data row {i + 1} has {len(row)} fields, expected {len(HEADER)}"
            )
    return rows, truncated


def read_error_log(path: str | os.PathLike[str]) -> ErrorLog:
    """Read a log written by :class:`ErrorLogWriter`; a last line cut short (killed run) is dropped.

    Raises:
        ValueError: the file is missing, its header differs from :data:`HEADER`, or a complete
            row has the wrong number of fields or a field that is not a number (named).
    """
    path = Path(path)
    rows, truncated = _split_rows(path)
    try:
        data = np.array(rows, dtype=np.float64).reshape(len(rows), len(HEADER))
    except ValueError as exc:
        raise ValueError(f"error log {path}: a field is not a number ({exc})") from None
    columns = {name: data[:, i] for i, name in enumerate(HEADER)}
    columns["step"] = columns["step"].astype(np.int64)
    return ErrorLog(**columns, truncated=truncated)


def count_rows(path: str | os.PathLike[str]) -> int:
    """Number of complete data rows in a log; 0 when the file is missing or not an error log."""
    try:
        rows, _ = _split_rows(Path(path))
    except ValueError:
        return 0
    return len(rows)
