"""Settings of the ``lost`` flag and of the recovery it triggers: thresholds of the scan fit, the
cloud's spread and the scans' jump ([`mcl.filter.lost`][mcl.filter.lost] says what each does).

Units: metres, seconds, fractions of beams.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from racecar_sim.settings.validation import short

__all__ = ["LostParams"]


@dataclass(frozen=True)
class LostParams:
    """Thresholds of the ``lost`` flag and the recovery it triggers (what each does:
    [`mcl.filter.lost`][mcl.filter.lost]).

    Attributes:
        enabled: compute the flag (False: ``lost`` is always False and nothing is injected).
        fit_tolerance: metres; a beam agrees when its measured range is this close to the cast.
        skip_short: leave out of the fit the beams that return more than ``fit_tolerance``
            short of the cast (furniture, people, other cars: what the map lacks).
        beams: beams of the scan compared (evenly spaced).
        window_s: seconds of driving over which the fit is averaged (exponential time constant).
        raise_below: the flag goes up when the averaged fit falls below this fraction.
        raise_after_s: ... and has stayed under it (or over the misfit bound) this many seconds:
            a filter keeps the car for a while on its odometry where the map has changed, and a
            kidnap raises the flag at once through the jump check (0: at once).
        raise_continuous: the seconds under the bar (``raise_after_s``) count one stretch: they
            start again whenever the average is back over the bar (false: they are kept until
            the average rises above ``clear_above``, so separate dips add up). On 40 honest
            kidnaps in the filter's second draw it changed three drives (cluttered kidnaps 13,
            14 and 17): the cluttered kidnaps' false alarms 2.2 -> 1.0 %, precision 0.74 ->
            0.85, one more found within 15 s; in the third one (clean kidnap 0, lost either
            way, flagged on fewer of its lost steps): the clean recall 0.176 -> 0.170
            (docs/recovery.md).
        standing_holds: the fit's time under the bar counts towards the reported ``lost`` only
            while the car moves (the filter's standstill check does not say it stands, its cloud
            held still): a held cloud cannot drift from where the car stopped, and a car pinned
            where the old map is wrong round it would otherwise be flagged for as long as it
            stands. Not after a jump, nor for a spread cloud; the recovery the fit asks for runs
            as before, so no estimate changes. On the 80 honest tracking drives (first draw,
            2026-12-08) the false alarms fell from 7.06 to 4.64 % (cluttered) and 0.91 to 0.79 %
            (clean), the recall the same (docs/recovery.md).
        clear_above: the flag goes down when the averaged fit rises above this fraction
            (at least ``raise_below``: hysteresis).
        misfit_ratio: the flag also goes up when the averaged misfit exceeds this many times
            the reference's (at least 1; ``.inf``: never).
        reference_s: seconds (of time not lost) over which the reference fit is averaged.
        max_position_sd: metres; the flag is also up while the cloud's position standard
            deviation exceeds this (``math.inf``: never).
        recover: inject free-space particles whenever the fit says lost (off by default: in the
            honest world it moved the cloud to wrong places that fit 62-86 % of the beams and lost
            runs the plain filter keeps, docs/recovery.md).
        recover_after_jump: inject them after a jump (a kidnap) until the car is found, and
            again whenever the fit says lost within ``jump_search_s`` of the jump.
        jump_below: a jump is a scan that sees fewer than this fraction of the previous scan's
            points again (0: never; the wrappers feed the odometry the check needs).
        jump_confirm_s: a dip of the continuity is a jump when, within this many seconds, the
            scan fit at the estimate falls under ``clear_above`` (something passing close to the
            lidar makes a dip, but the fit holds).
        jump_hold_s: seconds the flag stays up after a jump at least.
        jump_found_within: after a jump, the car counts as found when the averaged fit is
            back within this fraction of the usual fit before the jump.
        jump_search_s: seconds after a jump during which a fit that says lost resumes the
            search, and after which a jumped filter stops searching for a better place than
            one the fit does not call lost.
        inject_share: fraction of each resampling's draws replaced by uniform free-space poses
            while lost, in [0, 0.5].
        burst_every_s: seconds between two bursts of uniform poses while lost (the first one as
            soon as the flag goes up).
        burst_density: burst particles per m² of the filter map's free floor.
        burst_max: most particles of one burst (0: no bursts).
        burst_accept: a burst's outcome is kept only when the scan fit at the new estimate
            beats the fit at the cloud's estimate before the burst by this much; else the
            cloud before the burst is restored (the beam model may prefer a wrong place that a
            cluttered, out-of-date world happens to fit).
        search_filter: after a jump, also run a global start of its own beside the filter
            ([`mcl.filter.global_search`][mcl.filter.global_search]) until it confirms the
            filter's place, the filter takes its cloud, or ``jump_search_s`` has passed.
        search_on_lost: also start the search filter whenever the flag goes up without a jump
            (off by default: on the honest world's tracking drives of `racecar-sim lost-flag` it
            moved runs the filter held to wrong places that fit the old map better, cluttered
            seed 9 from 0.83 to 8.4 m of mean error, clean seeds 5 and 6 from 0.19 and 0.30 to
            6.3 and 28.6 m).
        search_converged_sd: metres; the search's cloud counts as converged (and is compared
            with the filter's) when its position standard deviation is under this.
        search_adopt_s: seconds; the filter takes the search's cloud when the search's scan fit
            beats its own by ``burst_accept`` on average over this long (exponential time
            constant), converged at least this long. Half a second: a search whose weight hops
            between rival places (a car standing after a kidnap) is compared before it hops; on
            40 honest kidnaps in three draws of the filter, 36, 33 and 29 found within 15 s and
            a mean time of 5.4-7.2 s, against 32, 33 and 30 and 6.8-7.8 s with 1 s
            (docs/recovery.md).
        search_inject_share: fraction of each of the search filter's resamplings replaced by
            uniform free-space poses for as long as it runs, in [0, 0.5] (augmented MCL's
            injection): a search that settled on a look-alike place keeps sampling the map, and
            poses that land near the car take over when its scans favour them (0: never; off by
            default: on 20 honest kidnaps 0.02 found 16 within 15 s against 14 by the fit alone,
            and with a 10-nat ``search_adopt_loglik`` the same 17 as that rule alone,
            docs/recovery.md).
        search_adopt_loglik: nats per scan; within ``jump_search_s`` of a jump the filter also
            takes the search's cloud when the scan's log-likelihood (the filter's sensor model,
            its beams and squash exponent) at the search's estimate beats that at the filter's
            by this much on average over ``search_adopt_s``, and its scan fit is not worse by
            ``burst_accept`` (two corridors alike fit the same share of beams while the car's
            own place explains each beam more closely; ``.inf``: never). On 40 honest kidnaps 30
            found 32 within 15 s against 29 by the fit alone; 10 found 31 but hopped between wrong
            places (docs/recovery.md).
        search_restart_misfit: fraction of beams; while the flag is up, a search that has
            stayed converged ``search_restart_s`` seconds without a verdict while its own
            averaged scan fit lies this far under the car's usual fit (the reference, held since
            the jump) settled on a look-alike place: it starts again from a new uniform draw
            (``.inf``: never). Measured with plain resampling in the search: on 40 honest
            kidnaps 0.15 found 33 within 15 s and 36 within 20 s against 32 and 34 without (a
            searching cloud's noise kept while the car stands in both); 16 of 20 held-out
            kidnaps as without, three sooner. That is one draw of the filter's random numbers:
            over three draws, with the noise kept, 88 of 120 against 86 for neither, within what
            a draw moves (docs/recovery.md). A search that keeps its places
            (``search_place_draws``) found cluttered kidnap 5 without the restart.
        search_restart_s: seconds converged before such a restart.
        search_confirmations: after a jump, the car counts as found (the flag comes down and the
            search ends) once this many searches in a row, each started anew from its own
            uniform draw, have settled on the filter's own place (within 1 m and 0.5 rad) with
            no search settling in between on another place that fits as well (one settled on a
            place that fits worse by ``burst_accept`` neither confirms nor refutes), while the
            fit does not say lost (its average at least ``raise_below``, not ``clear_above``:
            searches that agree outweigh a place the old map explains only in half): where the
            car was carried to a place the old map explains less well than the one it left, the
            fit alone would keep the flag up over a car already found; one search can settle on
            the filter's look-alike too (0: only the fit's return to ``jump_found_within`` of
            the usual fit finds it). On 40 honest kidnaps in three draws of the filter, 2 found
            the same kidnaps as 0 and 3 and flagged 1.8-3.6 % of the cluttered kidnap drives'
            steps under 0.3 m (3: 2.3-3.1 %; 0: 4.4-6.7 %), and the clean ones' 1.0-1.5 %
            (3: 1.2-1.9 %; docs/recovery.md).
        search_watch: within ``jump_search_s`` of a jump the search filter runs on once it has
            settled on the filter's place with the flag down (or confirmed it), keeping its
            other places, instead of ending: a place a burst found can be a look-alike that
            the drive refutes seconds later (cluttered kidnap 3: 17 m off). On 40 honest kidnaps
            in three draws of the filter (2026-12-07): found within 15 s 33, 34 and 31 (false:
            33, 34 and 29), the false alarms within 0.2 of a point (docs/recovery.md).
        search_rival: within ``jump_search_s`` of a jump the flag is also up while the search
            filter has settled on another place that fits at least as well as the filter's (a
            rival the scans do not refute; it does not move the filter). On 40 honest kidnaps
            in three draws of the filter (2026-12-08) the flag's recall rose from 0.22-0.32 to
            0.41-0.49 (clean) and from 0.26-0.35 to 0.35-0.48 (cluttered), its precision in
            every draw; its false alarms rose in two draws of six (clean 1.38 -> 1.64 % and
            2.89 -> 3.55 %, cluttered 1.61 -> 1.93 %; docs/recovery.md).
        confirmed_bar: once the searches confirmed a car found after a jump, judge its place by
            its own fit: the averaged fit raises the flag under the average at the confirmation
            minus ``clear_above - raise_below`` (when that is under ``raise_below``), and the
            car's usual fit (the reference) starts afresh there, until the average climbs above
            ``clear_above`` (false: the bars and the record of the place the car left). On 40
            honest kidnaps in the filter's second draw it changed one drive (cluttered kidnap
            13, where the old map explains 0.44-0.55 of the beams at the car's place): the
            cluttered kidnaps' false alarms 3.6 -> 2.2 %; in the other two draws the false
            alarms, precision and times are those of before (docs/recovery.md).
        search_draw_density: poses per m² of the filter map's free floor in the search filter's
            first draw, at its start and at each restart (at most ``search_draw_max``): the first
            scan weighs them all, then the cloud is resampled to the filter's global count
            (``global_density``, 20 per m²), so that a pose close enough to the car for one
            scan to favour it is drawn more often (0: no denser draw; off by default: on 40
            honest kidnaps in three draws of the filter, with plain resampling, 100 per m²
            found 29, 30 and 31 within 15 s against 33, 25 and 30 without, docs/recovery.md).
        search_draw_max: the most poses of such a first draw.
        search_place_draws: draws each place (a cell of ``search_place_m`` metres a side and one
            of ``search_place_headings`` heading sectors) that holds weight is given at each of
            the search filter's resamplings, the particles drawn carrying their weight over the
            draw's ([`mcl.filter.place_keeping`][mcl.filter.place_keeping]): its first scans
            cannot drop the car's place for a look-alike that one scan happened to favour, and
            a later scan that favours a kept place moves the weight there (0: plain resampling).
        search_place_m: metres; the side of a place's cell (world frame).
        search_place_headings: heading sectors of a place's cell.
        search_scan_exponent: the power, in (0, 1], the search filter raises each scan's
            likelihood to, so that the weight moves between the kept places over several scans
            rather than on one (1: Bayes' rule as it is). With 4 draws per place and 0.25, 40
            honest kidnaps in three draws of the filter were found within 15 s 32, 33 and 30
            times, against 33, 25 and 30 with plain resampling and the power 1
            (docs/recovery.md).
        local_below: while the averaged fit is under this fraction (the estimate explains almost
            none of the scan), every ``burst_every_s`` a burst of poses around the estimate is
            weighed with the cloud and kept only when the scan fits its outcome better by
            ``burst_accept``, at least ``clear_above`` and at least the car's usual fit (the
            reference) (0: never).
        local_particles: poses of one such local burst.
        local_sd: metres; their position standard deviation around the estimate (each axis).
        local_heading_sd: radians; their heading standard deviation.
    """

    enabled: bool = True
    fit_tolerance: float = 0.2
    skip_short: bool = True
    beams: int = 100
    window_s: float = 0.75
    raise_below: float = 0.5
    raise_after_s: float = 1.5
    clear_above: float = 0.65
    misfit_ratio: float = 6.0
    reference_s: float = 20.0
    max_position_sd: float = 2.0
    recover: bool = False
    recover_after_jump: bool = True
    jump_below: float = 0.5
    jump_confirm_s: float = 0.5
    jump_hold_s: float = 0.25
    jump_found_within: float = 0.1
    jump_search_s: float = 30.0
    inject_share: float = 0.02
    burst_every_s: float = 1.0
    burst_density: float = 20.0
    burst_max: int = 20_000
    burst_accept: float = 0.1
    search_filter: bool = True
    search_on_lost: bool = False
    search_converged_sd: float = 0.5
    search_adopt_s: float = 0.5
    search_inject_share: float = 0.0
    search_adopt_loglik: float = 30.0
    search_restart_misfit: float = 0.15
    search_restart_s: float = 3.0
    search_confirmations: int = 2
    search_watch: bool = True
    search_rival: bool = True
    confirmed_bar: bool = True
    raise_continuous: bool = True
    standing_holds: bool = True
    search_draw_density: float = 0.0
    search_draw_max: int = 100_000
    search_place_draws: float = 4.0
    search_place_m: float = 2.0
    search_place_headings: int = 8
    search_scan_exponent: float = 0.25
    local_below: float = 0.25
    local_particles: int = 2000
    local_sd: float = 1.5
    local_heading_sd: float = 0.3

    def __post_init__(self) -> None:
        for name in (
            "enabled",
            "recover",
            "recover_after_jump",
            "skip_short",
            "search_filter",
            "search_on_lost",
            "search_watch",
            "search_rival",
            "confirmed_bar",
            "raise_continuous",
            "standing_holds",
        ):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"LostParams.{name} = {short(getattr(self, name))} must be true or false"
                )
        for name in ("beams", "burst_max", "local_particles", "search_draw_max", "search_place_headings",
                     "search_confirmations"):  # fmt: skip
            v = getattr(self, name)
            low = 1 if name in ("beams", "search_draw_max", "search_place_headings") else 0
            high = 360 if name == "search_place_headings" else 1_000_000  # PlaceKeeping's bound
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
                raise ValueError(f"LostParams.{name} = {short(v)} must be an integer in [{low}, {high}]")

        def number(name: str) -> float:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or math.isnan(v):
                raise ValueError(f"LostParams.{name} = {short(v)} must be a number")
            return float(v)

        if not 0.0 <= number("raise_after_s") <= 60.0:
            raise ValueError(
                f"LostParams.raise_after_s = {short(self.raise_after_s)} must lie in [0, 60] seconds"
            )
        checks = {
            "fit_tolerance": (0.0, 10.0, "metres"),
            "window_s": (0.0, 60.0, "seconds"),
            "reference_s": (0.0, 3600.0, "seconds"),
            "burst_every_s": (0.0, 600.0, "seconds"),
            "jump_hold_s": (0.0, 600.0, "seconds"),
            "jump_confirm_s": (0.0, 60.0, "seconds"),
            "jump_search_s": (0.0, 3600.0, "seconds"),
            "burst_density": (0.0, 10_000.0, "particles per m²"),
            "search_converged_sd": (0.0, 100.0, "metres"),
            "search_place_m": (0.0, 1000.0, "metres"),
            "search_scan_exponent": (0.0, 1.0, "(a power)"),
            "search_adopt_s": (0.0, 600.0, "seconds"),
            "search_restart_s": (0.0, 600.0, "seconds"),
            "local_sd": (0.0, 100.0, "metres"),
            "local_heading_sd": (0.0, 10.0, "radians"),
        }
        for name, (low, high, unit) in checks.items():
            v = number(name)
            if not low < v <= high:
                raise ValueError(
                    f"LostParams.{name} = {short(v)} must lie in ({low:g}, {high:g}] {unit}"
                )
        if not 0.0 <= number("search_place_draws") <= 1_000_000.0:
            raise ValueError(
                f"LostParams.search_place_draws = {short(self.search_place_draws)} must lie in "
                "[0, 1000000] draws per place (0: plain resampling)"
            )
        if not 0.0 <= number("search_draw_density") <= 10_000.0:
            raise ValueError(
                f"LostParams.search_draw_density = {short(self.search_draw_density)} must lie in "
                "[0, 10000] poses per m² (0: no denser draw)"
            )
        for name in (
            "raise_below",
            "clear_above",
            "burst_accept",
            "jump_below",
            "jump_found_within",
            "local_below",
        ):
            if not 0.0 <= number(name) <= 1.0:
                raise ValueError(
                    f"LostParams.{name} = {short(getattr(self, name))} must be a fraction in [0, 1]"
                )
        if self.clear_above < self.raise_below:
            raise ValueError(
                f"LostParams.clear_above = {self.clear_above} must be at least raise_below = "
                f"{self.raise_below} (hysteresis)"
            )
        for name in ("inject_share", "search_inject_share"):
            if not 0.0 <= number(name) <= 0.5:
                raise ValueError(
                    f"LostParams.{name} = {short(getattr(self, name))} must lie in [0, 0.5]"
                )
        if not number("search_adopt_loglik") > 0.0:
            raise ValueError(
                f"LostParams.search_adopt_loglik = {short(self.search_adopt_loglik)} must be a "
                "positive number of nats per scan (.inf: never)"
            )
        misfit = number("search_restart_misfit")
        if not (0.0 < misfit <= 1.0 or misfit == math.inf):
            raise ValueError(
                f"LostParams.search_restart_misfit = {short(self.search_restart_misfit)} must be a "
                "fraction of beams in (0, 1] (.inf: never)"
            )
        if not number("misfit_ratio") >= 1.0:
            raise ValueError(
                f"LostParams.misfit_ratio = {short(self.misfit_ratio)} must be >= 1 (.inf: off)"
            )
        if not number("max_position_sd") > 0.0:
            raise ValueError(
                f"LostParams.max_position_sd = {short(self.max_position_sd)} must be > 0 metres (.inf: never)"
            )
