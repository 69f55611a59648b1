"""
The selection with the physical candidates beside the empirical library, and its hooks.

``PhysicalSelection`` brackets and refines the candidates (scored on their profiles:
``profile``); ``choice.PhysicalDecision`` decides between the best of them and "none".
The hooks at the end are what the workflow calls.
"""

import math

import numpy as np

from bb_friction_ros.discrepancy.physical.choice import PhysicalDecision
from bb_friction_ros.discrepancy.physical.identifiability import _tie, _unchosen_twins
from bb_friction_ros.discrepancy.physical.profile import (
    _held, _next_value, _penalised, _Point, _Profile)
from bb_friction_ros.discrepancy.physical.results import Outcome, PhysicalSearch
from bb_friction_ros.discrepancy.physical.trials import chosen, PHYSICAL, TrialRunner, TWINS
from bb_friction_ros.discrepancy.selection import candidates
from bb_friction_ros.discrepancy.selection import select as select_empirical
from bb_friction_ros.model_file import load_model_file


def select_with_physics(physics, rec_all, ok, fit_mask, r, x_fit, settings, skip, fixed, tau):
    """
    Select as selection.select does, with the physical candidates beside the library.

    ``rec_all``: the input recording (every sample drives the model), ``ok``: its usable
    samples (``r``, ``fit_mask`` are over them).  Return (TermSet, trace, SelectionContext,
    PhysicalSearch); the PhysicalSearch's ``chosen`` is None when no physical effect is
    chosen (the TermSet is then exactly selection.select's).  The steps are
    ``PhysicalSelection``'s.
    """
    return PhysicalSelection(physics, rec_all, ok, fit_mask, r, x_fit, settings, skip,
                             fixed, tau).run()


class PhysicalSelection:
    """
    One selection with the physical candidates beside the library, step by step.

    1. The empirical selection on r ("none": no physical change; ``outcome``).
    2. The bracket (``bracket``): a model run per trial value.  Each is scored by its
       profile (the RSS of r - d(p) with none's terms held, its twin left out: ``_Profile``),
       not by a selection of its own: only the model column changes between trials.
    3. A candidate is refined only if its change, at the best scale (the free amplitude of
       a bracket run), could beat "none": the bound no value of the same shape exceeds
       (``bound``).  Where "none" holds the candidate's twin and that bound fails, the bound
       with the twin held too (``bound_with_twin``); a candidate that passes so is refined
       with the twin beside it.  At most ``refine_candidates`` are refined (``refine``), in
       rounds of one model run each (a batch on the Dask cluster), at ``_next_value``; after
       the first round the empirical selection is re-run at the candidate's best value and
       its terms are held instead.
    4. The empirical selection at each refined candidate's best value decides (``decide``),
       under the penalised BIC (the parameter counted) and the blocked cross-validation,
       against "none".  A tie with the twin (``_tie``) is decided on the whole recording:
       the held-out part's evidence on the two readings is added (``_heldout_gap``).

    State, per candidate name: ``bases`` (the config's value), ``points`` (its model runs,
    ``_Point``), ``profiles`` (the profile its runs are scored on), ``bounds`` (the best
    penalised BIC a run's change reaches at its free scale); ``rows`` maps (name, value) to
    the trial's row in ``search.trials``.
    """

    def __init__(self, physics, rec_all, ok, fit_mask, r, x_fit, settings, skip, fixed, tau):
        """Keep the recording, its fit part and the selection's settings."""
        self.physics = physics
        self.ps = physics.settings
        self.rec_all, self.ok, self.fit_mask, self.r = rec_all, ok, fit_mask, r
        self.x_fit, self.settings, self.skip, self.fixed, self.tau = \
            x_fit, settings, skip, fixed, tau
        self.r_fit = r[fit_mask]
        self.n_fit = self.r_fit.size
        self.selections = 0           # empirical selections run
        self.none = None              # the Outcome without a physical change
        self.runner = None            # TrialRunner
        self.search = None            # PhysicalSearch, the result
        self.bases, self.points, self.profiles, self.rows = {}, {}, {}, {}
        self.bounds = {}
        self.twin_held = set()        # candidates read with their twin held (bound_with_twin)
        self.selected = {}            # (name, value): the Outcome selected there
        self.cands = {}               # the empirical library's candidates by name

    def run(self):
        """Return (TermSet, trace, SelectionContext, PhysicalSearch) of the selection."""
        ps = self.ps
        self.none = none = self.outcome(None, None)
        self.runner = runner = TrialRunner(self.rec_all, self.physics.config_path,
                                           self.physics.runner_args, ps.workers, ps.threads,
                                           ps.coarse_step_factor)
        self.search = search = PhysicalSearch(workers=ps.workers, base=runner.base,
                                              usable=self.ok, none_score=none.score,
                                              threads=ps.threads,
                                              coarse_step_factor=ps.coarse_step_factor)
        search.base_run_kept = runner.base.first_pass
        try:
            cfg = load_model_file(self.physics.config_path)[0]
            self.bases = {k.name: k.base_value(cfg) for k in PHYSICAL.values()}
            self.points = {name: [] for name in PHYSICAL}
            self.profiles = {k.name: self.profile(_held(k, none)) for k in PHYSICAL.values()}
            self.bracket()
            self.bounds = {name: self.bound(name) for name in PHYSICAL}
            for name in PHYSICAL:
                self.bound_with_twin(name)
            active = sorted((n for n in PHYSICAL
                             if self.bounds[n] < none.score + self.tie_margin(n)),
                            key=self.bounds.get)[:ps.refine_candidates]
            finals = self.refine(active)
            best = None
            # the candidates that beat "none", or tie with its twin, first; then by score
            for o in sorted(finals, key=lambda o: (not (o.score < none.score or self.tie(o)),
                                                   o.score)):
                best = self.confirmed(o)
                if best is not None:
                    break
            if best is None:
                search.identifiability = _unchosen_twins(self.bounds, self.points, none,
                                                         self.settings)
                return none.terms, none.trace, none.ctx, search
            self.cands = {c.name: c for c in candidates(self.x_fit, self.settings,
                                                        self.skip, self.fixed)}
            chosen = PhysicalDecision(self).decide(best, finals)
        finally:
            runner.close()
            search.runs, search.wall_s = runner.runs, runner.wall_s
            search.coarse_runs = runner.coarse_runs
            search.selections = self.selections
        return chosen.terms, chosen.trace, chosen.ctx, search

    def profile(self, members):
        """Return the _Profile of the fit part with ``members`` held."""
        return _Profile(members, self.x_fit, self.r_fit, self.tau, self.settings)

    def outcome(self, kind, pt):
        """Return the Outcome of the empirical selection on r - d(p) at ``pt`` (None: r)."""
        self.selections += 1
        d_fit = pt.d_fit if pt is not None else 0.0
        terms, trace, ctx = select_empirical(self.x_fit, self.r_fit - d_fit, self.settings,
                                             skip=self.skip, fixed=self.fixed, tau=self.tau)
        score = _penalised(trace, 0 if kind is None else 1, self.settings, self.tau,
                           self.n_fit)
        return Outcome(kind, None if pt is None else pt.value, terms, trace, ctx, score,
                       None if pt is None else pt.run, None if pt is None else d_fit)

    def consider(self, kind, run, prof=None):
        """Record a trial's row and, when the model converged, its _Point (returned)."""
        ok = self.ok
        conv = run.converged[ok]
        bad = float(np.mean(~conv | ~np.isfinite(run.total_nm[ok])))
        row = {"candidate": kind.name, "param": kind.param, "value": run.value,
               "nonconverged_fraction": bad, "selection": False, "coarse": run.coarse}
        self.search.trials.append(row)
        if bad > self.ps.max_nonconverged_fraction:
            row.update(penalised_bic=None, terms=None,
                       note="not used: the model did not converge")
            return None
        pt = _Point(run.value, run, np.nan_to_num(run.delta_nm[ok])[self.fit_mask])
        prof = prof or self.profiles[kind.name]
        row.update(penalised_bic=prof.score(prof.rss(pt.d_fit)),
                   terms=[c.name for c, _ in prof.members])
        if run.coarse or (kind.name, pt.value) not in self.rows:
            self.rows[(kind.name, pt.value)] = row
        points = self.points[kind.name]
        if not run.coarse or not any(q.value == pt.value for q in points):
            points.append(pt)
        return pt

    def bracket(self):
        """Run the bracket of every candidate: a model run per trial value."""
        tried = [(k, v) for k in PHYSICAL.values()
                 for v in k.bracket(self.bases[k.name], self.ps)]
        for (kind, _), run in zip(tried, self.runner.run(tried)):
            self.consider(kind, run)

    def bound(self, name):
        """
        Return the best penalised BIC any scale of a run's change reaches (terms held).

        With none's terms held or any one of them dropped: a term of "none" may stand in for
        the change itself (mu 0.0869 hidden: none's seal_drag, held, cost the price of a term
        the change did not need, and mu was never refined).
        """
        held = self.profiles[name].members
        subsets = [held] + [held[:i] + held[i + 1:] for i in range(len(held))]
        best = math.inf
        for sub in subsets:
            prof = self.profiles[name] if sub is held else self.profile(sub)
            free = [prof.amplitude(pt.d_fit) for pt in self.points[name]]
            best = min([best] + [prof.score(rss) for a, _, rss in free if a > 0.0])
        return best

    def tie_margin(self, name):
        """
        Return how far above "none" a candidate's bound may be and still be refined.

        A candidate whose twin "none" holds may be kept on a tie with it (_tie): it needs to
        come within bic_threshold of "none", not to beat it.
        """
        return self.settings.bic_threshold if self.ps.prefer_model_parameter_on_tie and \
            TWINS[name] in self.none.terms.names else 0.0

    def bound_with_twin(self, name):
        """
        Bound a candidate the gate leaves out, whose twin "none" holds, with the twin held.

        Beside none's other terms, or in place of one of them, as the twin's reading after a
        choice (``with_twin``) is taken.  The twin-less bound cannot see a change that is
        there beside its twin: bench seed 13's mu 0.112 with a hidden load_dependent (named
        load_dependent + thermal_drift, mu never refined).  Such a candidate beats "none"
        only outright (holding the twin, it cannot tie with it), and is refined on that
        profile: its value is read with the twin beside it.
        """
        none, points = self.none, self.points[name]
        twin = TWINS[name]
        if self.bounds[name] < none.score + self.tie_margin(name) or \
                twin not in none.terms.names or not points:
            return
        full = tuple(none.members)
        variants = [full] + [full[:i] + full[i + 1:] for i in range(len(full))
                             if full[i][0].name != twin]
        profs = [self.profile(v) for v in variants]
        reach = [min([math.inf] + [prof.score(rss) for a, _, rss in
                                   (prof.amplitude(pt.d_fit) for pt in points)
                                   if a > 0.0]) for prof in profs]
        k = int(np.argmin(reach))
        if reach[k] < none.score:
            self.bounds[name] = reach[k]
            self.profiles[name] = profs[k]
            self.twin_held.add(name)

    def held_of(self, name, o):
        """
        Return the terms held while the value is refined.

        The twin left out (_held), unless the candidate is read with its twin beside it
        (``twin_held``).
        """
        return o.members if name in self.twin_held else _held(PHYSICAL[name], o)

    def best_of(self, name):
        """Return the candidate's run of the least RSS on its profile."""
        prof = self.profiles[name]
        return min(self.points[name], key=lambda pt: prof.rss(pt.d_fit))

    def refine(self, active):
        """Refine the ``active`` candidates; return the Outcome at each one's best value."""
        for step in range(self.ps.refine_runs):
            batch = []
            for name in active:
                v = _next_value(PHYSICAL[name], self.points[name], self.bases[name],
                                self.profiles[name], self.ps)
                if v is not None:
                    batch.append((PHYSICAL[name], v))
            if not batch:
                break
            for (kind, _), run in zip(batch, self.runner.run(batch)):
                self.consider(kind, run)
            if step == 0:
                # the empirical terms at the best value so far: held from now on
                for name in active:
                    pt = self.best_of(name)
                    o = self.outcome(PHYSICAL[name], pt)
                    self.selected[(name, pt.value)] = o
                    self.profiles[name] = self.profile(self.held_of(name, o))
        finals = []
        for name in active:
            pt = self.best_of(name)
            o = self.selected.get((name, pt.value)) or self.outcome(PHYSICAL[name], pt)
            if name in self.twin_held:
                o.profile = self.profiles[name]      # its interval is read on that profile
            row = self.rows[(name, pt.value)]
            row.update(penalised_bic=o.score, terms=list(o.terms.names), selection=True)
            finals.append(o)
        return finals

    def fine_point(self, kind, pt):
        """
        Return ``pt`` run again at the replay path's step if it was found at the coarse one.

        The change the selection decides on, the report plots and augmented.yaml runs;
        None: that run did not converge.
        """
        if not pt.run.coarse:
            return pt
        fine_pt = self.consider(kind, self.runner.run([(kind, pt.value)], fine=True)[0])
        if fine_pt is not None:
            self.search.trials[-1]["rerun"] = True
            self.points[kind.name] = [q for q in self.points[kind.name]
                                      if q.value != pt.value or q is fine_pt]
        return fine_pt

    def confirmed(self, o):
        """
        Return the outcome ``o`` at the replay step (None: its run there did not converge).

        Only the winner is run again (the coarse change is within 0.5 % of the fine one: the
        ranking of the candidates does not hang on it).
        """
        if not o.run.coarse:
            return o
        pt = self.fine_point(o.kind, _Point(o.value, o.run, o.delta_fit))
        if pt is None:
            return None
        f = self.outcome(o.kind, pt)
        f.profile = o.profile
        self.search.trials[-1].update(penalised_bic=f.score, terms=list(f.terms.names),
                                      selection=True)
        return f

    def tie(self, o):
        """Tell whether ``o`` ties with its twin and the model's parameter is preferred."""
        return self.ps.prefer_model_parameter_on_tie and _tie(o, self.none, self.settings)


# ------------------------------------------------------------------------------------------
# Hooks of the workflow (workflow.py, report.py): small, so the workflow reads as before


def select(physics, rec_in, ok, fit_mask, r, x_fit, settings, skip, fixed, tau):
    """
    Return (TermSet, trace, SelectionContext, PhysicalSearch or None): the selection.

    ``physics`` None (no model of the screw, or physical candidates not asked for):
    selection.select exactly, and no PhysicalSearch.
    """
    if physics is None:
        terms, trace, ctx = select_empirical(x_fit, r[fit_mask], settings, skip=skip,
                                             fixed=fixed, tau=tau)
        return terms, trace, ctx, None
    search = select_with_physics(physics, rec_in, ok, fit_mask, r, x_fit, settings, skip,
                                 fixed, tau)
    search[3].context = physics
    return search


def shift_nm(search, n):
    """Return the chosen physical change of the model torque at the usable samples (or 0)."""
    if search is None or search.chosen is None:
        return np.zeros(n)
    return search.chosen.delta_nm


def unseen_on_hold(search, shift_hold, noise, n_fit, settings):
    """
    Tell whether the held-out part cannot judge the chosen physical change (and say so).

    The held-out check keeps a choice only if the held-out RMSE falls ("after < before").
    For a change d that is really there, RSS after - before = -|d|^2 - 2 e.d on the held-out
    part, so the check fails with probability Phi(-sqrt(E) / 2), E = |d|^2 / (sigma^2 tau)
    the change's evidence there.  The selection demanded of the change the price of a
    parameter, ln n' + bic_threshold, on the fit part.  Where the held-out part holds less
    evidence than that price, it cannot tell the change from nothing (at E = 16.6 a true
    change fails 2 % of the time, at E = 1.7 26 %, at E = 0 half the time).  A theta whose
    B2B contacts close on the fit part only is such a change.  Then the held-out part does
    not judge it, and the choice stands on the fit part's penalised BIC and blocked
    cross-validation.  ``search.notes`` says so.
    """
    choice = chosen(search)
    if choice is None:
        return False
    tau = max(noise.tau, 1.0)
    evidence = float(shift_hold @ shift_hold) / (noise.std_nm ** 2 * tau)
    price = math.log(n_fit / tau) + settings.bic_threshold
    if not evidence < price:
        return False
    fails = 0.5 * math.erfc(math.sqrt(evidence) / 2.0 / math.sqrt(2.0))
    search.heldout_judged = False
    search.notes.append(
        f"the held-out part does not judge {choice.kind.name}: its change there carries "
        f"|d|^2/sigma^2 = {evidence:.2g}, below the price of a parameter (ln n' + "
        f"bic_threshold = {price:.1f}); a true change would fail 'after < before' there with "
        f"probability {fails:.0%}, so the fit part's evidence decides")
    return True


def reject(search):
    """Drop the chosen physical effect (the held-out part disagreed); keep it as rejected."""
    if search is not None and search.chosen is not None:
        search.rejected, search.chosen = search.chosen, None
        search.identifiability = []
