"""The bounds of the filter's number settings, with the reason for each (the table that
[`ParticleFilterParams`][mcl.filter.params.ParticleFilterParams], [`SensorModelParams`][mcl.filter.sensor_params.SensorModelParams],
[`MotionModelParams`][mcl.filter.motion_model.MotionModelParams] and [`LocalizationConfig`][mcl.wrappers.localization.LocalizationConfig]
check against; docs/settings.md shows it)."""

from __future__ import annotations

import math
from typing import Any

from racecar_sim.settings.bounds import Bound, check

__all__ = ["FILTER_BOUNDS", "MAX_CASTS", "check_filter"]

MAX_PARTICLES = 1_000_000
MAX_CASTS = 10_000_000
"""Most rays one correction casts (particles x beams per particle): 66 times the default
1500 x 100 and 5 times a global start's 20 000 x 100; each cast's range and weight are held in
memory (about 16 bytes a cast), and a correction of 10 M casts takes about a second."""

_P = "a million particles take seconds an update; the lab uses 1-5 thousand"
FILTER_BOUNDS: dict[str, Bound] = {
    "filter.n_particles": Bound(1, MAX_PARTICLES, "particles", _P, integer=True),
    "filter.global_particles": Bound(1, MAX_PARTICLES, "particles", _P, integer=True),
    "filter.global_max_particles": Bound(1, MAX_PARTICLES, "particles", _P, integer=True),
    "filter.global_density": Bound(0.0, 10_000.0, "1/m^2", "a particle per square centimetre"),
    "filter.global_clearance": Bound(0.0, 10.0, "m", "more room than any corridor"),
    "filter.init_spread": Bound(0.0, 10_000.0, "m, rad", "wider than any map; use a global start"),
    "filter.update_min_distance": Bound(0.0, 100.0, "m", "a scan at least every 100 m"),
    "odometry_scale.window": Bound(0.1, 100.0, "m", "a comparison at least every 100 m"),
    "filter.update_min_angle": Bound(0.0, 2 * math.pi, "rad", "a full turn"),
    "sensor.num_beams_per_particle": Bound(
        1, 10_000, "beams", "as the lidar's n_beams", integer=True
    ),
    "sensor.table_width": Bound(
        2, 4096, "pixels", "the beam table is width^2 float64 (4096: 134 MB)", integer=True
    ),
    "sensor.alpha": Bound(0.0, 1.0, "", "a mixture weight of the beam model"),
    "sensor.sigma_hit": Bound(0.0, 1000.0, "pixels", "wider than the table", low_open=True),
    "sensor.squash_exponent": Bound(
        0.0, 10.0, "", "1/2.2 in the lab; 10 sharpens beyond use", low_open=True
    ),
    "sensor.lidar_scale_to_map_scale": Bound(
        0.0, 100.0, "", "a scale factor near 1", low_open=True
    ),
    "sensor.mount_offset": Bound(-5.0, 5.0, "m", "on the car"),
    "sensor.fov": Bound(0.0, 2 * math.pi, "rad", "a full turn", low_open=True),
    "sensor.max_range": Bound(0.0, 1000.0, "m", "as the lidar's max_range", low_open=True),
    "sensor.likelihood_sigma": Bound(
        0.0, 100.0, "m", "wider than any map's features", low_open=True
    ),
    "sensor.likelihood_z_hit": Bound(0.0, 1.0, "", "a mixture weight", low_open=True),
    "sensor.likelihood_z_rand": Bound(0.0, 1.0, "", "a mixture weight"),
    "sensor.likelihood_max_distance": Bound(
        0.0, 100.0, "m", "the distance field's cut-off", low_open=True
    ),
    "sensor.likelihood_max_range": Bound(0.0, 1000.0, "m", "as max_range", low_open=True),
    "sensor.lut_sort_extent": Bound(
        0.0,
        math.inf,
        "m",
        "inf never sorts; a tracking cloud spans about 3.5 m, a global one the floor",
        allow_inf=True,
    ),
    "motion.coefficients": Bound(
        0.0, 10.0, "m, rad per update", "10 m of noise per update is no odometry"
    ),
    "motion.search_coefficients": Bound(
        0.0, 10.0, "m, rad per update", "10 m of noise per update is no odometry"
    ),
    "motion.alphas": Bound(
        0.0,
        100.0,
        "variance per motion",
        "amcl's defaults are 0.2 and below; 100 spreads a metre's move over ten metres",
    ),
    "render_particles": Bound(0, MAX_PARTICLES, "particles", "as n_particles", integer=True),
}
"""Filter setting (``filter.``, ``sensor.``, ``motion.``) -> its bound."""


def check_filter(owner: str, name: str, value: Any, key: str) -> float | int:
    """``value`` checked against ``FILTER_BOUNDS[key]`` (one line naming ``owner.name``)."""
    return check(owner, name, value, key, FILTER_BOUNDS)
