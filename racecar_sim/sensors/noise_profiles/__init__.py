"""Named noise profiles: sets of [`EnvConfig`][racecar_sim.settings.config.EnvConfig] settings that make the
simulated sensors behave like a particular real car.

A profile is a YAML file in ``racecar_sim/sensors/noise_profiles/data/`` (package data) with a
``settings`` mapping (env settings) and, for the record, where the numbers came from
(``description``, ``source``, ``fit``). Select one with
``gym.make("RacecarSim-v0", noise_profile="mit_racecar")``; explicit settings override the
profile's. Profiles:

* ``ideal``: the simulator's defaults (the filter's own four-part beam model, mild odometry noise).
* ``mit_racecar``: fitted on the two shared MIT racecar recordings by
  ``scripts/calibrate_noise.py`` (README, "Honest noise").
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml

from racecar_sim.settings.validation import load_yaml, read_text, short, yaml_problem

__all__ = ["load_profile", "profile_document", "profile_names", "profile_path"]


def _data_dir() -> Path:
    return Path(__file__).resolve().parent / "data"


def profile_names() -> list[str]:
    """Names of the bundled profiles (sorted), ``"ideal"`` included."""
    return sorted({"ideal", *(p.stem for p in _data_dir().glob("*.yaml"))})


def profile_path(name: str | os.PathLike[str]) -> Path:
    """The YAML file of a bundled profile name, or ``name`` itself when it is a YAML path.

    Raises:
        ValueError: neither a bundled profile nor an existing YAML file (lists the names).
    """
    if not isinstance(name, str | os.PathLike):
        raise ValueError(
            f"noise_profile must be a profile name ({', '.join(profile_names())}) or a YAML path, "
            f"got {short(name)}"
        )
    if len(os.fspath(name)) > 255:
        raise ValueError(f"noise_profile {short(os.fspath(name))} is too long for a name or path")
    path = _data_dir() / f"{name}.yaml"
    if path.is_file():
        return path
    given = Path(name)
    if given.suffix in (".yaml", ".yml") and given.is_file():
        return given
    raise ValueError(
        f"noise_profile {short(str(name))} is neither a bundled profile "
        f"({', '.join(profile_names())}) nor a profile YAML file"
    )


@lru_cache(maxsize=16)
def _read(path: str) -> dict[str, Any]:
    try:
        data = load_yaml(read_text(Path(path)))
    except yaml.YAMLError as exc:
        raise ValueError(f"noise profile {path}: not valid YAML ({yaml_problem(exc)})") from None
    if not isinstance(data, dict) or not isinstance(data.get("settings"), dict):
        raise ValueError(f"noise profile {path}: expected a mapping with a 'settings' mapping")
    return data


def profile_document(name: str | os.PathLike[str]) -> dict[str, Any]:
    """The whole profile (settings, description, source, fit) as read from its YAML."""
    if str(name) == "ideal":
        return {"name": "ideal", "description": "the simulator's defaults", "settings": {}}
    return _read(str(profile_path(name)))


def load_profile(name: str | os.PathLike[str]) -> dict[str, Any]:
    """The env settings of profile ``name`` (a fresh dict; ``"ideal"`` is empty = the defaults)."""
    return dict(profile_document(name)["settings"])
