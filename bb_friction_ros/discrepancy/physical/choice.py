"""
The choice of a physical value: its second reading with the twin, its interval, the verdict.

``PhysicalDecision`` takes the best refined candidate of a ``PhysicalSelection`` and decides,
under the penalised BIC (the parameter counted) and the blocked cross-validation, between it
and "none" (no physical change).  A tie with the twin (``_tie``) is decided on the whole
recording: the held-out part's evidence on the two readings is added (``_heldout_gap``).
"""

import math

import numpy as np

from bb_friction_ros.discrepancy.physical.identifiability import (
    _cv_judges, _heldout_gap, _other_parameters, _unchosen_twins, identifiability)
from bb_friction_ros.discrepancy.physical.profile import _held, _interval, _next_value
from bb_friction_ros.discrepancy.physical.results import PhysicalChoice
from bb_friction_ros.discrepancy.physical.trials import TWINS
from bb_friction_ros.discrepancy.selection import cv_rmse


class PhysicalDecision:
    """
    The verdict on the best refined candidate of a ``PhysicalSelection`` (``decide``).

    Reads and extends the selection's runs and trials (``sel``): a second reading with the
    twin held runs the model again (``with_twin``).
    """

    def __init__(self, selection):
        """Decide on the runs of ``selection`` (a PhysicalSelection)."""
        self.sel = selection

    def with_twin(self, o):
        """
        Return the outcome at the best value of o's candidate with its twin beside it.

        The profile (and so the value) was taken without the twin: held, the twin flattens
        it (_held).  But the twin may be there as well: a hidden mu 0.0749 with a hidden
        load_dependent was named mu 0.0875 + seal_drag (penalised BIC -7354.8), while mu
        0.0749 + load_dependent scores -7355.0 and was never tried.  So the profile with
        the twin held (beside the held terms or in place of one: whichever a run's change
        at its free scale fits best) is followed too, refined as above from the runs so
        far (at most refine_runs runs, none where the change's scale already says the
        chosen value); where its best value is the chosen one's, or the config's (the
        twin alone: "none"), there is no second reading.
        """
        ps = self.sel.ps
        kind, twin = o.kind, self.sel.cands.get(TWINS[o.kind.name])
        if twin is None or twin.name in o.terms.names:
            return None
        pts = [q for q in self.sel.points[kind.name] if q.d_fit is not None]
        # the twin beside the held terms, or in place of one of them: mu's change is
        # nearly seal_drag + load_dependent, so mu + seal_drag and mu' + load_dependent
        # are two readings (seal_drag standing in for part of the change, as in bound)
        held = _held(kind, o)
        variants = [held] + [held[:i] + held[i + 1:] for i in range(len(held))]
        profs = [self.sel.profile(v + ((twin, None),)) for v in variants]

        def reach(prof):
            # the best penalised BIC a run's change reaches at its free scale
            return min([math.inf] + [prof.score(rss) for a, _, rss in
                                     (prof.amplitude(q.d_fit) for q in pts) if a > 0.0])

        prof = min(profs, key=reach)
        for _ in range(ps.refine_runs):
            v = _next_value(kind, pts, self.sel.bases[kind.name], prof, ps)
            if v is None:
                break
            pt = self.sel.consider(kind, self.sel.runner.run([(kind, v)])[0], prof)
            if pt is None:
                break
            self.sel.search.trials[-1]["twin_held"] = twin.name
            pts.append(pt)
        zero = prof.rss(np.zeros_like(prof.mr))
        pt = min(pts, key=lambda q: prof.rss(q.d_fit))
        if prof.rss(pt.d_fit) >= zero or pt.value == o.value or \
                abs(pt.value - o.value) < kind.resolution(ps):
            return None
        pt = self.sel.fine_point(kind, pt)
        if pt is None:
            return None
        alt = self.sel.outcome(kind, pt)
        row = [t for t in self.sel.search.trials if t["candidate"] == kind.name and
               t["value"] == pt.value and t.get("penalised_bic") is not None][-1]
        row.update(penalised_bic=alt.score, terms=list(alt.terms.names), selection=True)
        alt.profile = prof
        return alt

    def interval_of(self, kind, o):
        """Return the 95 % interval of ``o``'s value on its profile (``_interval``)."""
        return _interval(o.value, self.sel.points[kind.name], self.sel.bases[kind.name],
                         o.profile or self.sel.profile(_held(kind, o)))

    def interval(self, best, other):
        """
        Return the 95 % interval of the chosen value; (None, None): not a minimum.

        Two readings the data cannot tell apart (``other`` within bic_threshold): the value's
        interval covers both, each with its own profile's interval (with the twin held, the
        profile is nearly flat: wide).
        """
        kind = best.kind
        interval = self.interval_of(kind, best)
        if other is not None and other.score - best.score < self.sel.settings.bic_threshold:
            both = [interval, self.interval_of(kind, other)]
            if any(lo is not None for lo, _ in both):
                ends = [v for pair in both for v in pair if v is not None]
                interval = (min(ends + [best.value, other.value]),
                            max(ends + [best.value, other.value]))
        if interval[0] is None:
            # the best value is at the edge of what was tried: not a minimum of its profile
            # (a parameter the bracket did not resolve, or another effect it stands in for)
            self.sel.search.notes.append(f"{kind.name}: its best value {best.value:.4g} is "
                                         "at the edge of the values tried, not a minimum of "
                                         "its profile: not adopted")
        return interval

    def break_tie(self, best):
        """
        Return (ties, broken, fit gap, held-out gap) of the best outcome against "none".

        On a tie with the twin (_tie) the fit part cannot choose; the held-out part's
        evidence on the same question is added (_heldout_gap): the tie stands if the whole
        recording cannot choose.  ``broken``: (fit gap, held-out gap) of a tie the held-out
        part broke.
        """
        none, settings, kind = self.sel.none, self.sel.settings, best.kind
        ties = not best.score < none.score and self.sel.tie(best)
        broken = None
        fit_gap, held_gap = best.score - none.score, 0.0
        if ties:
            held_gap = _heldout_gap(best, none, self.sel.rec_all, self.sel.ok, self.sel.fit_mask,
                                    self.sel.r, self.sel.tau)
            if not fit_gap + held_gap < settings.bic_threshold:
                ties, broken = False, (fit_gap, held_gap)
                self.sel.search.notes.append(
                    f"{kind.name} tied with {TWINS[kind.name]} on the fit part "
                    f"({', '.join(none.terms.names)} better by a penalised BIC of "
                    f"{fit_gap:.1f} < {settings.bic_threshold}), but the held-out part, "
                    f"where both readings predict as fitted, adds {held_gap:.1f} for "
                    f"{TWINS[kind.name]}: {fit_gap + held_gap:.1f} >= "
                    f"{settings.bic_threshold} over the whole recording, which is no tie; "
                    f"{TWINS[kind.name]} is kept")
        return ties, broken, fit_gap, held_gap

    def decide(self, best, finals):
        """Choose between the best physical outcome and "none"; return the chosen Outcome."""
        none, settings, search = self.sel.none, self.sel.settings, self.sel.search
        other = self.with_twin(best) if best.score < none.score else None
        if other is not None and other.score < best.score:
            best, other = other, best
        kind = best.kind
        interval = self.interval(best, other)
        # on a tie with the twin (_tie) the parameter must lower the cross-validated RMSE
        # against "none" without the twin, as a term must against the model without it:
        # against the twin itself it is as much a coin toss as the BIC
        ties, broken, fit_gap, held_gap = self.break_tie(best)
        versus = tuple(m for m in none.members if m[0].name != TWINS[kind.name]) if ties \
            else none.members
        # a reading smaller than the "none" it beats is not vetoed by cross-validation
        # (_cv_judges): the empirical selection's own rule
        smaller = not _cv_judges(best, none, ties)
        folds = settings.cv_folds
        if not (interval[0] is not None and (best.score < none.score or ties) and
                (smaller or
                 cv_rmse(best.members, self.sel.x_fit, self.sel.r_fit - best.delta_fit, folds) <
                 cv_rmse(versus, self.sel.x_fit, self.sel.r_fit, folds))):
            search.identifiability = _unchosen_twins(self.sel.bounds, self.sel.points, none,
                                                     settings, kind, broken)
            return none
        delta = np.nan_to_num(best.run.delta_nm[self.sel.ok])
        search.chosen = PhysicalChoice(kind, best.value, self.sel.bases[kind.name], interval,
                                       best.run, delta)
        search.tie = ties
        if smaller:
            search.notes.append(
                f"{' + '.join((kind.name,) + best.terms.names)} (the parameter counted "
                f"as one term) beats the larger empirical-only model "
                f"({', '.join(none.terms.names)}) by a penalised BIC of "
                f"{none.score - best.score:.1f}; cross-validation, which vetoes only "
                "a larger model against a smaller one, is not applied against it")
        if ties:
            search.notes.append(
                f"{kind.name} ties with {TWINS[kind.name]}: the empirical-only model "
                f"({', '.join(none.terms.names)}) fits better by a penalised BIC of "
                f"{fit_gap:.1f} on the fit part and {held_gap:.1f} on the held-out part "
                f"(-2 ln of the likelihood ratio of the two readings as fitted), "
                f"{fit_gap + held_gap:.1f} < {settings.bic_threshold} over the whole "
                "recording, "
                + ("which favours the parameter" if fit_gap + held_gap < 0.0 else
                   "which the data cannot tell from noise")
                + "; the model's own parameter is kept (prefer_model_parameter_on_tie)")
        sel = self.sel
        search.identifiability = identifiability(search.chosen, best, none, sel.x_fit,
                                                 sel.r_fit, settings, sel.tau, sel.skip,
                                                 sel.fixed, other)
        search.identifiability += _other_parameters(kind, best, self.sel.bounds, finals,
                                                    self.sel.points, settings)
        return best
