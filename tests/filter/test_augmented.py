"""Augmented MCL's likelihood averages and injection probability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.filter.augmented import AugmentedParams, LikelihoodAverages

ON = AugmentedParams(alpha_slow=0.01, alpha_fast=0.2)


def test_per_beam_likelihood_undoes_beams_and_squash() -> None:
    # 50 beams, each with likelihood 0.04 before a squash of 0.5: log mean = 50 * 0.5 * log 0.04
    log_mean = 50 * 0.5 * math.log(0.04)
    assert LikelihoodAverages.per_beam(log_mean, 50, 0.5) == pytest.approx(0.04)
    assert LikelihoodAverages.per_beam(-math.inf, 50) == 0.0
    assert LikelihoodAverages.per_beam(-3.0, 0) == 1.0  # no beam: no information


def test_off_never_injects() -> None:
    avg = LikelihoodAverages(AugmentedParams())
    for w in (0.2, 0.2, 0.001, 0.0):
        avg.update(math.log(w) if w > 0 else -math.inf, 1)
    assert avg.injection_probability == 0.0


def test_a_drop_in_likelihood_injects_in_proportion() -> None:
    avg = LikelihoodAverages(ON)
    for _ in range(500):
        avg.update(math.log(0.2), 1)
    assert avg.w_slow == pytest.approx(0.2) and avg.w_fast == pytest.approx(0.2)
    assert avg.injection_probability == 0.0
    for _ in range(30):  # kidnapped: the scans fit 4x worse per beam
        avg.update(math.log(0.05), 1)
    assert avg.w_fast < 0.06 and avg.w_slow > 0.13
    assert avg.injection_probability == pytest.approx(1 - avg.w_fast / avg.w_slow)
    assert avg.injection_probability > 0.5
    for _ in range(100):  # found again: the fast average recovers first, no more injection
        avg.update(math.log(0.2), 1)
    assert avg.injection_probability == 0.0
    avg.reset()
    assert math.isnan(avg.w_slow) and avg.injection_probability == 0.0


def test_the_averages_start_as_running_means() -> None:
    avg = LikelihoodAverages(AugmentedParams(alpha_slow=0.001, alpha_fast=0.1))
    values = np.linspace(0.1, 0.3, 9)  # 9 updates: 1/n > alpha_fast throughout
    for w in values:
        avg.update(math.log(w), 1)
    assert avg.w_slow == pytest.approx(values.mean())
    assert avg.w_fast == pytest.approx(values.mean())


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(1e-6, 1.0), min_size=1, max_size=60))
def test_probability_is_a_probability(values) -> None:
    avg = LikelihoodAverages(ON)
    for w in values:
        avg.update(math.log(w), 10, 0.5)
        assert 0.0 <= avg.injection_probability <= 1.0


def test_bad_alphas_are_named() -> None:
    with pytest.raises(ValueError, match="alpha_fast"):
        AugmentedParams(alpha_slow=0.1, alpha_fast=0.05)
    with pytest.raises(ValueError, match="alpha_slow"):
        AugmentedParams(alpha_slow=-0.1, alpha_fast=0.05)
