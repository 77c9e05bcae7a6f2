"""Validation written once: numbers in ranges and YAML files of settings, with messages that name the
field (``Owner.field``) and, for files, the file.

Every parameter dataclass of the project checks its fields with `check_number()` in
``__post_init__``, so a bad value fails once, where it is given, with one clear line.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

__all__ = [
    "MAX_YAML_BYTES",
    "YAMLRefused",
    "check_action",
    "check_number",
    "check_options",
    "check_poses",
    "check_seed",
    "describe",
    "load_yaml",
    "read_text",
    "read_yaml_mapping",
    "short",
    "yaml_problem",
]

MAX_YAML_BYTES = 1_000_000
"""Longest YAML text of settings or a map that is read (bytes): a settings file or a map_server
YAML is a few hundred bytes; more is refused before parsing, so parsing stays bounded."""

_SHORT = 40


def short(value: Any, limit: int = _SHORT) -> str:
    """``repr(value)`` on one line, cut to about ``limit`` characters (``...`` marks the cut), for
    messages that quote a value given by a user, however large it is."""
    if isinstance(value, list | tuple | dict | set) and len(value) > 16:
        text = f"<{type(value).__name__} of {len(value)} items>"
    elif isinstance(value, float) and len(repr(value)) > 12 and float(f"{value:g}") == value:
        text = f"{value:g}"  # 1e+12, not 1000000000000.0 (only when it is the same number)
    else:
        text = re.sub(r"\s*\n\s*", " ", repr(value))  # one line: an array's repr breaks lines
    return text if len(text) <= limit else text[: limit - 3] + "..."


class YAMLRefused(yaml.YAMLError):
    """A YAML text this project does not read: an anchor or alias, or one too long or too deep."""


# A number with an exponent but no dot (``1e12``, ``-2E-3``) is a float here, as in YAML 1.2;
# PyYAML (YAML 1.1) would read it as text.
_EXP_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader without anchors and aliases (no "billion laughs": every node is read
    once), with ``1e12`` read as a number."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            mark = event.start_mark
            raise YAMLRefused(
                f"anchors and aliases (&name, *name) are not read (line {mark.line + 1})"
            )
        return super().compose_node(parent, index)


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _EXP_FLOAT, list("-+0123456789"))


def load_yaml(text: str) -> Any:
    """The value of a YAML text read safely and in bounded work: no anchors or aliases, at most
    `MAX_YAML_BYTES`, nesting no deeper than Python's recursion allows; ``1e12`` is a float.

    Raises:
        yaml.YAMLError: not valid YAML, or refused (`YAMLRefused`, one line).
    """
    if len(text) > MAX_YAML_BYTES:
        raise YAMLRefused(f"{len(text)} characters, more than the {MAX_YAML_BYTES} read")
    try:
        return yaml.load(text, Loader=_Loader)
    except RecursionError:
        raise YAMLRefused("nested too deeply") from None


def yaml_problem(exc: yaml.YAMLError) -> str:
    """One short line saying what is wrong with a YAML text."""
    first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return first if len(first) <= 160 else first[:157] + "..."


def _interval(low: float, high: float, low_open: bool, high_open: bool) -> str:
    if low == 0 and low_open and high == math.inf:
        return "positive"
    if low == 0 and not low_open and high == math.inf:
        return ">= 0"
    if high == math.inf:
        return f"{'>' if low_open else '>='} {low:g}"
    if low == -math.inf:
        return f"{'<' if high_open else '<='} {high:g}"
    return f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


def check_number(
    owner: str,
    name: str,
    value: Any,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    high_open: bool = False,
    integer: bool = False,
    allow_inf: bool = False,
    unit: str = "",
) -> float | int:
    """``value`` as a float (or int with ``integer``) if it is a finite number in the range.

    Args:
        owner: what holds the field, e.g. ``"LidarParams"`` (empty: the field name alone).
        name: the field.
        value: the value given (a bool, a string or NaN is refused).
        low, high: the bounds; ``low_open`` / ``high_open`` exclude them.
        integer: require a whole number.
        allow_inf: accept +-inf (within the bounds), e.g. "no limit".
        unit: the bounds' unit, named after them in the message (e.g. ``"m"``; empty: none).

    Raises:
        ValueError: ``"Owner.name = value must be <what>"``, e.g. ``"a number in [0, 10] m"``.
    """
    field = f"{owner}.{name}" if owner else name
    kind = "an integer" if integer else "a number"
    what = _interval(low, high, low_open, high_open)
    if what == "positive":
        need = f"a positive {'integer' if integer else 'number'}"
    else:
        need = f"{kind} {what}"
    if unit:
        need = f"{need} {unit}"
    ok_type = isinstance(value, int | float) and not isinstance(value, bool)
    shown = short(value)
    if integer:
        ok_type = ok_type and float(value).is_integer() if ok_type else False
    if not ok_type or math.isnan(value) or (math.isinf(value) and not allow_inf):
        raise ValueError(f"{field} = {shown} must be {need}")
    below = value <= low if low_open else value < low
    above = value >= high if high_open else value > high
    if below or above:
        raise ValueError(f"{field} = {shown} must be {need}")
    return int(value) if integer else float(value)


def read_text(path: Path, limit: int = MAX_YAML_BYTES) -> str:
    """The text of a small file, refusing (`YAMLRefused`) one longer than ``limit`` bytes
    before reading it; bytes that are not UTF-8 are replaced."""
    size = path.stat().st_size
    if size > limit:
        raise YAMLRefused(f"{size} bytes, more than the {limit} read")
    with open(path, "rb") as f:  # at most limit + 1 bytes, whatever stat said (a device says 0)
        raw = f.read(limit + 1)
    if len(raw) > limit:
        raise YAMLRefused(f"more than the {limit} bytes read")
    return raw.decode("utf-8", errors="replace")


def read_yaml_mapping(path: str | os.PathLike[str], what: str = "parameter file") -> dict[str, Any]:
    """The mapping in a YAML file (empty file: ``{}``).

    Raises:
        ValueError: ``"<what> <path>: <problem>"`` when the file is missing, not YAML or not a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {path} not found")
    try:
        data = load_yaml(read_text(path))
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} {path}: not valid YAML ({yaml_problem(exc)})") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{what} {path}: expected a mapping of settings, got {type(data).__name__}")
    return data


def describe(value: Any) -> str:
    """A value's kind and a short quote of it, for messages (``str '12'``, ``float64 array (3,)``)."""
    if isinstance(value, np.ma.MaskedArray):
        return f"a masked {value.dtype} array of shape {value.shape}"
    if isinstance(value, np.ndarray):
        return f"a {value.dtype} array of shape {value.shape}"
    return f"{type(value).__name__} {short(value)}"


def _has_non_number(value: Any, depth: int = 0) -> bool:
    """Whether a (nested) list / tuple holds a bool, a string, bytes or a masked value anywhere
    (depth <= 2): numpy would read them as numbers."""
    for v in value:
        if isinstance(v, bool | np.bool_ | str | bytes | np.ma.MaskedArray):
            return True
        if depth < 1 and isinstance(v, list | tuple) and _has_non_number(v, depth + 1):
            return True
    return False


def check_action(action: Any, shape: tuple[int, ...], what: str = "action") -> np.ndarray:
    """``action`` as a float64 array of ``shape`` if it is numbers of that shape, all finite.

    Accepted: a numpy array of integer or float dtype, or a list / tuple (nested for 2-D) of ints
    and floats. Refused, naming what was given: strings and bytes (``"12"`` is not [1, 2]),
    booleans, mappings, other shapes, NaN and infinity, and masked arrays (numpy drops the mask
    on conversion, so a masked value would be driven as if it were a number).

    Raises:
        ValueError: one line, ``"action must be ... got <kind> <value>"``.
    """
    per_car = " per car" if len(shape) > 1 else ""
    need = f"{what} must be numbers of shape {shape} ([steer rad, speed m/s]{per_car})"
    if isinstance(action, np.ma.MaskedArray):
        raise ValueError(f"{need}, got {describe(action)} (fill it: np.ma.filled)")
    ok = isinstance(action, np.ndarray) or (
        isinstance(action, list | tuple) and not _has_non_number(action)
    )
    arr = None
    if ok:
        try:
            arr = np.asarray(action)
        except (TypeError, ValueError):
            arr = None
    if arr is None or arr.dtype.kind not in "fiu":
        raise ValueError(f"{need}, got {describe(action)}")
    if arr.shape != shape:
        given = describe(action)
        if not isinstance(action, np.ndarray):
            given += f" of shape {arr.shape}"
        raise ValueError(f"{need}, got {given}")
    out = arr.astype(np.float64)
    if not np.isfinite(out).all():
        raise ValueError(f"{what} must be finite, got {describe(action)}")
    return out


def check_options(owner: str, options: Any) -> dict[str, Any]:
    """A ``reset`` call's ``options`` as a new dict: None is ``{}``; a mapping with text keys is
    copied.

    Raises:
        ValueError: ``"<owner>: options must be a dict ..., got <kind> <value>"`` for anything
            else (a list, a string, a number), or a key that is not a string.
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(
            f"{owner}: options must be a dict of reset options or None, got {describe(options)}"
        )
    bad = [k for k in options if not isinstance(k, str)]
    if bad:
        raise ValueError(f"{owner}: options keys must be option names (str), got {short(bad[0])}")
    return dict(options)


def check_poses(what: str, value: Any, rows: int | None = None) -> np.ndarray:
    """``value`` as float64 poses [x m, y m, theta rad]: shape (3,) when ``rows`` is None, else
    (``rows``, 3); every number finite.

    Raises:
        ValueError: one line naming ``what`` and what was given (a mapping, text, bools, another
            shape, NaN or infinity).
    """
    shape = (3,) if rows is None else (rows, 3)
    need = (
        f"{what} must be three finite numbers [x, y, theta]"
        if rows is None
        else f"{what} must be a finite ({rows}, 3) array of poses [x, y, theta]"
    )
    ok = isinstance(value, np.ndarray) and not isinstance(value, np.ma.MaskedArray)
    ok = ok or (isinstance(value, list | tuple) and not _has_non_number(value))
    arr = None
    if ok:
        try:
            arr = np.asarray(value)
        except (TypeError, ValueError):
            arr = None
    if arr is None or arr.dtype.kind not in "fiu":
        raise ValueError(f"{need}, got {describe(value)}")
    if arr.shape != shape:
        raise ValueError(f"{need}, got shape {arr.shape}")
    out = arr.astype(np.float64)
    if not np.isfinite(out).all():
        raise ValueError(f"{need}, got {short(out.tolist(), 80)}")
    return out


def check_seed(owner: str, seed: Any) -> int | None:
    """``seed`` if it is None or a non-negative int (what Gymnasium seeds a generator with).

    Raises:
        ValueError: ``"<owner>: seed must be a non-negative int or None, got <value>"``.
    """
    if seed is None:
        return None
    if not isinstance(seed, int | np.integer) or isinstance(seed, bool | np.bool_) or seed < 0:
        raise ValueError(f"{owner}: seed must be a non-negative int or None, got {short(seed)}")
    return int(seed)
