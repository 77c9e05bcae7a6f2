"""The ``lost`` flag: when the filter's estimate should not be trusted, and the recovery it asks for.

What the filter can see, measured once per used scan (no truth involved):

- **Scan fit**: the fraction of the scan's beams (``LostParams.beams`` of them, evenly spaced) whose
  measured range agrees, within ``fit_tolerance`` metres, with the range cast in the *filter's*
  map from the estimated pose's lidar. It is a count of beams, not a likelihood, so it does not
  depend on the sensor model's tempering or on its ``sigma_hit``. Beams at or beyond the filter's
  range agree with a cast that finds no wall within it. One cast of ``beams`` rays from one pose
  (the sensor model's caster; the distance field at the beam end points for the likelihood field,
  which has no caster): tens of microseconds per scan. Beams that return short of the cast
  (``skip_short``: something the map lacks stands in front) are left out of the fraction: they
  neither confirm nor refute the pose, and the honest world's furniture and people would
  otherwise pull the fit at the true pose down to that of a wrong one.
- **Smoothing and hysteresis**: the fit is averaged exponentially with a time constant of
  ``window_s`` seconds of driving; the flag is raised when the average has stayed below
  ``raise_below`` for ``raise_after_s`` (``raise_continuous``: in one stretch) and cleared only
  once it climbs above ``clear_above``.
- **Against the car's own record**: a slower average of the smoothed fit, over ``reference_s``
  seconds of the time the flag was down, is the fit this world usually gives at the right pose.
  The flag is also raised when the misfit (1 - smoothed fit) grows beyond ``misfit_ratio`` times
  the reference's misfit (at least 0.02), and cleared only once it is back under half that;
  this test waits until the record holds ``reference_s`` of driving. A
  clean world, where the right pose explains 98 % of the beams, flags a wrong pose that explains
  85 %; a cluttered one, whose right pose explains 85 %, falls back on ``raise_below``.
- **Spread**: the flag is also up while the cloud's position standard deviation (largest axis of
  the weighted covariance) exceeds ``max_position_sd`` metres, e.g. after a global start or while
  the cloud holds two distant modes.

- **A jump**: the scan no longer continues the previous one as the odometry says it should
  ([`mcl.filter.scan_continuity`][mcl.filter.scan_continuity]): fewer than ``jump_below`` of the
  previous scan's points are seen again where they should be, and within ``jump_confirm_s`` the
  scan fit at the estimate falls under ``clear_above``: a kidnap (no map involved; people close to
  the lidar dip the continuity, not the fit). The flag goes up at once and stays up while the fit
  (averaged from the jump on) says lost, or ``jump_hold_s`` seconds at least.
- **A rival** (``search_rival``): within ``jump_search_s`` of a jump, the search filter (below)
  settled on another place that fits at least as well as the filter's. A car that stands (the
  filter holds its cloud still) is not flagged by the fit alone (``standing_holds``).

Recovery (``recover``, or ``recover_after_jump`` after a jump): while the fit says lost, the filter is asked
([ParticleFilter.request_recovery][mcl.filter.particle_filter.ParticleFilter.request_recovery]) to
replace ``inject_share`` of every resampling's draws by uniform free-space poses, and every
``burst_every_s`` seconds to weigh a burst of uniform free-space poses (``burst_density`` per m² of
the filter map's free floor, at most ``burst_max``) together with the cloud, after which the cloud
is resampled back to its count. The cloud is kept, and the burst's outcome is kept only when the
scan fits the new estimate better (``burst_accept``) than the cloud's before the burst, so a false
alarm costs time, not the track.

Local bursts (``local_below``): while the averaged fit is under ``local_below`` without a jump
(the estimate explains almost none of the scan: a car the cloud lost nearby), every
``burst_every_s`` seconds ``local_particles`` poses drawn around the estimate (``local_sd``
metres, ``local_heading_sd`` radians) are weighed with the cloud
([ParticleFilter.request_local_burst][mcl.filter.particle_filter.ParticleFilter.request_local_burst]);
the outcome is kept only when the scan fits it better by ``burst_accept``, at least
``clear_above`` and at least the car's usual fit (the reference), else the cloud is restored.

The search filter (``search_filter``; [`mcl.filter.global_search`][mcl.filter.global_search]): a
jump, or a dip of the continuity the fit did not confirm (the old estimate has a look-alike), starts
a global start of its own beside the filter for up to ``jump_search_s``, which keeps replacing
``search_inject_share`` of each resampling by uniform poses; once settled, the filter takes its
cloud when it fits better by ``burst_accept`` on average over ``search_adopt_s`` or, within
``jump_search_s`` of a jump, when the scan's log-likelihood at its estimate beats that at the
filter's by ``search_adopt_loglik`` nats per scan on average (two corridors alike fit the same
share of beams; the car's own place explains them more closely), and it starts again after that,
when it settled on a worse place, or on the filter's place while the flag is up, and, while the
flag is up, when it stayed ``search_restart_s`` undecided on a place fitting
``search_restart_misfit`` under the car's usual fit (a look-alike); on the filter's place with
the flag down it stops, or, within ``jump_search_s`` of a jump (``search_watch``), runs on
watching its other places. After a jump, ``search_confirmations`` searches in a row that settle on
the filter's own place (each from a new uniform draw, none settling in between on another place
that fits as well) find the car while the fit does not say lost (its average at least
``raise_below``): where the car was carried to a place the old map explains less well than the
one it left, the fit alone would keep the flag up over a car already found. From then on
(``confirmed_bar``) that place is judged by its own fit: the bar the average must fall under is
the average at the confirmation minus the hysteresis band (``clear_above - raise_below``) where
that is under ``raise_below``, and the car's usual fit is learned afresh from there, until the
average climbs above ``clear_above`` again.

Frames and units: world frame; metres, radians, seconds.
"""

from __future__ import annotations

import math

import numpy as np

from mcl.filter.confirmations import SearchConfirmations
from mcl.filter.global_search import GlobalSearch
from mcl.filter.lost_params import LostParams
from mcl.filter.particle_filter import ParticleFilter
from mcl.filter.scan_continuity import ScanContinuity, scan_bearings
from mcl.filter.scan_fit import ScanFit, scan_agreement
from mcl.filter.step_kernels import pose_moments
from mcl.filter.uncertainty import largest_position_sd

__all__ = ["LostDetector", "scan_agreement"]

_MIN_MISFIT = 0.02
"""The smallest usual misfit the relative test assumes (a perfect record would flag any beam)."""


class LostDetector:
    """The ``lost`` flag of one filter (module docstring); one per car, restarted with its filter.

    Args:
        params: [LostParams][mcl.filter.lost_params.LostParams].

    Attributes:
        fit: the last scan's fit (fraction of beams, NaN before the first scan).
        smoothed_fit: its exponential average over ``window_s`` (NaN before the first scan).
        reference_fit: the slow average of ``smoothed_fit`` while not lost (``reference_s``).
        fit_lost: the hysteresis flag of the fit alone.
        position_sd: metres, the cloud's position standard deviation at the last scan.
        continuity: the last scan's continuity of the one before (NaN without odometry, or
            before the second scan; [`mcl.filter.scan_continuity`][mcl.filter.scan_continuity]).
        jumped: a jump was seen and the filter has not found the car again since.
        jumps: jumps seen since the restart.
        lost: the flag reported: ``raised`` or ``rival`` (with ``standing_holds``, a raise by
            the fit alone shows once the fit has said lost over ``raise_after_s`` of moving).
        raised: ``fit_lost``, a spread cloud, or ``jumped`` (what the recovery answers).
        rival: after a jump, the search settled on another place fitting as well.
        search: the search filter run after a jump
            ([GlobalSearch][mcl.filter.global_search.GlobalSearch]).
        confirmations: the searches in a row that settled on the filter's place since the jump
            ([SearchConfirmations][mcl.filter.confirmations.SearchConfirmations]).
    """

    def __init__(self, params: LostParams | None = None) -> None:
        self.params = params if params is not None else LostParams()
        self.fit = math.nan
        self.smoothed_fit = math.nan
        self.reference_fit = math.nan
        self.fit_lost = False
        self.position_sd = 0.0
        self.continuity = math.nan
        self.jumped = False
        self.jumps = 0
        self.lost = self.raised = self.rival = False
        self._low_moving = 0.0  # seconds the fit was under the bar (or lost) while the car moved
        self._since_scan = 0.0  # seconds of driving since the last scan observed
        self._low_for = 0.0  # seconds the averaged fit has said lost without the flag up
        self._reference_age = 0.0  # seconds of driving folded into reference_fit
        self._since_burst = math.inf
        self._since_jump = math.inf
        self._found_fit = 0.0  # the averaged fit at which a jumped car counts as found
        self._since_dip = math.inf  # seconds since the continuity last dipped under jump_below
        self._since_search = math.inf  # seconds since the search filter started
        self._since_local = math.inf  # seconds since the last local burst
        self.confirmations = SearchConfirmations(self.params.search_confirmations)
        self._raise_below = self.params.raise_below  # the bar in use (lowered at a confirmed place)
        self._local_burst = False  # the burst asked for is a local one
        self._scans: ScanContinuity | None = None  # built at the first scan (needs the lidar)
        self._scan_fit = ScanFit(self.params.beams, self.params.fit_tolerance, self.params.skip_short)
        self._lidar_range: float | None = None  # metres the lidar sees (observe's argument)
        self._odometry_fed = False
        self.search = GlobalSearch.from_params(self.params)

    def restart(self) -> None:
        """Forget the history (a new belief: a reset or a new start)."""
        self.__init__(self.params)

    def advance(self, dt: float, odometry: np.ndarray | None = None) -> None:
        """``dt`` seconds of driving passed (called on every step, with or without a scan), on the
        car-frame ``odometry`` twist [vx m/s, vy m/s, omega rad/s] (None: no jump check)."""
        self._since_scan += dt
        self._since_burst += dt
        self._since_jump += dt
        self._since_dip += dt
        self._since_search += dt
        self._since_local += dt
        if odometry is not None and self._scans is not None:
            twist = np.asarray(odometry, dtype=np.float64)
            self._scans.advance(twist, dt)
            self._odometry_fed = True
            self.search.predict(twist, dt)

    def observe(
        self, pf: ParticleFilter, scan: np.ndarray, lidar_range: float | None = None
    ) -> bool:
        """Measure the fit of ``scan`` (metres, the filter's beams) at ``pf``'s estimate, update
        the flag, ask ``pf`` for recovery while lost; returns the flag. ``lidar_range``: metres
        the lidar sees (its no-returns say no wall within it; None: the sensor model's range)."""
        p = self.params
        if not p.enabled:
            return False
        self._lidar_range = lidar_range
        estimate = pf.estimate()
        fit = self.fit_at(pf, estimate, scan)
        prior = pf.burst_prior
        if prior is not None:  # a burst: keep its winner only when the scan fits it better
            local, self._local_burst = self._local_burst, False
            before = self.fit_at(pf, pose_moments(prior[0], prior[1], False)[0], scan)
            # a local burst's place must also fit as well as the car usually fits (the old map
            # may be wrong all round a car it holds, and a place nearby explain more of the scan)
            need = before + p.burst_accept
            if local:
                usual = self.reference_fit if math.isfinite(self.reference_fit) else 0.0
                need = max(need, p.clear_above, usual)
            if not fit >= need:
                pf.undo_burst()
                estimate = pf.estimate()
                fit = self.fit_at(pf, estimate, scan)
            else:  # a new estimate: the odometry scale's window spans the move, the average
                pf.moved_elsewhere()  # of the old estimate's fit is moot
                if math.isfinite(fit):
                    self.smoothed_fit = fit
        self.fit = fit
        jumps = self.jumps
        self._check_jump(pf, scan)
        # a jump, or a dip of the continuity the fit did not confirm (the scan fits the old
        # estimate as well: a look-alike place), starts the search filter
        if p.search_filter and (
            self.jumps > jumps or (self._since_dip == 0.0 and not self.search.running)
        ):
            self.search.start(pf)
            self._since_search = 0.0
        if self.search.running and self._search(pf, estimate, scan):
            estimate = pf.estimate()
            fit = self.fit = self.fit_at(pf, estimate, scan)
            if math.isfinite(fit):
                self.smoothed_fit = fit
        if math.isfinite(fit):
            if math.isnan(self.smoothed_fit):
                self.smoothed_fit = self.reference_fit = fit
            else:
                dt = max(self._since_scan, 0.0)
                self.smoothed_fit += (1.0 - math.exp(-dt / p.window_s)) * (fit - self.smoothed_fit)
                if not (self.fit_lost or self.jumped):
                    a = 1.0 - math.exp(-dt / p.reference_s)
                    self.reference_fit += a * (self.smoothed_fit - self.reference_fit)
                    self._reference_age += dt
        since_scan, self._since_scan = self._since_scan, 0.0
        s = self.smoothed_fit
        if math.isfinite(s):
            # the usual misfit, once the record holds reference_s of driving (inf before)
            usual = max(1.0 - self.reference_fit, _MIN_MISFIT)
            if self._reference_age < p.reference_s:
                usual = math.inf
            if self.fit_lost and s > p.clear_above and 1.0 - s < 0.5 * p.misfit_ratio * usual:
                self.fit_lost = False
            elif not self.fit_lost and (s < self._raise_below or 1.0 - s > p.misfit_ratio * usual):
                self._low_for += since_scan
                self.fit_lost = self._low_for >= p.raise_after_s
            elif s > p.clear_above or (p.raise_continuous and not self.fit_lost):
                self._low_for = 0.0  # over the bar again (or, not continuous, a good fit again)
            if s > p.clear_above:  # the car left the place its searches confirmed, if any
                self._raise_below = p.raise_below
            if self.fit_lost:
                self._low_for = 0.0
            # the same time under the bar, counted only while the car moves (the cloud can drift)
            moving = 0.0 if pf.standstill.standing else since_scan
            self._low_moving = self._low_moving + moving if self.fit_lost or self._low_for > 0.0 else 0.0
        cov = pf.covariance()
        self.position_sd = largest_position_sd(cov)
        was_raised = self.raised
        self.raised = self.fit_lost or self.position_sd > p.max_position_sd or self.jumped
        if (
            p.search_filter
            and p.search_on_lost
            and self.raised
            and not was_raised
            and not self.search.running
        ):
            self.search.start(pf)  # the next scan weighs it
            self._since_search = 0.0
        # after a jump, a fit that says lost within jump_search_s resumes the search: the place
        # the search found may fit only where the car happened to be
        after_jump = self.jumped or (self.fit_lost and self._since_jump < p.jump_search_s)
        searching = (p.recover and self.fit_lost) or (p.recover_after_jump and after_jump)
        if p.recover or p.recover_after_jump:
            burst = 0
            if searching and self._since_burst >= p.burst_every_s and p.burst_max > 0:
                burst = min(p.burst_max, math.ceil(p.burst_density * pf.map.free_area))
                self._since_burst = 0.0
            if not searching:
                self._since_burst = math.inf  # the next loss bursts at once
            pf.request_recovery(p.inject_share if searching else 0.0, burst)
        # the estimate explains almost none of the scan: look for the car around it
        deep = math.isfinite(s) and s < p.local_below and not (self.jumped or searching)
        if deep and self._since_local >= p.burst_every_s and p.local_particles > 0:
            pf.request_local_burst(p.local_particles, p.local_sd, p.local_heading_sd)
            self._since_local = 0.0
            self._local_burst = True
        search = self.search  # a rival place the scans do not refute, after a jump
        self.rival = p.search_rival and self._since_jump < p.jump_search_s and search.rival(estimate)
        stood = p.standing_holds and self._low_moving < p.raise_after_s  # said lost while standing
        by_fit_alone = not self.jumped and self.position_sd <= p.max_position_sd
        self.lost = (self.raised and not (stood and by_fit_alone)) or self.rival
        return self.lost

    def _search(self, pf: ParticleFilter, estimate: np.ndarray, scan: np.ndarray) -> bool:
        """One scan of the search filter; returns whether ``pf`` took its cloud (its fit, or
        after a jump its log-likelihood, beat the filter's: module docstring). The search ends
        ``jump_search_s`` after it started, once it settles on the filter's place while the
        flag is down, or once it confirms that place after a jump (``search_confirmations``),
        unless it watches on (``search_watch``, within ``jump_search_s`` of the jump);
        it starts again after an adoption, when it settles on the filter's place
        while the flag is up, when it settles on a place that fits worse than the filter's, and
        when it stays undecided on a look-alike (``search_restart_misfit``)."""
        search = self.search
        if self._since_search > self.params.jump_search_s:
            search.stop()
            return False
        search.correct(scan, self._since_scan)
        if search.filter is None or search.converged_for <= 0.0:
            return False
        if search.settled() and search.agrees_with(estimate):
            # after a jump it may watch on: the place the fit found may be a look-alike
            watch = self.params.search_watch and self._since_jump < self.params.jump_search_s
            if self.jumped and self.raised and self._confirmed():
                if not watch:
                    search.stop()
            elif self.raised:
                search.start(pf)
            elif not watch:
                search.stop()
            return False
        found = search.filter.estimate()
        search_fit = self.fit_at(search.filter, found, scan)
        loglik_gap = math.nan  # the scan's log-likelihood, search minus filter, after a jump
        p = self.params
        if math.isfinite(p.search_adopt_loglik) and self._since_jump < p.jump_search_s:
            poses = np.stack([found, np.asarray(estimate, dtype=np.float64)])
            ll = pf.sensor_model.log_evaluate(poses, scan)
            loglik_gap = float(ll[0] - ll[1])
        verdict = search.compare(search_fit, self.fit, self._since_scan, loglik_gap)
        if search.settled():  # settled elsewhere: a place fitting as well breaks the row
            self.confirmations.settled_elsewhere(verdict)
        if verdict > 0:
            search.adopt(pf)
        # the flag up, undecided for search_restart_s on a place fitting well under the usual fit
        look_alike = self.raised and search.stuck(p.search_restart_s, self.reference_fit - p.search_restart_misfit)
        if verdict != 0 or look_alike:
            search.start(pf)
        return verdict > 0

    def _confirmed(self) -> bool:
        """Count one more search settled on the filter's place after a jump; True (and the car
        found: ``jumped`` cleared) once ``search_confirmations`` did in a row and the fit does not
        say lost (its average at least ``raise_below``)."""
        p = self.params
        if not self.confirmations.agreed():
            return False
        if not (self.smoothed_fit >= p.raise_below and not self.fit_lost):
            return False
        self.jumped = False
        self.confirmations.restart()
        if p.confirmed_bar:  # judge the place by its own fit, not the one the car left
            band = p.clear_above - p.raise_below
            self._raise_below = min(p.raise_below, self.smoothed_fit - band)
            self.reference_fit = self.smoothed_fit
            self._reference_age = 0.0
        return True

    def _check_jump(self, pf: ParticleFilter, scan: np.ndarray) -> None:
        """Compare ``scan`` with the previous one (odometry fed since): a jump raises ``jumped``
        and starts the fit's average again from this scan's fit. It falls once ``jump_hold_s``
        passed, the fit does not say lost and its average since is back within
        ``jump_found_within`` of the usual fit before the jump (a wrong place that fits a
        cluttered world fairly is searched on), or after ``jump_search_s``."""
        p, sm = self.params, pf.sensor_model
        z = np.asarray(scan, dtype=np.float64).reshape(-1)
        if self._scans is None:
            mount = sm.lidar_poses(np.zeros((1, 3)))[0]
            self._scans = ScanContinuity(mount, float(sm.max_range), p.beams)
        continuity = self._scans.observe(z, scan_bearings(sm, z.size))
        self.continuity = continuity if self._odometry_fed else math.nan
        if p.jump_below > 0.0 and self.continuity < p.jump_below:  # NaN compares False
            self._since_dip = 0.0
        # a dip of the continuity is a jump once the fit at the estimate has fallen too (people
        # and furniture passing close to the lidar make dips, but the fit holds)
        if self._since_dip <= p.jump_confirm_s and self.fit < p.clear_above:
            self._since_dip = math.inf
            if not self.jumped:  # the usual fit, from before the jump
                usual = self.reference_fit if math.isfinite(self.reference_fit) else 1.0
                self._found_fit = usual - p.jump_found_within
            self.jumped = True
            self.jumps += 1
            if math.isfinite(self.fit):  # the average speaks of where the car was carried to
                self.smoothed_fit = self.fit
            self.confirmations.restart()
            self._raise_below = p.raise_below
            pf.moved_elsewhere()  # its window holds the jump: nothing to learn from
            self._since_jump = 0.0
            self._since_burst = math.inf  # search at once
        elif (
            self.jumped
            and self._since_jump >= p.jump_hold_s
            and not self.fit_lost
            and (self.smoothed_fit >= self._found_fit or self._since_jump >= p.jump_search_s)
        ):
            self.jumped = False

    def fit_at(self, pf: ParticleFilter, estimate: np.ndarray, scan: np.ndarray) -> float:
        """The scan fit (fraction of beams, module docstring) of ``scan`` (metres, the filter's
        beams) at the world pose ``estimate`` [x m, y m, theta rad], cast in ``pf``'s map with its
        sensor model; NaN when no beam counts."""
        return self._scan_fit.at(pf.sensor_model, pf.map, estimate, scan, self._lidar_range)
