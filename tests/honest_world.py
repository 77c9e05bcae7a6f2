"""The honest world of ``docs/localization_changing_world.md`` for tests that record a drive in it:
the car in ``../shared/maps/basement_fixed_aligned.yaml`` with the ``mit_racecar`` noise, the
filter holding the out-of-date ``stata_basement.yaml``, the wall follower (skips without
``../shared``)."""

from __future__ import annotations

from mcl.experiments.recorded import RecordedDrive, record_drive
from tests.skips import need_shared


def honest_drive(scene: str, seed: int, duration: float, kidnap_at: float | None = None) -> RecordedDrive:
    """A drive of ``duration`` seconds in ``scene`` (``"cluttered"`` or ``"clean"``) from ``seed``,
    the car carried elsewhere at ``kidnap_at`` seconds (None: never)."""
    world, old = need_shared("maps/basement_fixed_aligned.yaml", "maps/stata_basement.yaml")
    return record_drive(world, filter_map=old, scene=scene, noise_profile="mit_racecar", driver="wall",
                        seed=seed, duration=duration, kidnap_at=kidnap_at)  # fmt: skip
