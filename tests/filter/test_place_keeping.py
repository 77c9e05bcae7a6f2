"""Resampling that keeps rival places ([mcl.filter.place_keeping][]): every place with weight keeps
particles, the belief's weights are carried by importance weights, and a place plain resampling
drops is kept."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.place_keeping import PlaceKeeping, place_index, resample_keeping_places
from mcl.filter.resampling import systematic


def _cloud(rng: np.random.Generator, n: int, side: float) -> np.ndarray:
    return np.c_[rng.uniform(-side, side, n), rng.uniform(-side, side, n), rng.uniform(-4, 4, n)]


@settings(max_examples=60)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(50, 3000),
    side=st.floats(1.0, 30.0),
    sharpness=st.floats(0.0, 500.0),
    draws=st.floats(0.5, 8.0),
    share=st.floats(0.05, 0.9),
)
def test_every_place_keeps_its_draws_and_one_weight(seed, n, side, sharpness, draws, share):
    rng = np.random.default_rng(seed)
    particles = _cloud(rng, n, side)
    log_weights = -sharpness * np.hypot(particles[:, 0] - 1.0, particles[:, 1]) ** 2
    keeping = PlaceKeeping(draws=draws, share=share)
    drawn, new = resample_keeping_places(particles, log_weights, rng, n, keeping)
    assert drawn.shape == new.shape == (n,)
    assert math.isclose(np.exp(new).sum(), 1.0, rel_tol=1e-9)
    place = place_index(particles, keeping)
    places = int(place.max()) + 1
    counts = np.bincount(place[drawn], minlength=places)
    assert counts.min() >= math.floor(min(draws, share * n / places) + 1e-9)
    # within a place the proposal is the weight times one factor: one log-weight per place
    for p in np.unique(place[drawn]):
        mine = new[place[drawn] == p]
        assert np.ptp(mine) <= 1e-9 * max(1.0, abs(mine).max())


def test_the_weighted_belief_stays_where_it_was():
    rng = np.random.default_rng(3)
    particles = _cloud(rng, 4000, 20.0)
    log_weights = -2.0 * np.hypot(particles[:, 0] - 4.0, particles[:, 1] + 3.0) ** 2
    w = np.exp(log_weights - log_weights.max())
    w /= w.sum()
    before = (w[:, None] * particles[:, :2]).sum(axis=0)
    drawn, new = resample_keeping_places(particles, log_weights, rng, 4000, PlaceKeeping())
    after = (np.exp(new)[:, None] * particles[drawn, :2]).sum(axis=0)
    assert np.hypot(*(after - before)) < 0.05  # the drawn cloud's spread is about 0.5 m


def test_a_place_plain_resampling_drops_is_kept():
    rng = np.random.default_rng(1)
    particles = np.r_[np.tile([[0.5, 0.5, 0.1]], (990, 1)), np.tile([[30.5, 0.5, 0.1]], (10, 1))]
    log_weights = np.r_[np.zeros(990), np.full(10, -40.0)]  # the far place: e^-40 of the weight
    plain = systematic(np.exp(log_weights) / np.exp(log_weights).sum(), rng, 1000)
    assert not (plain >= 990).any()
    drawn, new = resample_keeping_places(particles, log_weights, rng, 1000, PlaceKeeping(draws=4))
    far = drawn >= 990
    assert far.sum() == 4
    # its weight is still e^-40 of the near place's: the estimate does not move
    ratio = np.exp(new[far]).sum() / np.exp(new[~far]).sum()
    assert math.isclose(ratio, 10 * math.exp(-40.0) / 990, rel_tol=1e-6)


def test_impossible_particles_get_no_draws():
    rng = np.random.default_rng(2)
    particles = _cloud(rng, 500, 10.0)
    log_weights = np.where(particles[:, 0] > 0, 0.0, -np.inf)
    drawn, new = resample_keeping_places(particles, log_weights, rng, 500, PlaceKeeping())
    assert (particles[drawn, 0] > 0).all()
    assert np.isfinite(new).all()


@pytest.mark.parametrize(
    ("field", "value"),
    [("cell_m", 0.0), ("cell_m", math.nan), ("headings", 0), ("headings", 2.5), ("draws", -1.0),
     ("share", 1.0), ("share", 0.0), ("draws", True)],
)
def test_bad_settings_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=f"PlaceKeeping.{field}"):
        PlaceKeeping(**{field: value})
