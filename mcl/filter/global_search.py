"""A second filter that searches the whole map beside a filter that may hold the wrong place.

After a jump (a kidnap) the filter's own cloud searches by bursts of uniform poses, one scan each
([`mcl.filter.lost`][mcl.filter.lost]): a burst finds the car only when one of its poses happens to
fall close enough to the car's to fit that scan, and a cloud that settled on a wrong place keeps
it for as long as the scan fits there fairly (a corridor like the car's, a room turned round).
[`GlobalSearch`][mcl.filter.global_search.GlobalSearch] runs a global start of its own instead: uniform
poses over the filter map's free space (the filter's ``global_density`` per square metre, at most
``global_max_particles``), moved by the same odometry and weighed by the same scans with the
sensor model's wide search hit, so that the car's place wins over several scans as it does at a
global start. While it runs it can keep replacing ``inject_share`` of each resampling by uniform
poses (augmented MCL's injection; none by default): the first scans of a global start can gather the weight on a
look-alike place (a corridor fits from anywhere along it) before a pose near the car was drawn,
and injected poses that land near the car take over when its scans favour them. Its cloud has
*settled* once its position standard deviation has stayed under
``converged_sd`` for ``adopt_after_s`` seconds on one place (a global start's first scans can
gather the weight on a few poses that later scans refute; a scan that moves its estimate farther
than ``agree_m`` or ``agree_rad`` starts that time again); it is then resampled down to the filter's particle
count, and its estimate is compared with the filter's on every scan by the scan fit (the lost
flag's share of beams that agree with the map, averaged over ``adopt_after_s``):

- where the two agree (within ``agree_m`` and ``agree_rad``) the search has confirmed the filter's
  place;
- where it fits better by ``adopt_margin`` of the beams, the filter takes the search's cloud
  ([adopt][mcl.filter.global_search.GlobalSearch.adopt]); also where the scan's log-likelihood
  given to [compare][mcl.filter.global_search.GlobalSearch.compare] (the lost flag gives it
  after a jump) beats the filter's by ``adopt_loglik`` nats per scan on average and the fit is not
  worse by ``adopt_margin``: two corridors alike fit the same share of beams within 0.2 m, but
  the car's own place puts each return closer to its cast;
- where it fits worse by as much, it settled on a wrong place;
- otherwise it tracks its own place on, a second hypothesis.

What follows each verdict (stop, search again; also a search that stays undecided on a place
fitting well under the car's usual fit) is the lost flag's decision
([`LostDetector`][mcl.filter.lost.LostDetector]).

Frames and units: world poses [x m, y m, theta rad]; seconds; fits are fractions of beams.
"""

from __future__ import annotations

import math

import numpy as np

from mcl.filter.angles import wrap_angle
from mcl.filter.lost_params import LostParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.place_keeping import PlaceKeeping
from mcl.filter.uncertainty import largest_position_sd

__all__ = ["GlobalSearch"]


def _fold(average: float, value: float, a: float) -> float:
    """``average`` moved the share ``a`` of the way to ``value``; the first finite value is
    taken whole (``average`` NaN), a non-finite one leaves it as it was."""
    if not math.isfinite(value):
        return average
    return value if math.isnan(average) else average + a * (value - average)


class GlobalSearch:
    """The search filter of one [LostDetector][mcl.filter.lost.LostDetector] (module docstring).

    Args:
        converged_sd: metres; the search's cloud has converged when its position standard
            deviation (largest axis) is under this.
        agree_m: metres; a converged search this close to the filter's estimate ...
        agree_rad: radians; ... and this close in heading confirms it.
        adopt_margin: fraction of beams by which the search's fit must beat the filter's (on
            average) for the filter to take the search's cloud.
        adopt_after_s: seconds of driving over which the fit difference is averaged
            (exponential time constant), and the least time converged before an adoption.
        inject_share: fraction of each of the search's resamplings replaced by uniform
            free-space poses while it runs, in [0, 0.5] (0: none).
        adopt_loglik: nats per scan; the filter also takes the search's cloud when the
            log-likelihood difference given to `compare()` averages at least this and the fit
            is not worse by ``adopt_margin`` (``math.inf``: never).
        draw_density: poses per square metre of the filter map's free floor in each search's
            first draw (at most ``draw_max``): the first scan weighs them all, after which the
            cloud is resampled to the filter's global count (its ``global_density``); at or
            under that density nothing more is drawn.
        draw_max: the most poses of such a first draw.
        places: None (plain resampling), or how the search's resamplings keep particles in
            every place with weight ([`mcl.filter.place_keeping`][mcl.filter.place_keeping]), so
            that the first scans cannot drop the car's place for a look-alike.
        scan_exponent: the power the search raises each scan's likelihood to, in (0, 1] (1:
            Bayes' rule as it is; smaller: each scan moves the weight between places less).

    Attributes:
        filter: the search's particle filter (None while no search runs).
        fit_gap: the averaged difference of the scan fits, search minus filter (NaN before the
            search converged).
        fit: the search's own scan fit at its estimate, averaged as ``fit_gap`` (NaN before the
            search converged).
        loglik_gap: the averaged difference of the scans' log-likelihoods (nats), search minus
            filter (NaN before the search converged or while none is given).
        converged_for: seconds the search's cloud has stayed converged on one place (0 while
            it is not, and again after its estimate hopped farther than ``agree_m``).
        adoptions: how many times the filter took the search's cloud since the restart.
    """

    def __init__(
        self,
        converged_sd: float = 0.5,
        agree_m: float = 1.0,
        agree_rad: float = 0.5,
        adopt_margin: float = 0.1,
        adopt_after_s: float = 1.0,
        inject_share: float = 0.0,
        adopt_loglik: float = math.inf,
        draw_density: float = 0.0,
        draw_max: int = 100_000,
        places: PlaceKeeping | None = None,
        scan_exponent: float = 1.0,
    ) -> None:
        for name, value in (("converged_sd", converged_sd), ("agree_m", agree_m),
                            ("agree_rad", agree_rad), ("adopt_after_s", adopt_after_s)):  # fmt: skip
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < math.inf:
                raise ValueError(f"GlobalSearch {name} = {value!r} must be a positive number")
        number = (int, float)
        if isinstance(inject_share, bool) or not isinstance(inject_share, number) or not 0 <= inject_share <= 0.5:
            raise ValueError(f"GlobalSearch inject_share = {inject_share!r} must lie in [0, 0.5]")
        if isinstance(adopt_loglik, bool) or not isinstance(adopt_loglik, number) or not adopt_loglik > 0:
            raise ValueError(f"GlobalSearch adopt_loglik = {adopt_loglik!r} must be positive (inf: never)")
        if isinstance(draw_density, bool) or not isinstance(draw_density, number) or not 0 <= draw_density < math.inf:
            raise ValueError(f"GlobalSearch draw_density = {draw_density!r} must be a number >= 0 per m²")
        if isinstance(draw_max, bool) or not isinstance(draw_max, int) or draw_max < 1:
            raise ValueError(f"GlobalSearch draw_max = {draw_max!r} must be a positive integer")
        if isinstance(scan_exponent, bool) or not isinstance(scan_exponent, number) or not 0 < scan_exponent <= 1:
            raise ValueError(f"GlobalSearch scan_exponent = {scan_exponent!r} must lie in (0, 1]")
        if places is not None and not isinstance(places, PlaceKeeping):
            raise ValueError(f"GlobalSearch places = {places!r} must be a PlaceKeeping or None")
        if isinstance(adopt_margin, bool) or not 0 <= adopt_margin <= 1:
            raise ValueError(f"GlobalSearch adopt_margin = {adopt_margin!r} must be a fraction in [0, 1]")
        self.converged_sd = converged_sd
        self.agree_m = agree_m
        self.agree_rad = agree_rad
        self.adopt_margin = adopt_margin
        self.adopt_after_s = adopt_after_s
        self.inject_share = inject_share
        self.adopt_loglik = adopt_loglik
        self.draw_density = draw_density
        self.draw_max = draw_max
        self.places = places
        self.scan_exponent = scan_exponent
        self.filter: ParticleFilter | None = None
        self.fit = self.fit_gap = self.loglik_gap = math.nan
        self.converged_for = 0.0
        self.adoptions = 0

    @classmethod
    def from_params(cls, p: LostParams) -> GlobalSearch:
        """The search filter the lost flag's settings ``p`` describe (their ``search_*`` fields;
        a burst's ``burst_accept`` is the adoption margin)."""
        places = None
        if p.search_place_draws > 0:
            places = PlaceKeeping(cell_m=p.search_place_m, headings=p.search_place_headings,
                                  draws=p.search_place_draws)  # fmt: skip
        return cls(p.search_converged_sd, adopt_margin=p.burst_accept, adopt_after_s=p.search_adopt_s,
                   inject_share=p.search_inject_share, adopt_loglik=p.search_adopt_loglik,
                   draw_density=p.search_draw_density, draw_max=p.search_draw_max, places=places,
                   scan_exponent=p.search_scan_exponent)  # fmt: skip

    @property
    def running(self) -> bool:
        """Whether a search runs."""
        return self.filter is not None

    def start(self, pf: ParticleFilter) -> None:
        """Start a global search beside ``pf``: its map, motion and sensor models and settings,
        the odometry scale ``pf`` learned, and a generator seeded from ``pf``'s; the poses of a
        denser first draw (``draw_density``) join at the next scan."""
        search = ParticleFilter(
            pf.map,
            motion_model=pf.motion_model,
            sensor_model=pf.sensor_model,
            params=pf.params,
            rng=int(pf.rng.integers(2**63 - 1)),
        )
        search.initialize_global()
        search.place_keeping = self.places
        search.scan_exponent = self.scan_exponent
        search.odometry_scale.take(pf.odometry_scale)
        dense = min(self.draw_max, math.ceil(self.draw_density * pf.map.free_area))
        extra = max(0, dense - search.n_particles)  # weighed by the next scan, then dropped
        if self.inject_share > 0.0 or extra > 0:
            search.request_recovery(self.inject_share, burst=extra)
        self.filter = search
        self._converged_anew()

    def stop(self) -> None:
        """End the search (its particles are dropped)."""
        self.filter = None
        self._converged_anew()

    def _converged_anew(self) -> None:
        """Forget how long the cloud has been converged and the averages taken meanwhile."""
        self.converged_for = 0.0
        self.fit = self.fit_gap = self.loglik_gap = math.nan

    def predict(self, twist: np.ndarray, dt: float) -> None:
        """Move the search's particles by the car-frame odometry ``twist`` [vx m/s, vy m/s,
        omega rad/s] held ``dt`` seconds (nothing while no search runs)."""
        if self.filter is not None:
            self.filter.predict(twist, dt)

    def correct(self, scan: np.ndarray, dt: float) -> None:
        """Weigh the search's particles by ``scan`` (metres, the filter's beams), taken ``dt``
        seconds after the last. A cloud converged for ``adopt_after_s`` seconds of more
        particles than the filter's count is resampled down to it (a global start's first scans
        can gather its weight on a few poses that a later scan refutes). A converged cloud whose
        estimate this scan moved farther than ``agree_m`` or ``agree_rad`` (its weight hopped to
        a rival place it kept) counts as converged anew: `converged_for` and the averages
        start again, so that they speak of one place."""
        search = self.filter
        if search is None:
            return
        before = search.estimate() if self.converged_for > 0.0 else None
        search.correct(scan)
        hopped = before is not None and not self.agrees_with(before)  # to a rival place
        if hopped or not largest_position_sd(search.covariance()) < self.converged_sd:
            self._converged_anew()
            return
        self.converged_for += dt
        count = search.params.n_particles
        if self.settled() and search.n_particles > count and not search.params.kld.enabled:
            search.resample(count)

    def settled(self) -> bool:
        """Whether the search's cloud has stayed converged (position sd under ``converged_sd``)
        for ``adopt_after_s`` seconds: only then is it compared with the filter."""
        return self.filter is not None and self.converged_for >= self.adopt_after_s

    def agrees_with(self, estimate: np.ndarray) -> bool:
        """Whether the search's estimate lies within ``agree_m`` / ``agree_rad`` of ``estimate``."""
        if self.filter is None:
            return False
        mine = self.filter.estimate()
        turn = abs(float(wrap_angle(mine[2] - float(estimate[2]))))
        return math.dist(mine[:2], estimate[:2]) <= self.agree_m and turn <= self.agree_rad

    def stuck(self, after_s: float, fit_under: float) -> bool:
        """Whether the search has stayed converged ``after_s`` seconds on one place whose
        averaged fit (`fit`, a fraction of beams) lies under ``fit_under`` (a look-alike)."""
        return self.converged_for >= after_s and self.fit < fit_under

    def rival(self, estimate: np.ndarray) -> bool:
        """Whether the search has settled on another place than ``estimate`` (farther than
        ``agree_m`` or ``agree_rad``) whose averaged fit is at least the filter's (`fit_gap`
        above 0): the scans do not tell the two places apart, or favour the search's."""
        return self.settled() and not self.agrees_with(estimate) and self.fit_gap > 0.0

    def compare(
        self, search_fit: float, filter_fit: float, dt: float, loglik_gap: float = math.nan
    ) -> int:
        """Fold one scan's fits (fractions of beams at the search's and the filter's estimate)
        taken ``dt`` seconds after the last into `fit_gap`, and ``loglik_gap`` (nats, the
        scan's log-likelihood at the search's estimate minus at the filter's; NaN: none) into
        `loglik_gap`; returns 1 when the filter should take the search's cloud (settled, and
        the averaged fit gap at least ``adopt_margin``, or the averaged log-likelihood gap at
        least ``adopt_loglik`` with the fit gap above ``-adopt_margin``), -1 when the search
        settled on a place that fits worse by ``adopt_margin`` (search again), else 0."""
        a = 1.0 - math.exp(-dt / self.adopt_after_s)
        self.fit = _fold(self.fit, search_fit, a)
        self.fit_gap = _fold(self.fit_gap, search_fit - filter_fit, a)
        self.loglik_gap = _fold(self.loglik_gap, loglik_gap, a)
        if not self.settled() or math.isnan(self.fit_gap):
            return 0
        if self.fit_gap >= self.adopt_margin:
            return 1
        if self.loglik_gap >= self.adopt_loglik and self.fit_gap > -self.adopt_margin:
            return 1
        return -1 if self.fit_gap <= -self.adopt_margin else 0

    def adopt(self, pf: ParticleFilter) -> None:
        """Give ``pf`` the search's cloud, resampled to ``pf``'s particle count (KLD-sampling's
        when ``pf`` has it on), and end this search."""
        if self.filter is None:
            raise RuntimeError("GlobalSearch.adopt: no search runs")
        search = self.filter
        pf.set_particles(search.particles, search.weights)  # copied there
        pf.resample(None if pf.params.kld.enabled else pf.params.n_particles)
        pf.moved_elsewhere()  # the scale's bridge would span the move
        self.adoptions += 1
        self.stop()
