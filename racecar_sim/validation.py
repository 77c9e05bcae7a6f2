"""Validation written once: numbers in ranges and YAML files of settings, with messages that name the
field (``Owner.field``) and, for files, the file.

Every parameter dataclass of the project checks its fields with :func:`check_number` in
``__post_init__``, so a bad value fails once, where it is given, with one clear line.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import yaml

__all__ = ["check_number", "read_yaml_mapping"]


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
) -> float | int:
    """``value`` as a float (or int with ``integer``) if it is a finite number in the range.

    Args:
        owner: what holds the field, e.g. ``"LidarParams"`` (empty: the field name alone).
        name: the field.
        value: the value given (a bool, a string or NaN is refused).
        low, high: the bounds; ``low_open`` / ``high_open`` exclude them.
        integer: require a whole number.
        allow_inf: accept +-inf (within the bounds), e.g. "no limit".

    Raises:
        ValueError: ``"Owner.name = value must be <what>"``.
    """
    field = f"{owner}.{name}" if owner else name
    kind = "an integer" if integer else "a number"
    what = _interval(low, high, low_open, high_open)
    if what == "positive":
        need = f"a positive {'integer' if integer else 'number'}"
    else:
        need = f"{kind} {what}"
    ok_type = isinstance(value, int | float) and not isinstance(value, bool)
    if integer:
        ok_type = ok_type and float(value).is_integer() if ok_type else False
    if not ok_type or math.isnan(value) or (math.isinf(value) and not allow_inf):
        raise ValueError(f"{field} = {value!r} must be {need}")
    below = value <= low if low_open else value < low
    above = value >= high if high_open else value > high
    if below or above:
        raise ValueError(f"{field} = {value!r} must be {need}")
    return int(value) if integer else float(value)


def read_yaml_mapping(path: str | os.PathLike[str], what: str = "parameter file") -> dict[str, Any]:
    """The mapping in a YAML file (empty file: ``{}``).

    Raises:
        ValueError: ``"<what> <path>: <problem>"`` when the file is missing, not YAML or not a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {path} not found")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ValueError(f"{what} {path}: not valid YAML ({first})") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{what} {path}: expected a mapping of settings, got {type(data).__name__}")
    return data
