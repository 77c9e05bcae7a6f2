"""The sensor-model benchmark's real-bag part runs and reports what the README says of it."""

from __future__ import annotations

import re

import pytest

from tests.io.bag_fixtures import BAG1, shared_bag


@pytest.mark.slow
def test_bag_comparison_on_a_real_bag(capsys) -> None:
    """Tracking from the global filter's pose: both models fit most beams; from an unknown start
    the beam model finds the car and the likelihood field alone does not."""
    from mcl.bench.sensor_models import bag_comparison

    bag_comparison(shared_bag(BAG1))
    out = capsys.readouterr().out
    tracked = dict(re.findall(r"\.bag: (beam|likelihood field)[^:]*: scan_fit median ([0-9.]+)", out))
    assert float(tracked["beam"]) > 0.8 and float(tracked["likelihood field"]) > 0.7, out
    beam, field = re.search(r"beam model scan_fit median ([0-9.]+); likelihood field ([0-9.]+)", out).groups()
    assert float(beam) > 0.7 > 0.2 > float(field), out
