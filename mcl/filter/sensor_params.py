"""The sensor model's settings (`SensorModelParams`): which model, the beam table's mixture,
the beams used per particle, the caster and the range (metres), validated once.

See `mcl.filter.sensor_model` for what each setting does to the likelihood.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mcl.filter.bounds import check_filter
from racecar_sim.settings.config import LidarParams
from racecar_sim.settings.validation import short

__all__ = ["MODELS", "SensorModelParams"]

_LIDAR = LidarParams()

MODELS: tuple[str, ...] = ("beam", "likelihood_field")
"""Names accepted by `SensorModelParams.model`."""


@dataclass(frozen=True)
class SensorModelParams:
    """Parameters of the beam sensor model (defaults: the MIT RSS localization lab).

    Attributes:
        alpha_hit: weight of the Gaussian hit around the expected range.
        alpha_short: weight of short returns (unmapped obstacles).
        alpha_max: weight of max-range drop-outs.
        alpha_rand: weight of uniformly random returns.
        sigma_hit: standard deviation of the hit Gaussian, in pixels (table cells): 2 cells, 0.1 m on
            a 0.05 m map (the MIT lab used 8; the real Hokuyo's hits spread 0.05 m about the Stata
            map, and 8 cells let clutter pull the estimate: docs/localization_changing_world.md).
        search_sigma_hit: pixels; the hit spread while the filter searches (None: ``sigma_hit``
            always). A particle a few decimetres from the car must still score for a global start or
            a kidnap's random particles to find it, so the search uses the lab's 8 cells.
        search_spread: metres; a searching filter tracks again once its cloud's position standard
            deviation (square root of the covariance's xy trace) is below this.
        search_start_spread: metres; a tracking filter searches when its cloud's position standard
            deviation exceeds this (a global start), or when random particles have just joined the
            cloud (augmented MCL, recovery). Between the two the filter keeps its mode.
        table_width: number of table rows and columns; z_max = table_width - 1 pixels.
        max_range: metres of the table's last cell (the beam model's range: measured and expected
            ranges beyond it land in the max-range cell). None = ``z_max`` map cells, i.e.
            ``z_max x resolution x lidar_scale_to_map_scale`` (10 m on a 0.05 m map, the lab's).
            When given, the table keeps its ``table_width`` cells, each ``max_range / z_max``
            metres wide, and ``sigma_hit`` (in cells) widens with them: scale it by the ratio of
            the cell sizes to keep its metres.
        squash_exponent: the product over beams is raised to this power (1/2.2 in the lab).
        lidar_scale_to_map_scale: lidar metres per map metre (ranges are divided by it, with the
            resolution, to get pixels).
        num_beams_per_particle: beams used per particle, evenly spaced over the scan.
        raycast_method: [`racecar_sim.raycast.RayCaster`][racecar_sim.raycast.RayCaster] method for the expected ranges
            (an approximate one is fine: the simulated lidar stays exact).
        lut_sort_extent: metres; with the ``"lut"`` caster, a cloud whose bounding box is at
            least this wide (on either axis) is cast in Z-order of its cells and the scores
            scattered back (``LutParams.sort_extent``): the same numbers, fewer cache misses when
            the particles are spread over the map (a global start). ``.inf`` (YAML) never sorts.
        mount_offset: metres from the rear axle (the particle pose) forward to the lidar.
        fov: radians spanned by the scan when the beam angles are not given (first beam at -fov/2).
        parallel: numba threads for casting and scoring: None decides by size (the caster's
            ``PARALLEL_MIN_RAYS``, `PARALLEL_MIN_LOOKUPS`); False keeps one thread, which is
            faster when other processes keep the cores busy (e.g. a pool of experiment workers);
            True always uses every thread.
        model: ``"beam"`` (the table above, with ray casting) or ``"likelihood_field"`` (beam end
            points scored on the map's distance field, no casting; [`mcl.filter.likelihood_field`][mcl.filter.likelihood_field]).
            The ``likelihood_*`` fields are the latter's (amcl's defaults); it reads as many beams
            as ``num_beams_per_particle`` allows, so set that to the scan's length for all beams.
        likelihood_sigma: metres, standard deviation of the end point's distance to a wall.
        likelihood_z_hit: weight of the Gaussian term.
        likelihood_z_rand: weight of random returns (density ``z_rand / likelihood_max_range``).
        likelihood_max_distance: metres; distances to a wall are clipped to it.
        likelihood_max_range: metres; beams at or beyond it (no return) are skipped.
        beam_skip: leave out, once the cloud has converged, the beams most particles cannot
            explain (ROS amcl's ``do_beamskip``, here in the beam model; `mcl.filter.beam_skip`).
            Off by default; the beam model only.
        beam_skip_distance: metres; a particle explains a beam whose expected range lies this
            close to the measured one (amcl's default 0.5).
        beam_skip_threshold: fraction of the particles that must explain a beam for it to be
            used (amcl's default 0.3).
        beam_skip_error_threshold: fraction of the beams at or beyond which, when that many
            would be skipped, every beam is used instead (amcl's default 0.9).
        beam_skip_converged_distance: metres; the cloud counts as converged when every particle
            lies this close to the particles' mean in x and in y (amcl's 0.5).
        beam_skip_short_only: skip only beams that return short of what the particles expect
            (what an occluding opponent makes); not in amcl.
        beam_bound: while the cloud tracks (not searching), a beam's log-likelihood counts at
            most this far under the cloud's best for that beam (natural log, after the squash;
            the table's hit peak lies about 2.5 above its floor), so no beam outvotes the rest
            where the map is out of date (`mcl.filter.beam_bound`). None: the plain sum. The
            beam model only; not with beam skipping (both leave out what most particles
            cannot explain: choose one).
    """

    alpha_hit: float = 0.74
    alpha_short: float = 0.07
    alpha_max: float = 0.07
    alpha_rand: float = 0.12
    sigma_hit: float = 2.0
    search_sigma_hit: float | None = 8.0
    search_spread: float = 0.15
    search_start_spread: float = 1.0
    table_width: int = 201
    max_range: float | None = None
    squash_exponent: float = 1.0 / 2.2
    lidar_scale_to_map_scale: float = 1.0
    num_beams_per_particle: int = 100
    raycast_method: str = "lut"
    lut_sort_extent: float = 10.0
    mount_offset: float = _LIDAR.mount_offset
    fov: float = _LIDAR.fov
    parallel: bool | None = None
    model: str = "beam"
    likelihood_sigma: float = 0.2
    likelihood_z_hit: float = 0.95
    likelihood_z_rand: float = 0.05
    likelihood_max_distance: float = 2.0
    likelihood_max_range: float = _LIDAR.max_range
    beam_skip: bool = False
    beam_skip_distance: float = 0.5
    beam_skip_threshold: float = 0.3
    beam_skip_error_threshold: float = 0.9
    beam_skip_converged_distance: float = 0.5
    beam_skip_short_only: bool = False
    beam_bound: float | None = None

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"SensorModelParams.{name} = {short(getattr(self, name))}: {why}")

        alphas = ("alpha_hit", "alpha_short", "alpha_max", "alpha_rand")
        for name in (
            *alphas,
            "sigma_hit",
            "squash_exponent",
            "lidar_scale_to_map_scale",
            "mount_offset",
            "fov",
            "likelihood_sigma",
            "likelihood_z_hit",
            "likelihood_z_rand",
            "likelihood_max_distance",
            "likelihood_max_range",
            "beam_skip_distance",
            "beam_skip_threshold",
            "beam_skip_error_threshold",
            "beam_skip_converged_distance",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise bad(name, "must be a number")
            if not math.isfinite(value):
                raise bad(name, "must be finite")
        for name in alphas:
            if getattr(self, name) < 0:
                raise bad(name, "must be >= 0")
        if self.alpha_hit + self.alpha_max + self.alpha_rand <= 0:
            raise ValueError(
                "SensorModelParams: alpha_hit, alpha_max and alpha_rand must not all be zero "
                "(the d = 0 column of the table would be empty)"
            )
        mr = self.max_range
        if mr is not None and (
            isinstance(mr, bool) or not isinstance(mr, int | float) or not 0 < mr < math.inf
        ):
            raise bad("max_range", "must be None or a positive number of metres")
        ss = self.search_sigma_hit
        if ss is not None and (
            isinstance(ss, bool) or not isinstance(ss, int | float) or not 0 < ss <= 1000
        ):
            raise bad("search_sigma_hit", "must be None or a number of pixels in (0, 1000]")
        for name in ("search_spread", "search_start_spread"):
            sp = getattr(self, name)
            if isinstance(sp, bool) or not isinstance(sp, int | float) or not 0 <= sp < math.inf:
                raise bad(name, "must be a number of metres >= 0")
        if self.search_start_spread < self.search_spread:
            raise bad("search_start_spread", "must be >= search_spread")
        if self.model not in MODELS:
            raise bad("model", f"must be one of {MODELS}")
        if self.likelihood_z_rand < 0:
            raise bad("likelihood_z_rand", "must be >= 0")
        for name in (
            "sigma_hit",
            "squash_exponent",
            "lidar_scale_to_map_scale",
            "fov",
            "likelihood_sigma",
            "likelihood_z_hit",
            "likelihood_max_distance",
            "likelihood_max_range",
        ):
            if getattr(self, name) <= 0:
                raise bad(name, "must be > 0")
        for name, low in (("table_width", 2), ("num_beams_per_particle", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise bad(name, f"must be an integer >= {low}")
        # bounds and their reasons: mcl.filter.bounds
        for name in ("table_width", "num_beams_per_particle", "sigma_hit", "squash_exponent",
                     "lidar_scale_to_map_scale", "mount_offset", "fov", "likelihood_sigma",
                     "likelihood_z_hit", "likelihood_z_rand", "likelihood_max_distance",
                     "likelihood_max_range"):  # fmt: skip
            check_filter("SensorModelParams", name, getattr(self, name), f"sensor.{name}")
        for name in alphas:
            check_filter("SensorModelParams", name, getattr(self, name), "sensor.alpha")
        check_filter("SensorModelParams", "lut_sort_extent", self.lut_sort_extent,
                     "sensor.lut_sort_extent")  # fmt: skip
        if self.max_range is not None:
            check_filter("SensorModelParams", "max_range", self.max_range, "sensor.max_range")
        if not isinstance(self.raycast_method, str):
            raise bad("raycast_method", "must be a method name")
        if self.parallel is not None and not isinstance(self.parallel, bool):
            raise bad("parallel", "must be true, false or null")
        for name in ("beam_skip", "beam_skip_short_only"):
            if not isinstance(getattr(self, name), bool):
                raise bad(name, "must be true or false")
        if self.beam_skip and self.model != "beam":
            raise bad(
                "beam_skip", f"is implemented for the beam model only, not {short(self.model)}"
            )
        bb = self.beam_bound
        if bb is not None and (
            isinstance(bb, bool) or not isinstance(bb, int | float) or not 0 <= bb < math.inf
        ):
            raise bad("beam_bound", "must be None or a number >= 0 (log-likelihood)")
        if self.beam_skip and self.beam_bound is not None:
            raise bad("beam_bound", "cannot be combined with beam_skip: set one of them")
        for name in ("beam_skip_distance", "beam_skip_converged_distance"):
            if getattr(self, name) <= 0:
                raise bad(name, "must be > 0 metres")
        for name in ("beam_skip_threshold", "beam_skip_error_threshold"):
            if not 0 <= getattr(self, name) <= 1:
                raise bad(name, "must be a fraction in [0, 1]")

    @property
    def z_max(self) -> int:
        """Largest range in pixels (the last table row / column)."""
        return self.table_width - 1
