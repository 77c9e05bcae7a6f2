"""Per-step localization error log: a CSV written row by row and flushed, and its reader.

Columns (`HEADER`), one row per env step:

``step`` (1, 2, ... since reset), ``time`` (seconds since reset), ``x_true, y_true, theta_true``
(true world pose of the rear axle, metres, radians), ``x_est, y_est, theta_est`` (the filter's
estimate, same frame and units), ``position_error`` (metres), ``heading_error`` (radians, wrapped
to [-pi, pi), estimate minus truth), ``n_eff`` (effective sample size after the step's weight
update, before any resampling), ``update_s`` (seconds of wall time the filter update took),
``lost`` (1 when the filter's lost flag was up after the step, else 0;
[LostDetector][mcl.filter.lost.LostDetector]).

Every row is flushed to the operating system as soon as it is written, so a run that is killed
(even with SIGKILL) leaves a file holding every row completed before it died. The reader ignores a
last line that was cut short.
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from racecar_sim.file_guard import starts_with, writable

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
    "lost",
)
"""The CSV columns, in order."""

_HEADER_LINE = ",".join(HEADER)
_OLD_HEADER_LINE = ",".join(HEADER[:-1])  # logs written before the lost column: read as never lost


def _fmt(value: float) -> str:
    """A float with enough digits to round-trip poses to well below a micrometre."""
    v = float(value)
    if math.isnan(v):
        return "nan"
    return f"{v:.10g}"


class ErrorLogWriter:
    """Writes the error log to ``path`` (created with its parents, truncated), flushing each row.

    Usable as a context manager. The header is written (and flushed) on opening. An existing file
    is replaced only when it is an error log (its first line is the header) or lies in one of
    racecar-sim's folders ([writable][racecar_sim.file_guard.writable]).

    Raises:
        FileExistsError: ``path`` is another file
            ([NotOurs][racecar_sim.file_guard.NotOurs]).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = writable(path, starts_with((_HEADER_LINE + "\n").encode()))
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
        lost: bool = False,
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
            float(bool(lost)),
        )
        self._write_line(",".join([str(int(step)), *(_fmt(v) for v in values)]))
        self.n_rows += 1

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
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

    Attributes are named as in `HEADER` (``lost`` as bool); ``truncated`` tells whether a cut-short last line
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
    lost: np.ndarray | None = None
    truncated: bool = False

    def __post_init__(self) -> None:
        if self.lost is None:  # built without the column: never lost
            object.__setattr__(self, "lost", np.zeros(self.step.shape[0], dtype=np.bool_))

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


_BLOCK_ROWS = 1024
"""Rows parsed together: the reader holds one block of text fields at a time, never the file's."""


def _row_blocks(path: Path) -> Iterator[list[list[str]] | None]:
    """Blocks of at most `_BLOCK_ROWS` data rows of a log, as lists of fields, read as the
    file streams by. The last item is None when a cut-short last line was dropped.

    A complete row ends with ``"\\n"``, so a last line without one was cut short (killed run).
    """
    try:
        f = open(path, encoding="utf-8", newline="")
    except FileNotFoundError:
        raise ValueError(f"error log {path} not found") from None
    with f:
        first = f.readline()
        if first.strip() not in (_HEADER_LINE, _OLD_HEADER_LINE):
            raise ValueError(
                f"error log {path}: first line {first[:200]!r} is not the header {_HEADER_LINE!r}"
            )
        width = len(first.strip().split(","))
        block: list[list[str]] = []
        n = 0
        for line in f:
            if not line.endswith("\n"):
                if block:
                    yield block
                yield None
                return
            if line == "\n":
                continue
            row = line[:-1].split(",")
            n += 1
            if len(row) != width:
                raise ValueError(
                    f"error log {path}: data row {n} has {len(row)} fields, expected {width}"
                )
            block.append(row if width == len(HEADER) else [*row, "0"])
            if len(block) == _BLOCK_ROWS:
                yield block
                block = []
        if block:
            yield block


def read_error_log(path: str | os.PathLike[str]) -> ErrorLog:
    """Read a log written by `ErrorLogWriter`; a last line cut short (killed run) is dropped.

    The file is parsed in blocks of rows, so reading it takes about twice the memory of its columns
    (13 float64 values, 104 bytes, per row), not the ~1.2 KB per row of its text split into fields.

    Raises:
        ValueError: the file is missing, its header differs from `HEADER`, or a complete
            row has the wrong number of fields or a field that is not a number (named).
    """
    path = Path(path)
    parts: list[np.ndarray] = []
    truncated = False
    for block in _row_blocks(path):
        if block is None:
            truncated = True
            break
        try:
            parts.append(np.array(block, dtype=np.float64))
        except ValueError as exc:
            raise ValueError(f"error log {path}: a field is not a number ({exc})") from None
    if parts:
        data = np.concatenate(parts) if len(parts) > 1 else parts[0]
    else:
        data = np.empty((0, len(HEADER)))
    del parts
    columns = {name: data[:, i] for i, name in enumerate(HEADER)}
    columns["step"] = columns["step"].astype(np.int64)
    columns["lost"] = columns["lost"] > 0.5
    return ErrorLog(**columns, truncated=truncated)


def count_rows(path: str | os.PathLike[str]) -> int:
    """Number of complete data rows in a log; 0 when the file is missing or not an error log."""
    try:
        return sum(len(block) for block in _row_blocks(Path(path)) if block is not None)
    except ValueError:
        return 0
