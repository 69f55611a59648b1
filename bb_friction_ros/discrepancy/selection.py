"""
Which effect: best-subset selection of library terms by BIC, confirmed by cross-validation.

The residual r = measured - predicted of the fit part is regressed on the columns of the
candidate terms.  Each term is linear in its amplitudes; a nonlinear parameter (Stribeck
velocity, thermal time constant) is profiled over a log grid, then refined by a bounded 1-D
search.

With six terms and at most ``max_terms`` (3) of them, every subset is fitted (41 subsets, a
fraction of a second), so no greedy path can trap the answer.  For each size m the subset of
lowest BIC = n ln(RSS/n) + k ln n (k = amplitudes + profiled parameters) is kept, provided
its amplitudes have their physical sign (a viscous, seal or Stribeck drag is >= 0).  The size
chosen minimises BIC + ``bic_threshold`` m: every term must bring strong evidence, not just
any improvement.  A larger model must also lower the RMSE of a blocked K-fold
cross-validation (contiguous time blocks) against the next smaller choice, or the smaller one
is kept.  The empty model is a valid answer: clean data selects nothing.
"""

import dataclasses
import itertools
import math

import numpy as np
from scipy.optimize import minimize_scalar

from bb_friction_ros.empirical_terms import LIBRARY, make_term, TermSet

# Tolerance of the 1-D refinement of a nonlinear parameter, in ln units: 1e-3 is 0.1 %,
# far below what a noisy recording can resolve.
REFINE_LOG_TOLERANCE = 1e-3


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A library term as the selection tries it: its fitted amplitudes and its grid."""

    name: str
    linear: tuple
    grid: tuple = (None,)

    @property
    def kind(self):
        """Return the library TermKind."""
        return LIBRARY[self.name]

    @property
    def n_params(self):
        """Return amplitudes plus the profiled nonlinear parameter, as BIC counts them."""
        return len(self.linear) + (0 if self.grid == (None,) else 1)

    def columns(self, x, nl):
        """Return the design columns at inputs ``x`` for nonlinear value ``nl``."""
        return self.kind.columns(x, nl, self.linear)


def _log_grid(lo, hi, n):
    return tuple(float(v) for v in np.geomspace(lo, hi, n))


def candidates(x, settings, skip=()):
    """Return the candidates for fit inputs ``x``; names in ``skip`` are left out."""
    speed = np.abs(x.nut_velocity_rad_s)
    moving = speed[speed > settings.standstill_speed_rad_s]
    span = float(np.max(x.t_s) - np.min(x.t_s))
    out = []
    for name in LIBRARY:
        if name in skip:
            continue
        if name == "lead_error":
            linear = tuple(f"{k}{h}_m" for h in range(1, settings.lead_error_harmonics + 1)
                           for k in ("sin", "cos"))
            out.append(Candidate(name, linear))
        elif name == "stribeck":
            lo = float(np.percentile(moving, 5))
            hi = settings.stribeck_max_speed_fraction * float(np.percentile(moving, 90))
            out.append(Candidate(name, LIBRARY[name].linear,
                                 _log_grid(lo, hi, settings.nonlinear_grid_points)))
        elif name == "thermal_drift":
            out.append(Candidate(name, LIBRARY[name].linear, _log_grid(
                settings.thermal_min_tau_fraction * span,
                settings.thermal_max_tau_fraction * span, settings.nonlinear_grid_points)))
        else:
            out.append(Candidate(name, LIBRARY[name].linear))
    return out


@dataclasses.dataclass(frozen=True)
class Fit:
    """A model: candidates with their nonlinear values, the amplitudes and the scores."""

    members: tuple            # ((Candidate, nl), ...)
    coef: np.ndarray
    rss: float
    bic: float
    physical: bool

    @property
    def names(self):
        """Return the term names in the model."""
        return tuple(c.name for c, _ in self.members)


def _design(members, x, cache=None):
    n = x.t_s.size
    cols = []
    for c, nl in members:
        key = (c.name, nl)
        if cache is None or key not in cache:
            a = c.columns(x, nl)
            if cache is None:
                cols.append(a)
                continue
            cache[key] = a
        cols.append(cache[key])
    return np.hstack(cols) if cols else np.zeros((n, 0))


def _bic(rss, n, k):
    # floor: an exact fit (noise-free synthetic data) must not give log(0)
    return n * math.log(max(rss, 1e-300) / n) + k * math.log(n)


def _in_range(cls, name, value):
    meta = {f.name: f.metadata for f in dataclasses.fields(cls)}[name]
    return (meta["lo"] is None or value >= meta["lo"]) and \
        (meta["hi"] is None or value <= meta["hi"])


def _is_physical(members, coef):
    """Tell whether every amplitude has its physical sign and lies in its validated range."""
    i = 0
    for c, _ in members:
        for name in c.linear:
            if name in c.kind.nonnegative and coef[i] < 0.0:
                return False
            if not _in_range(c.kind.params_cls, name, coef[i]):
                return False
            i += 1
    return True


def fit(members, x, r, cache=None):
    """
    Least-squares fit of residual ``r`` on the model ``members``; return a Fit.

    ``cache`` (a dict) keeps the design columns of (term, nonlinear value) between calls on
    the same ``x``: profiling evaluates each many times.
    """
    members = tuple(members)
    a = _design(members, x, cache)
    n = r.size
    if a.shape[1] == 0:
        coef = np.zeros(0)
        rss = float(r @ r)
    else:
        coef, *_ = np.linalg.lstsq(a, r, rcond=None)
        res = r - a @ coef
        rss = float(res @ res)
    k = sum(c.n_params for c, _ in members)
    return Fit(members, coef, rss, _bic(rss, n, k), _is_physical(members, coef))


def cv_rmse(members, x, r, folds):
    """Return the RMSE of a blocked K-fold cross-validation (contiguous blocks in time)."""
    a = _design(tuple(members), x)
    n = r.size
    if a.shape[1] == 0:
        return float(np.sqrt(np.mean(r ** 2)))
    edges = np.linspace(0, n, folds + 1).astype(int)
    sq = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        train = np.ones(n, dtype=bool)
        train[lo:hi] = False
        coef, *_ = np.linalg.lstsq(a[train], r[train], rcond=None)
        e = r[lo:hi] - a[lo:hi] @ coef
        sq += float(e @ e)
    return math.sqrt(sq / n)


def refine(f, x, r, cache=None):
    """
    Re-profile each nonlinear value over its whole grid, then refine it by a bounded search.

    One pass, in model order, the others held.  The whole grid, not just the neighbourhood:
    a term that entered first may have stood in for a later one at another value.
    """
    members = list(f.members)
    for i, (cand, nl) in enumerate(members):
        if nl is None:
            continue

        def cost(log_nl, i=i, cand=cand):
            trial = members[:i] + [(cand, float(math.exp(log_nl)))] + members[i + 1:]
            g = fit(trial, x, r, cache)
            # a finite penalty (worse than no model at all) keeps the search arithmetic sane
            return g.rss if g.physical else 2.0 * float(r @ r)

        grid = np.log(np.array(cand.grid))
        costs = [cost(v) for v in grid]
        k = int(np.argmin(costs))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        best_log, best_cost = grid[k], costs[k]
        if hi > lo:
            res = minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                                  options={"xatol": REFINE_LOG_TOLERANCE})
            if res.fun < best_cost:
                best_log, best_cost = res.x, res.fun
        if best_cost < cost(math.log(nl)):
            members[i] = (cand, float(math.exp(best_log)))
    return fit(members, x, r, cache)


def best_fit(subset, x, r, cache=None):
    """
    Return the best physical Fit of the terms ``subset``, or None if none is physical.

    The nonlinear values are profiled jointly over the product of their grids (at most two
    terms carry one), then refined (``refine``).
    """
    best = None
    for nls in itertools.product(*(c.grid for c in subset)):
        f = fit(tuple(zip(subset, nls)), x, r, cache)
        if f.physical and (best is None or f.bic < best.bic):
            best = f
    if best is None or all(nl is None for _, nl in best.members):
        return best
    refined = refine(best, x, r)      # no cache: the refined values are used once
    return refined if refined.physical and refined.rss <= best.rss else best


def select(x, r, settings, skip=()):
    """
    Select terms explaining residual ``r`` at fit inputs ``x`` (an empirical_terms.Inputs).

    Best-subset selection: for each size m <= max_terms the subset of lowest BIC; the size
    chosen minimises BIC + bic_threshold * m (every term must earn strong evidence), and a
    larger model must also beat the next smaller choice in blocked cross-validation.
    Return (TermSet, trace): the trace has one row per size for the report.
    """
    cands = candidates(x, settings, skip)
    best = {0: fit((), x, r)}
    cache = {}
    for m in range(1, min(settings.max_terms, len(cands)) + 1):
        for subset in itertools.combinations(cands, m):
            f = best_fit(subset, x, r, cache)
            if f is not None and (m not in best or f.bic < best[m].bic):
                best[m] = f
    score = {m: f.bic + settings.bic_threshold * m for m, f in best.items()}
    cv = {}

    def cv_of(m):
        if m not in cv:
            cv[m] = cv_rmse(best[m].members, x, r, settings.cv_folds)
        return cv[m]

    chosen = min(score, key=score.get)
    while chosen > 0:
        smaller = min((m for m in score if m < chosen), key=score.get)
        if cv_of(chosen) < cv_of(smaller):
            break
        chosen = smaller      # not confirmed out of sample: fall back to the smaller model
    trace = [{"size": m, "terms": list(f.names), "bic": f.bic, "penalised_bic": score[m],
              "cv_rmse_nm": cv.get(m), "rss_nm2": f.rss, "chosen": m == chosen}
             for m, f in sorted(best.items())]
    return to_termset(best[chosen]), trace


def to_termset(f):
    """Convert a Fit into a TermSet of validated terms."""
    terms = []
    i = 0
    for cand, nl in f.members:
        values = {}
        for name in cand.linear:
            values[name] = float(f.coef[i])
            i += 1
        if cand.kind.nonlinear:
            values[cand.kind.nonlinear] = float(nl)
        terms.append(make_term(cand.name, values))
    return TermSet(terms)
