"""Settings put over other settings (`racecar_sim.settings.params.settings_over`): what a command's
``--filter`` does to a filter that is not the defaults (the replay's adaptive filter)."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.experiments.replay import unknown_start_localization
from mcl.wrappers.localization import LocalizationConfig, dotted_settings
from racecar_sim.settings.params import settings_over

BASE = unknown_start_localization()


def _leaves(value, prefix=""):
    """Every non-dataclass field of a (nested) dataclass, by its dotted name."""
    if not dataclasses.is_dataclass(value):
        return {prefix: value}
    found = {}
    for field in dataclasses.fields(value):
        found.update(_leaves(getattr(value, field.name), f"{prefix}.{field.name}" if prefix else field.name))
    return found


@settings(max_examples=25, deadline=None)
@given(
    epsilon=st.floats(0.001, 0.5, allow_nan=False),
    sigma_hit=st.floats(0.05, 5.0, allow_nan=False),
    track=st.integers(1, 3000),  # at most the tracking cloud's bound (AdaptiveParams)
)
def test_only_the_named_settings_change(epsilon, sigma_hit, track):
    items = [f"filter.kld.epsilon={epsilon!r}", f"sensor.sigma_hit={sigma_hit!r}",
             f"adaptive.track_min_particles={track}"]  # fmt: skip
    changed = settings_over(BASE, dotted_settings(items))
    before, after = _leaves(BASE), _leaves(changed)
    assert after.pop("filter.kld.epsilon") == epsilon
    assert after.pop("sensor.sigma_hit") == sigma_hit
    assert after.pop("adaptive.track_min_particles") == track
    for name in ("filter.kld.epsilon", "sensor.sigma_hit", "adaptive.track_min_particles"):
        before.pop(name)
    assert after == before  # the replay's own settings (KLD on, 300 000 global cap...) are kept


def test_settings_checked_together_may_be_changed_together():
    """A lower bound above the upper one's default is refused alone and taken with the upper one."""
    changed = settings_over(BASE, dotted_settings(["adaptive.track_min_particles=4000",
                                                   "adaptive.track_max_particles=6000"]))  # fmt: skip
    assert (changed.adaptive.track_min_particles, changed.adaptive.track_max_particles) == (4000, 6000)


def test_the_base_is_not_the_defaults():
    """Over the replay's filter, an unrelated setting keeps what the replay chose, which the
    defaults would not (``as_localization_config`` of the same mapping starts from the defaults)."""
    changed = settings_over(BASE, {"sensor": {"sigma_hit": 2.0}})
    assert changed.filter.kld.enabled and changed.adaptive is not None
    assert changed.filter.global_max_particles == 300_000
    assert not LocalizationConfig().filter.kld.enabled


@pytest.mark.parametrize(
    ("mapping", "message"),
    [
        ({"filter": {"kdl": 1}}, "unknown LocalizationConfig.filter parameter(s) ['kdl']"),
        ({"filtre": 1}, "unknown LocalizationConfig parameter(s) ['filtre']"),
        ({"filter": {"kld": 5}}, "ParticleFilterParams.kld must be a KLDParams or a mapping"),
        ({"filter": {"n_particles": -1}}, "ParticleFilterParams.n_particles = -1"),
        ({"filter": {"kld": {"max_particles": 400}}}, "KLDParams.max_particles = 400"),
        ({"adaptive": {"track_min_particles": 4000}}, "track_max_particles must be >= track_min"),
    ],
)
def test_bad_settings_are_named(mapping, message):
    with pytest.raises(ValueError) as exc:
        settings_over(BASE, mapping)
    assert message in str(exc.value)
