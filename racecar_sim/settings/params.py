"""Building the parameter dataclasses: from a mapping or a YAML file (unknown keys raise a
``ValueError`` naming them), nested parameter classes, settings put over other settings, and the
positive-number check they share."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from racecar_sim.settings.validation import check_number, read_yaml_mapping, short

__all__ = ["from_mapping", "from_yaml", "nested", "positive", "settings_over"]

T = TypeVar("T")


def from_mapping(cls: type[T], mapping: dict[str, Any] | None) -> T:
    """Build dataclass ``cls`` from a mapping, defaults for missing keys.

    Raises:
        ValueError: a key is not a field of ``cls``, or a value is rejected by its validation.
    """
    mapping = dict(mapping or {})
    _check_known(cls, mapping, cls.__name__)
    return cls(**mapping)


def _check_known(cls: Any, mapping: Mapping[str, Any], owner: str) -> None:
    """Raise a ValueError naming the keys of ``mapping`` that are not fields of dataclass ``cls``
    (``owner`` names it in the message), and the fields there are."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(mapping) - names)
    if unknown:
        raise ValueError(f"unknown {owner} parameter(s) {short(unknown, 200)}; known: {sorted(names)}")


def nested(value: Any, cls: type[T], owner: str) -> T:
    """A nested parameter dataclass from an instance of ``cls`` or a mapping of its fields.

    ``owner`` names the field in errors (e.g. ``"ParticleFilterParams.kld"``).

    Raises:
        ValueError: the mapping has an unknown key or a rejected value, or ``value`` is neither.
    """
    if isinstance(value, cls):
        return value
    if isinstance(value, dict) or hasattr(value, "keys"):
        try:
            return from_mapping(cls, dict(value))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{owner}: {exc}") from exc
    raise ValueError(f"{owner} must be a {cls.__name__} or a mapping, got {short(value)}")


def settings_over(base: T, settings: Mapping[str, Any], owner: str | None = None) -> T:
    """``base`` (a parameter dataclass) with the nested ``settings`` put over it.

    A mapping given for a field that holds a parameter dataclass changes only the keys it names
    (``{"filter": {"kld": {"epsilon": 0.05}}}`` keeps every other filter and KLD setting of
    ``base``); any other value replaces the field. Each changed dataclass is checked again by its
    own validation.

    Raises:
        ValueError: a key that is not a field (named, with its owner, e.g.
            ``LocalizationConfig.filter``), or a value the validation rejects.
    """
    owner = owner or type(base).__name__
    _check_known(base, settings, owner)
    changes: dict[str, Any] = {}
    for key, value in settings.items():
        current = getattr(base, key)
        if isinstance(value, Mapping) and dataclasses.is_dataclass(current):
            value = settings_over(current, value, f"{owner}.{key}")
        changes[key] = value
    try:
        return dataclasses.replace(base, **changes)  # type: ignore[type-var]
    except TypeError as exc:
        raise ValueError(f"{owner}: {exc}") from exc


def from_yaml(cls: type[T], path: str | os.PathLike[str], section: str | None = None) -> T:
    """Build dataclass ``cls`` from a YAML file (optionally from one top-level ``section``)."""
    path = Path(path)
    data = read_yaml_mapping(path)
    if section is not None:
        data = data.get(section, {}) or {}
    try:
        return from_mapping(cls, data)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"parameter file {path}: {exc}") from exc


def positive(owner: str, obj: Any, *names: str) -> None:
    for name in names:
        check_number(owner, name, getattr(obj, name), low=0.0, low_open=True)
