"""
The profile of a physical value: scoring its trials and choosing the next value to run.

Between trials only the model column changes, so a trial is scored by its profile (the RSS
of r - d(p) with the empirical terms held, by projection: ``_Profile``), not by a selection
of its own.  The 95 % interval is read from the profile's parabola, where n' ln(RSS/n)
rises by 3.84 (chi-square, one parameter).
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.discrepancy.physical.trials import CHI2_1_95, TrialRun, TWINS


def _penalised(trace, extra_params, settings, tau, n):
    row = [t for t in trace if t["chosen"]][0]
    n_eff = n / max(tau, 1.0)
    return row["penalised_bic"] + extra_params * (math.log(n_eff) + settings.bic_threshold)


class _Profile:
    """
    The profile of a physical value: the RSS of r - d(p) with empirical terms held.

    The held terms' columns are fitted by projection (an orthonormal basis of their span,
    from one SVD), so a trial costs a few dot products over the samples, not a selection.
    ``amplitude``: the least-squares scale a of a trial's change d(p) beside the held terms;
    a = 1 at the profile's minimum when the change keeps its shape, and a tells how much
    larger or smaller the change should be (``_next_value``).
    """

    def __init__(self, members, x, r, tau, settings):
        self.members = tuple(members)
        n = r.size
        cols = [c.columns(x, nl) for c, nl in self.members]
        a = np.hstack(cols) if cols else np.zeros((n, 0))
        if a.shape[1]:
            u, sv, _ = np.linalg.svd(a, full_matrices=False)
            # rank-deficient designs (offset and coulomb_asymmetry without standstill
            # samples): only the directions the columns span are projected out
            self.q = u[:, sv > sv[0] * 1e-10] if sv[0] > 0 else u[:, :0]
        else:
            self.q = a
        self.mr = self._proj(r)
        self.n = n
        n_eff = n / max(tau, 1.0)
        k = sum(c.n_params for c, _ in self.members)
        # as selection.select's penalised BIC, plus the physical parameter (_penalised)
        self.penalty = k * math.log(n_eff) + settings.bic_threshold * len(self.members) + \
            math.log(n_eff) + settings.bic_threshold
        self.n_eff = n_eff

    def _proj(self, v):
        return v - self.q @ (self.q.T @ v) if self.q.shape[1] else v

    def rss(self, d):
        """Return the RSS of the held terms fitted to r - d."""
        e = self.mr - self._proj(d)
        return float(e @ e)

    def score(self, rss):
        """Return the penalised BIC of an RSS (held terms and the physical value counted)."""
        return self.n_eff * math.log(max(rss, 1e-300) / self.n) + self.penalty

    def amplitude(self, d):
        """Return (a, ||M d||, RSS at the free amplitude): the change's best scale."""
        md = self._proj(d)
        dd = float(md @ md)
        if not dd > 0.0:
            return math.nan, 0.0, float(self.mr @ self.mr)
        a = float(md @ self.mr) / dd
        return a, math.sqrt(dd), float(self.mr @ self.mr) - a * a * dd


@dataclasses.dataclass
class _Point:
    """A model run of one candidate: its value, run and change at the fit samples."""

    value: float
    run: TrialRun
    d_fit: np.ndarray


def _vertex(p, y):
    """Return (vertex, curvature a of y = a (x - v)^2 + c) of the parabola through 3 points."""
    (x0, x1, x2), (y0, y1, y2) = p, y
    den = (x0 - x1) * (x0 - x2) * (x1 - x2)
    if den == 0.0:
        return None, 0.0
    a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
    b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den
    if not a > 0.0:
        return None, a
    return -b / (2.0 * a), a


def _three_around_best(points):
    """Return the best point and its neighbours in value (sorted), or None at an edge."""
    pts = sorted(points)
    k = int(np.argmin([y for _, y in pts]))
    if k == 0 or k == len(pts) - 1:
        return None, pts[k]
    return pts[k - 1:k + 2], pts[k]


def _next_value(kind, points, base_value, profile, ps):
    """
    Return the next trial value of ``kind`` from the runs so far, or None (converged).

    The run whose fitted amplitude a is nearest 1 (a > 0) says how large the change should
    be: a times its size.  The value giving that size is interpolated between the runs on
    the same side of the config's value (the size of the change against the value, from 0
    at the config's value; its logarithm between two non-zero sizes: at an onset such as
    the B2B contact's the size grows by orders of magnitude between bracket points), or
    stepped beyond the farthest run by its spacing.  A parabola through the profile could
    not do this at an onset: the RSS is flat, then steep.
    """
    best = None
    for pt in points:
        a, size, _ = profile.amplitude(pt.d_fit)
        if a > 0.0 and size > 0.0 and (best is None or abs(math.log(a)) < best[0]):
            best = (abs(math.log(a)), a * size, pt.value)
    if best is None:
        return None
    _, target, v = best
    side = 1.0 if v > base_value else -1.0
    same = sorted((side * (pt.value - base_value), profile.amplitude(pt.d_fit)[1])
                  for pt in points if side * (pt.value - base_value) > 0.0)
    curve = [(0.0, 0.0)] + same
    # the size of the change should grow with the distance from the config's value; where
    # it does not (a non-monotone stretch), the first crossing is taken
    new = None
    for (p0, s0), (p1, s1) in zip(curve[:-1], curve[1:]):
        if s0 <= target <= s1 and s1 > s0:
            if s0 > 0.0:
                f = math.log(target / s0) / math.log(s1 / s0)
            else:
                f = target / s1
            new = p0 + f * (p1 - p0)
            break
    if new is None:
        if target > curve[-1][1]:
            step = curve[-1][0] - curve[-2][0]
            new = curve[-1][0] + step
        else:
            return None
    new = base_value + side * new
    lo, hi = kind.limits()
    new = min(max(new, lo), hi)
    if min(abs(new - pt.value) for pt in points + [_Point(base_value, None, None)]) < \
            kind.resolution(ps):
        return None
    return new


def _interval(best_value, points, base_value, profile):
    """
    Return the 95 % interval of the value: where -2 ln L rises by 3.84 (chi-square, 1).

    The profile (the RSS, the chosen empirical terms held) is the parabola through the best
    run and its neighbours in value; (None, None) where the runs do not bracket it.
    """
    pts = [(base_value, profile.rss(np.zeros_like(profile.mr)))]
    pts += [(pt.value, profile.rss(pt.d_fit)) for pt in points]
    three, _ = _three_around_best(pts)
    if three is None:
        return (None, None)
    v, a = _vertex([p for p, _ in three], [y for _, y in three])
    if v is None:
        return (None, None)
    # -2 ln L = n' ln(RSS/n) rises by n' dRSS / RSS_min near the minimum
    rss_min = max(min(y for _, y in three), 1e-300)
    half = math.sqrt(CHI2_1_95 * rss_min / (profile.n_eff * a))
    return (best_value - half, best_value + half)


def _held(kind, outcome):
    """
    Return the empirical terms held while the value of ``kind`` is profiled.

    The outcome's chosen terms without the physical candidate's twin (``TWINS``): held, the
    twin would absorb the parameter's own change and flatten its profile (mu and
    load_dependent are nearly one column).
    """
    return tuple(m for m in outcome.members if m[0].name != TWINS[kind.name])
