"""
Which effect: best-subset selection of library terms by BIC, confirmed by cross-validation.

The residual r = measured - predicted of the fit part is regressed on the columns of the
candidate terms.  Each term is linear in its amplitudes; a nonlinear parameter (Stribeck
velocity, thermal time constant) is profiled over a log grid, then refined by a bounded 1-D
search.

Every subset of at most ``max_terms`` (5) of the library's terms is fitted, so no greedy path
can trap the answer; ``Gram`` makes each fit a few small solves, independent of the number of
samples.  For each size m the subset of lowest BIC = n' ln(RSS/n) + k ln n' (k = amplitudes
+ profiled parameters; n' = n / tau, the effective samples of correlated noise) is kept,
provided its amplitudes have their physical sign (a viscous, seal or Stribeck drag is >= 0)
and lie in their validated range.  The size chosen minimises BIC + ``bic_threshold`` m:
every term must bring strong evidence, not just any improvement (without a model of the
drive the rigid-body terms need only ``rigid_body_bic_threshold``: ``penalty``).  A larger
model must also lower the RMSE of a blocked K-fold cross-validation (contiguous time blocks)
against the next smaller choice, or the smaller one is kept.  The empty model is a valid
answer: clean data selects nothing.
"""

import dataclasses
import itertools
import math

import numpy as np
from scipy.optimize import minimize_scalar

from bb_friction_ros.empirical_terms import (AMBIGUOUS_PAIRS, Inputs, LIBRARY, make_term,
                                             TermSet)

# Tolerance of the 1-D refinement of a nonlinear parameter, in ln units: 1e-3 is 0.1 %,
# far below what a noisy recording can resolve.
REFINE_LOG_TOLERANCE = 1e-3
# Subsets per size whose nonlinear values are refined beyond the grid: the grid already ranks
# them; refining every subset would cost a bounded search each.
REFINED_PER_SIZE = 3
# The rigid-body reference's terms (reference.FORMULA: J alpha + c omega + T_c sign omega +
# T_0) as library terms.  Without a model of the drive they are the textbook floor of every
# motor torque, so they need only settings.rigid_body_bic_threshold (on driveNo2 the
# viscous drag, BIC gain 2.6 < 10, was left out and the workflow validated 1.2 % worse than
# the reference).
RIGID_BODY_TERMS = ("inertia", "viscous_drag", "seal_drag", "offset")
# Terms that shape a Coulomb level rather than add one: a Stribeck excess at low speed over
# it (T_c + (T_s - T_c) g(v)), and the build-up of it after a reversal (the Dahl element
# carries the Coulomb friction).  Without a model of the drive that level is seal_drag's, so
# they enter only with it (a hierarchical model, as an interaction needs its main effects):
# alone, a Stribeck term of high velocity stood in for the Coulomb level on the fit part
# and fell away at the held-out part's higher speeds (a calibration run at 0.25-3 rev/s:
# held-out RMSE 0.145 -> 0.269 N m).  With a model the physics carries the Coulomb level.
COULOMB_SHAPERS = ("stribeck", "pre_rolling")
COULOMB_LEVEL = "seal_drag"


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A library term as the selection tries it: its fitted amplitudes and its grid."""

    name: str
    linear: tuple
    grid: tuple = (None,)
    fixed: tuple = ()         # ((param, value), ...) set from the data, not fitted

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
        return self.kind.design(x, nl, self.linear, dict(self.fixed))


def _log_grid(lo, hi, n):
    return tuple(float(v) for v in np.geomspace(lo, hi, n))


def reversal_rotation_rad(x):
    """
    Return the median nut rotation of the first sample after a reversal [rad], or None.

    A reversal is a sample moving against the last direction the nut moved in (a start from
    rest in the other direction too).  Its rotation since the sample before says how finely
    the recording resolves what happens right after a reversal.
    """
    phi = np.asarray(x.nut_angle_rad, dtype=float)
    s = np.sign(np.asarray(x.nut_velocity_rad_s, dtype=float))
    idx = np.flatnonzero(s != 0.0)
    if idx.size < 2:
        return None
    # the last nonzero direction before each sample
    last = s[idx[np.maximum(np.searchsorted(idx, np.arange(s.size)) - 1, 0)]]
    rev = np.flatnonzero((s != 0.0) & (last != 0.0) & (s != last))
    rev = rev[rev > 0]
    if not rev.size:
        return None
    return float(np.median(np.abs(phi[rev] - phi[rev - 1])))


def pre_rolling_grid(x, settings):
    """Return the travels to try for ``pre_rolling`` [rad], or a reason it cannot be seen."""
    step = reversal_rotation_rad(x)
    if step is None:
        return "no reversal: pre-rolling shows only after the nut changes direction"
    lo = max(settings.pre_rolling_min_travel_rad, settings.pre_rolling_min_samples * step)
    hi = settings.pre_rolling_max_travel_rad
    if not lo < hi:
        return (f"the samples are too far apart at the reversals to see a pre-rolling "
                f"travel: the first sample after a reversal turns {step:.3g} rad (median), "
                f"{settings.pre_rolling_min_samples:g} of them exceed pre_rolling_max_travel_rad "
                f"= {hi:g} rad")
    return _log_grid(lo, hi, settings.nonlinear_grid_points)


def candidates(x, settings, skip=(), fixed=None):
    """
    Return the candidates for fit inputs ``x``; names in ``skip`` are left out.

    ``fixed`` maps a term name to the params set from the data (the inertia term's filter):
    {name: {param: value}}.
    """
    speed = np.abs(x.nut_velocity_rad_s)
    moving = speed[speed > settings.standstill_speed_rad_s]
    span = float(np.max(x.t_s) - np.min(x.t_s))
    fixed = fixed or {}
    out = []
    for name in LIBRARY:
        if name in skip:
            continue
        if name == "lead_error":
            linear = tuple(f"{k}{h}_m" for h in range(1, settings.lead_error_harmonics + 1)
                           for k in ("sin", "cos"))
            out.append(Candidate(name, linear))
        elif name == "angle_ripple":
            linear = tuple(f"{k}{h}_nm" for h in range(1, settings.angle_ripple_harmonics + 1)
                           for k in ("sin", "cos"))
            out.append(Candidate(name, linear))
        elif name == "stroke_position":
            lo, hi = float(np.min(x.nut_angle_rad)), float(np.max(x.nut_angle_rad))
            linear = tuple(f"p{k}_nm" for k in range(1, settings.stroke_order + 1))
            half_range = max(0.5 * (hi - lo), 1e-9)
            out.append(Candidate(name, linear, fixed=(
                ("center_rad", 0.5 * (lo + hi)), ("half_range_rad", half_range))))
        elif name == "inertia":
            if x.nut_accel_rad_s2 is None or name not in fixed:
                continue
            out.append(Candidate(name, LIBRARY[name].linear,
                                 fixed=tuple(sorted(fixed[name].items()))))
        elif name == "stribeck":
            lo = float(np.percentile(moving, 5))
            hi = settings.stribeck_max_speed_fraction * float(np.percentile(moving, 90))
            out.append(Candidate(name, LIBRARY[name].linear,
                                 _log_grid(lo, hi, settings.nonlinear_grid_points)))
        elif name == "pre_rolling":
            grid = pre_rolling_grid(x, settings)
            if isinstance(grid, tuple):
                out.append(Candidate(name, LIBRARY[name].linear, grid))
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


def _design(members, x):
    cols = [c.columns(x, nl) for c, nl in members]
    return np.hstack(cols) if cols else np.zeros((x.t_s.size, 0))


def _bic(rss, n, k, tau=1.0):
    """
    BIC of a least-squares fit with noise of integrated autocorrelation time ``tau``.

    Correlated noise carries n / tau independent samples' worth of evidence (the
    log-likelihood scales with it), so an AR-coloured residual does not inflate the evidence.
    The floor keeps an exact fit (noise-free synthetic data) away from log(0).
    """
    n_eff = n / max(tau, 1.0)
    return n_eff * math.log(max(rss, 1e-300) / n) + k * math.log(n_eff)


def _in_range(cls, name, value):
    meta = {f.name: f.metadata for f in dataclasses.fields(cls)}[name]
    return (meta["lo"] is None or value >= meta["lo"]) and \
        (meta["hi"] is None or value <= meta["hi"])


def _is_physical(members, coef):
    """Tell whether every amplitude has its physical sign and lies in its validated range."""
    i = 0
    for c, _ in members:
        for name in c.linear:
            if not math.isfinite(coef[i]):
                return False
            if name in c.kind.nonnegative and coef[i] < 0.0:
                return False
            if not _in_range(c.kind.params_cls, name, coef[i]):
                return False
            i += 1
    return True


def _solve(g, b):
    """Least squares from the normal equations, columns scaled to unit norm first."""
    d = np.sqrt(np.diag(g))
    d[d == 0.0] = 1.0
    coef, *_ = np.linalg.lstsq(g / np.outer(d, d), b / d, rcond=1e-10)
    return coef / d


class Gram:
    """
    Cross-products of every candidate column and the residual, per cross-validation block.

    They are accumulated over row chunks, for each grid value of a nonlinear parameter.

    Every subset's least-squares fit and blocked cross-validation then costs a few small
    solves, independent of the number of samples; the columns are never all in memory at
    once (a 10-minute 1 kHz recording).
    """

    # Rows per chunk: the chunk's design (every candidate column at every grid value, ~60)
    # is the largest array of the selection; 16384 rows keep it near 8 MB, and the products
    # are as fast as with larger chunks.
    CHUNK_ROWS = 16384

    def __init__(self, cands, x, r, folds):
        self.keys = [(c, nl) for c in cands for nl in c.grid]
        self.slices = {}
        p = 0
        for c, nl in self.keys:
            self.slices[(c.name, nl)] = slice(p, p + len(c.linear))
            p += len(c.linear)
        n = r.size
        self.n = n
        self.edges = np.linspace(0, n, folds + 1).astype(int)
        self.g = np.zeros((folds, p, p))
        self.b = np.zeros((folds, p))
        self.rr = np.zeros(folds)
        for f, (lo, hi) in enumerate(zip(self.edges[:-1], self.edges[1:])):
            for c0 in range(lo, hi, self.CHUNK_ROWS):
                c1 = min(c0 + self.CHUNK_ROWS, hi)
                xs = _rows(x, slice(c0, c1))
                a = np.hstack([c.columns(xs, nl) for c, nl in self.keys]) if p else \
                    np.zeros((c1 - c0, 0))
                rs = r[c0:c1]
                self.g[f] += a.T @ a
                self.b[f] += a.T @ rs
                self.rr[f] += float(rs @ rs)
        self.g_all = self.g.sum(axis=0)
        self.b_all = self.b.sum(axis=0)
        self.rr_all = float(self.rr.sum())
        # per candidate: (grid points, amplitudes) column indices; per column: its bounds
        self.grid_cols = {}
        lo, hi = np.full(p, -np.inf), np.full(p, np.inf)
        for c in cands:
            self.grid_cols[c.name] = np.array([np.arange(self.slices[(c.name, nl)].start,
                                                         self.slices[(c.name, nl)].stop)
                                               for nl in c.grid])
            meta = {f.name: f.metadata for f in dataclasses.fields(c.kind.params_cls)}
            for nl in c.grid:
                for j, name in zip(range(self.slices[(c.name, nl)].start,
                                         self.slices[(c.name, nl)].stop), c.linear):
                    m = meta[name]
                    lo[j] = m["lo"] if m["lo"] is not None else -np.inf
                    hi[j] = m["hi"] if m["hi"] is not None else np.inf
                    if name in c.kind.nonnegative:
                        lo[j] = max(lo[j], 0.0)
        self.col_lo, self.col_hi = lo, hi

    def best_over_grids(self, subset, tau):
        """
        Return the best physical Fit of ``subset`` over the product of its grids, or None.

        All grid combinations are solved at once (batched normal equations, pseudo-inverse:
        collinear columns such as offset and coulomb_asymmetry without standstill samples
        get the minimum-norm split instead of an error).
        """
        shapes = [len(c.grid) for c in subset]
        choice = np.stack(np.meshgrid(*[np.arange(n) for n in shapes], indexing="ij"),
                          axis=-1).reshape(-1, len(subset))
        idx = np.concatenate([self.grid_cols[c.name][choice[:, i]]
                              for i, c in enumerate(subset)], axis=1)        # (B, k)
        g = self.g_all[idx[:, :, None], idx[:, None, :]]
        b = self.b_all[idx]
        d = np.sqrt(np.einsum("bii->bi", g))
        d[d == 0.0] = 1.0
        gs = g / (d[:, :, None] * d[:, None, :])
        coef = np.einsum("bij,bj->bi", np.linalg.pinv(gs, rcond=1e-10), b / d) / d
        rss = self.rr_all - 2.0 * np.einsum("bi,bi->b", coef, b) + \
            np.einsum("bi,bij,bj->b", coef, g, coef)
        rss = np.maximum(rss, 0.0)
        ok = np.all((coef >= self.col_lo[idx]) & (coef <= self.col_hi[idx]), axis=1) & \
            np.all(np.isfinite(coef), axis=1)
        if not ok.any():
            return None
        k = sum(c.n_params for c in subset)
        n_eff = self.n / max(tau, 1.0)
        bic = n_eff * np.log(np.maximum(rss, 1e-300) / self.n) + k * math.log(n_eff)
        bic = np.where(ok, bic, np.inf)
        j = int(np.argmin(bic))
        members = tuple((c, c.grid[choice[j, i]]) for i, c in enumerate(subset))
        return Fit(members, coef[j], float(rss[j]), float(bic[j]), True)

    def index(self, members):
        """Return the column indices of ``members``."""
        idx = [np.arange(self.slices[(c.name, nl)].start, self.slices[(c.name, nl)].stop)
               for c, nl in members]
        return np.concatenate(idx) if idx else np.zeros(0, dtype=int)

    def fit(self, members, tau):
        """Return the Fit of ``members`` on all rows."""
        i = self.index(members)
        if i.size == 0:
            return Fit(tuple(members), np.zeros(0), self.rr_all,
                       _bic(self.rr_all, self.n, 0, tau), True)
        g, b = self.g_all[np.ix_(i, i)], self.b_all[i]
        coef = _solve(g, b)
        rss = max(self.rr_all - 2.0 * coef @ b + coef @ g @ coef, 0.0)
        k = sum(c.n_params for c, _ in members)
        return Fit(tuple(members), coef, rss, _bic(rss, self.n, k, tau),
                   _is_physical(members, coef))

    def cv_rmse(self, members):
        """Return the RMSE of the blocked cross-validation of ``members``."""
        i = self.index(members)
        if i.size == 0:
            return math.sqrt(self.rr_all / self.n)
        sq = 0.0
        for f in range(len(self.rr)):
            g_f, b_f = self.g[f][np.ix_(i, i)], self.b[f][i]
            coef = _solve(self.g_all[np.ix_(i, i)] - g_f, self.b_all[i] - b_f)
            sq += max(self.rr[f] - 2.0 * coef @ b_f + coef @ g_f @ coef, 0.0)
        return math.sqrt(sq / self.n)


def _rows(x, sl):
    return Inputs(*(None if v is None else v[sl] for v in
                    (x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s, x.axial_load_n,
                     x.nut_accel_rad_s2)))


def fit(members, x, r, tau=1.0):
    """Least-squares fit of residual ``r`` on the model ``members``; return a Fit."""
    members = tuple(members)
    a = _design(members, x)
    n = r.size
    if a.shape[1] == 0:
        coef = np.zeros(0)
        rss = float(r @ r)
    else:
        coef, *_ = np.linalg.lstsq(a, r, rcond=None)
        res = r - a @ coef
        rss = float(res @ res)
    k = sum(c.n_params for c, _ in members)
    return Fit(members, coef, rss, _bic(rss, n, k, tau), _is_physical(members, coef))


def refine(f, x, r, tau=1.0):
    """
    Re-profile each nonlinear value over its whole grid, then refine it by a bounded search.

    One pass, in model order, the others held.  The whole grid, not just the neighbourhood:
    a term that entered first may have stood in for a later one at another value.  Each
    evaluation is a ``fit_chunked`` (normal equations over row chunks, as the Gram's): the
    full design, lstsq's copies of it and a cache of every grid column were measured at
    ~80 MB of the selection's peak on a 10-minute 1 kHz recording.
    """
    members = list(f.members)
    for i, (cand, nl) in enumerate(members):
        if nl is None:
            continue

        def cost(log_nl, i=i, cand=cand):
            trial = members[:i] + [(cand, float(math.exp(log_nl)))] + members[i + 1:]
            g = fit_chunked(trial, x, r, tau)
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
    return fit_chunked(members, x, r, tau)


def penalty(f, settings, known=()):
    """
    Return the evidence a model's terms must bring beyond BIC: ``bic_threshold`` per term.

    A term in ``known`` (RIGID_BODY_TERMS without a model of the drive) needs only
    ``rigid_body_bic_threshold``: the threshold is the prior odds against an effect (Kass &
    Raftery), and these are not in doubt in a motor torque.
    """
    return sum(settings.rigid_body_bic_threshold if name in known else settings.bic_threshold
               for name in f.names)


def admissible(subset, known=()):
    """
    Tell whether the selection tries ``subset`` (a tuple of Candidates).

    Without a model of the drive (``COULOMB_LEVEL`` in ``known``) a ``COULOMB_SHAPERS``
    term needs the Coulomb level.
    """
    names = [c.name for c in subset]
    if COULOMB_LEVEL in known and COULOMB_LEVEL not in names:
        return not any(n in COULOMB_SHAPERS for n in names)
    return True


def select(x, r, settings, skip=(), fixed=None, tau=1.0, known=()):
    """
    Select terms explaining residual ``r`` at fit inputs ``x`` (an empirical_terms.Inputs).

    Best-subset selection: for each size m <= max_terms the subset of lowest BIC (its
    nonlinear values from the grid; the best ``REFINED_PER_SIZE`` per size then refined);
    the size chosen minimises BIC + bic_threshold * m (every term must earn strong
    evidence), and a larger model must also beat the next smaller choice in blocked
    cross-validation.  ``tau`` is the noise's integrated autocorrelation time in samples
    (regimes.noise_model).  ``known``: terms that need only ``rigid_body_bic_threshold``
    (``penalty``).  Return (TermSet, trace, Gram); the trace has one row per size.
    """
    cands = candidates(x, settings, skip, fixed)
    gram = Gram(cands, x, r, settings.cv_folds)
    best = {0: gram.fit((), tau)}
    for m in range(1, min(settings.max_terms, len(cands)) + 1):
        ranked = []
        for subset in itertools.combinations(cands, m):
            if not admissible(subset, known):
                continue
            f = gram.best_over_grids(subset, tau)
            if f is not None:
                ranked.append(f)
        ranked.sort(key=lambda f: f.bic + penalty(f, settings, known))
        for f in ranked[:REFINED_PER_SIZE]:
            if any(nl is not None for _, nl in f.members):
                g = refine(f, x, r, tau)
                f = g if g.physical and g.rss <= f.rss else f
            if m not in best or f.bic + penalty(f, settings, known) < \
                    best[m].bic + penalty(best[m], settings, known):
                best[m] = f
    score = {m: f.bic + penalty(f, settings, known) for m, f in best.items()}
    cv = {}

    def cv_of(m):
        if m not in cv:
            if any(nl is not None and (c.name, nl) not in gram.slices
                   for c, nl in best[m].members):
                cv[m] = cv_rmse(best[m].members, x, r, settings.cv_folds)
            else:
                cv[m] = gram.cv_rmse(best[m].members)
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
    return to_termset(best[chosen]), trace, SelectionContext(gram, best, chosen, tau)


@dataclasses.dataclass
class SelectionContext:
    """What the ambiguity check needs after the selection."""

    gram: Gram
    best: dict
    chosen: int
    tau: float


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


def swap_evidence(members, bic, x, r, tau, settings):
    """
    Return (BIC difference, separated) of the model ``members`` against one of BIC ``bic``.

    The evidence of an ambiguity check: a chosen effect's near-twin is swapped in and the
    model refitted to ``r``; the difference (inf when an amplitude leaves its physical sign or
    range) below ``bic_threshold`` means the data cannot tell the two apart.  Used here for
    AMBIGUOUS_PAIRS and by discrepancy.physical for a physical parameter and its twin.
    """
    g = fit(members, x, r, tau)
    delta = (g.bic - bic) if g.physical else math.inf
    return delta, bool(delta >= settings.bic_threshold)


def ambiguities(ctx, x, r, settings):
    """
    Name the pairs of chosen terms whose columns the data cannot separate (AMBIGUOUS_PAIRS).

    offset and coulomb_asymmetry are one column on moving samples; only standstill samples
    separate them.  The chosen member is swapped for its partner and refitted: when the BIC
    changes by less than ``bic_threshold`` the data cannot tell them apart and the pair is
    reported as one ambiguous effect; otherwise the evidence (standstill samples, BIC
    difference) is reported with the choice.  Return a list of dicts (summary.json).
    """
    f = ctx.best[ctx.chosen]
    names = f.names
    out = []
    for a, b in AMBIGUOUS_PAIRS:
        if (a in names) == (b in names):
            continue
        chosen, other = (a, b) if a in names else (b, a)
        cands = {c.name: c for c in candidates(x, settings)}
        members = tuple((cands[other], None) if c.name == chosen else (c, nl)
                        for c, nl in f.members)
        delta, separated = swap_evidence(members, f.bic, x, r, ctx.tau, settings)
        standstill = int(np.sum(np.abs(x.nut_velocity_rad_s)
                                <= settings.standstill_speed_rad_s))
        if separated:
            text = (f"{chosen} rather than {other}: the {standstill} standstill samples of "
                    f"the fit part decide it (BIC {delta:.1f} worse with {other})")
        else:
            text = (f"{chosen} and {other} are one ambiguous effect here: on moving samples "
                    f"they are the same constant, and the {standstill} standstill samples "
                    f"do not separate them (BIC difference {delta:.1f} < "
                    f"{settings.bic_threshold}); {chosen} was kept")
        out.append({"pair": [a, b], "chosen": chosen, "standstill_samples": standstill,
                    "bic_difference": delta if math.isfinite(delta) else None,
                    "separated": bool(separated), "statement": text})
    return out


def to_termset(f):
    """Convert a Fit into a TermSet of validated terms."""
    terms = []
    i = 0
    for cand, nl in f.members:
        values = dict(cand.fixed)
        for name in cand.linear:
            values[name] = float(f.coef[i])
            i += 1
        if cand.kind.nonlinear:
            values[cand.kind.nonlinear] = float(nl)
        terms.append(make_term(cand.name, values))
    return TermSet(terms)


# Rows per chunk of the refit's normal equations: the design of a 10-minute 1 kHz recording
# is never in memory at once (as in Gram).
REFIT_CHUNK_ROWS = 16384


def refit_all(f, x, r):
    """
    Refit the amplitudes of the chosen model ``f`` on all samples ``x``, ``r``.

    The selection and the held-out score need the split; the chosen terms, with their
    nonlinear values (Stribeck velocity, thermal tau) as selected, are then fitted by least
    squares on every usable sample, which is what ``augmented.yaml``, ``--validate`` and the
    node get.  The normal equations are accumulated over row chunks.  Return the Fit
    (``physical`` says whether every amplitude kept its sign and range).
    """
    return fit_chunked(f.members, x, r)


def fit_chunked(members, x, r, tau=1.0):
    """
    Least-squares Fit of ``r`` on ``members`` from normal equations over row chunks.

    Columns scaled as in ``_solve``; the RSS from the normal equations, as the Gram's.  The
    design is never in memory at once (a 10-minute 1 kHz recording: 420,000 fit rows).
    """
    members = tuple(members)
    n = r.size
    k = sum(len(c.linear) for c, _ in members)
    g, b, rr = np.zeros((k, k)), np.zeros(k), 0.0
    for lo in range(0, n, REFIT_CHUNK_ROWS):
        sl = slice(lo, min(lo + REFIT_CHUNK_ROWS, n))
        a = _design(members, _rows(x, sl))
        g += a.T @ a
        b += a.T @ r[sl]
        rr += float(r[sl] @ r[sl])
    coef = _solve(g, b) if k else np.zeros(0)
    rss = max(rr - 2.0 * float(coef @ b) + float(coef @ g @ coef), 0.0)
    return Fit(members, coef, rss, _bic(rss, n, sum(c.n_params for c, _ in members), tau),
               _is_physical(members, coef))
