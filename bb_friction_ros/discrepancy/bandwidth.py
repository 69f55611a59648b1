"""
The acceleration bandwidth: the cut-off of the filter that derives the nut acceleration.

JointState and most logs carry no acceleration, so it is the derivative of the nut velocity
low-passed at a cut-off f_c (``empirical_terms.AccelerationFilter``).  Too low, and the filter
misses the peaks of short moves: a fit then inflates the inertia J to make up for them, and on
another recording the inertia torque is wrong exactly where it is large (measured: 41 % against
the rigid-body model's 12.4 % on a measured servo axis, with a fixed 10 Hz).  Too high, and the
acceleration is mostly differentiated noise.  Recorders run from 10 Hz to several kHz, so the
cut-off is chosen per recording (``choose_cutoff``):

- candidates: ``accel_cutoff_grid_points`` log-spaced cut-offs from the highest safe one,
  ``accel_max_cutoff_fraction`` of the sample rate (0.2: 40 % of Nyquist, where the
  Butterworth still attenuates the aliased band), down by a factor ``accel_cutoff_grid_span``;
- score: the blocked K-fold cross-validated mean square error (``cv_folds`` contiguous time
  blocks of the fit part) of the rigid-body regression J alpha + c omega + T_c sign omega + T_0
  of the residual, alpha derived at that cut-off.  The inertia column is the only one that
  changes with the cut-off, so the score measures how well that alpha explains torque on
  data the fit did not see;
- choice: the one-standard-error rule (Hastie, Tibshirani & Friedman, ESL 7.10), towards
  the highest cut-off: among the candidates whose score is within one standard error of the
  lowest (the fold scatter of the best candidate's score, / sqrt(folds)), the highest.  The
  recording cannot tell those apart, and the cut-off travels to other motion (``--validate``,
  replay, the node): a lower cut-off than needed biases alpha wherever that motion is faster
  than the fit recording's (J alpha is then wrong exactly where it is large), while a higher
  one only adds the alpha noise this score has already measured, and has the shorter live
  lag.  Measured on the three RViMLab drives (docs/discrepancy.md): driveNo3's fit recording
  holds only a slow start-stop run; the lowest score chose 1.6 Hz and its faster validation
  run then validated at 0.2045 (reference 0.226), the rule gives 31 Hz and 0.1406 (0.171);
  driveNo1 0.1359 -> 0.1236.  The rule towards the *lowest* cut-off was tried first and
  rejected (3.5 instead of 7.1 Hz on driveNo1, validation 0.164 instead of 0.136);
- inertia identifiable: only when the best alpha lowers the score of the same regression
  without alpha.  Otherwise (a 10 Hz log, or a recording without acceleration phases) the
  inertia term is not tested, and the report says why instead of fitting noise.

An explicit ``accel_cutoff_hz`` (> 0) overrides the choice; above the highest safe cut-off it
is refused, naming the key.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.config import ConfigError
from bb_friction_ros.empirical_terms import zero_phase_acceleration
from bb_friction_ros.runner import run_starts


def sample_step_s(rec):
    """Return the median positive sample step [s] of a recording, or None."""
    dt = np.diff(rec.t_s)
    dt = dt[dt > 0]
    return float(np.median(dt)) if dt.size else None


def max_cutoff_hz(step_s, settings):
    """Return the highest safe cut-off [Hz]: ``accel_max_cutoff_fraction`` of the rate."""
    return settings.accel_max_cutoff_fraction / step_s


def acceleration_filter_of(rec, settings, cutoff_hz=None):
    """
    Return the acceleration filter's settings for a recording: {accel_cutoff_hz, max_gap_s}.

    The cut-off is ``cutoff_hz`` (or the settings' explicit ``accel_cutoff_hz``; with neither,
    the highest safe one), at most ``accel_max_cutoff_fraction`` of the sample rate (1 /
    median step); a step longer than ``segment_gap_factor`` median steps is a gap.
    """
    step = sample_step_s(rec)
    if step is None:
        return None
    top = max_cutoff_hz(step, settings)
    fc = cutoff_hz if cutoff_hz is not None else (settings.accel_cutoff_hz or top)
    return {"accel_cutoff_hz": min(fc, top), "max_gap_s": settings.segment_gap_factor * step}


def with_acceleration(rec, settings, spec=None):
    """
    Return ``rec`` with its nut acceleration: the CSV's own column, or derived.

    Derived: the zero-phase ``AccelerationFilter`` on the nut velocity per continuous
    segment.  Runs (the stamps restart) are filtered on their own, each with the gap rule and
    the cut-off limit of its own sample rate (a recording of several recorder files may mix
    rates); ``spec`` (filter settings) overrides the cut-off.  Samples of segments too short
    to derive it are NaN.  Return (recording, spec of the whole recording).
    """
    whole = acceleration_filter_of(rec, settings)
    if spec is not None and whole is not None:
        whole["accel_cutoff_hz"] = spec["accel_cutoff_hz"]
    if rec.nut_accel_rad_s2 is not None or whole is None:
        return rec, whole
    accel = np.full(len(rec), np.nan)
    cutoffs = []
    for sl in run_slices(rec):
        # late samples (a stamp a little behind, the runner's rule) in stamp order: the
        # filter's time must not run backwards within a run
        order = np.argsort(rec.t_s[sl], kind="stable")
        run = rec.take(sl).take(order)
        own = acceleration_filter_of(run, settings, whole["accel_cutoff_hz"])
        if own is None:
            continue
        fc = min(whole["accel_cutoff_hz"], own["accel_cutoff_hz"])
        cutoffs.append(fc)
        a = np.empty(order.size)
        a[order] = zero_phase_acceleration(run.t_s, run.nut_velocity_rad_s, fc,
                                           own["max_gap_s"], settings.accel_min_segment_samples)
        accel[sl] = a
    info = dict(rec.info)
    if cutoffs and (min(cutoffs) < whole["accel_cutoff_hz"]):
        info["acceleration_run_cutoff_hz"] = [min(cutoffs), max(cutoffs)]
    return dataclasses.replace(rec, nut_accel_rad_s2=accel, info=info), whole


@dataclasses.dataclass
class CutoffChoice:
    """The acceleration cut-off of a recording and the evidence for it (summary.json)."""

    cutoff_hz: float
    chosen_by: str
    sample_rate_hz: float
    candidates: list            # [{cutoff_hz, cv_mse_nm2, cv_rmse_nm, within_one_se}]
    no_acceleration_cv_rmse_nm: float = None
    # the lowest score's cut-off and its standard error [N m^2] (the one-SE rule's evidence)
    lowest_score_cutoff_hz: float = None
    one_se_nm2: float = None
    inertia_identifiable: bool = True
    reason: str = ""            # why inertia cannot be identified ("" when it can)
    # the best cut-off is the highest this sample rate allows: acceleration edges faster than
    # it are not resolved, and J is then only partly identifiable (docs/discrepancy.md)
    bandwidth_limited: bool = False

    def as_dict(self):
        """Return the summary.json ``acceleration`` fields of the choice."""
        return {"cutoff_hz": self.cutoff_hz, "chosen_by": self.chosen_by,
                "sample_rate_hz": self.sample_rate_hz, "candidates": self.candidates,
                "no_acceleration_cv_rmse_nm": self.no_acceleration_cv_rmse_nm,
                "inertia_identifiable": self.inertia_identifiable,
                "inertia_reason": self.reason or None,
                "bandwidth_limited": self.bandwidth_limited,
                "lowest_score_cutoff_hz": self.lowest_score_cutoff_hz,
                "one_se_nm2": self.one_se_nm2,
                "statement": self.statement()}

    def statement(self):
        """Return the report's sentence on what the cut-off means for the inertia."""
        if not self.candidates:
            return f"cut-off {self.cutoff_hz:.3g} Hz ({self.chosen_by})"
        if not self.inertia_identifiable:
            return f"inertia cannot be identified here: {self.reason}"
        if self.bandwidth_limited:
            return (f"the cross-validated error still falls at the highest cut-off this "
                    f"sample rate allows ({self.cutoff_hz:.3g} Hz at {self.sample_rate_hz:.4g}"
                    " samples/s): acceleration edges faster than that are not resolved, so "
                    "the inertia is only partly identifiable (J may absorb the missed "
                    "peaks); record faster where the inertia matters")
        if self.lowest_score_cutoff_hz is not None \
                and self.lowest_score_cutoff_hz < self.cutoff_hz:
            return (f"the cross-validated error is lowest at {self.lowest_score_cutoff_hz:.3g}"
                    f" Hz, but up to {self.cutoff_hz:.3g} Hz it stays within one standard "
                    "error of that: this recording cannot tell those cut-offs apart, and the "
                    f"highest ({self.cutoff_hz:.3g} Hz) is used, which biases the "
                    "acceleration least on faster motion and has the shortest live lag")
        return (f"the cross-validated error is lowest at {self.cutoff_hz:.3g} Hz, below the "
                f"highest safe cut-off: the recording resolves its accelerations")


def run_slices(rec):
    """Return the slices of the runs of a recording: where the runner resets (run_starts)."""
    starts = np.concatenate((np.flatnonzero(run_starts(rec.t_s)[0]), [len(rec)]))
    return [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:])]


def grid_step_s(rec, min_share):
    """
    Return the sample step [s] whose safe cut-off tops the cut-off grid.

    It is the step of the fastest rate at which, with the faster ones, at least
    ``min_share`` of the samples were taken.
    """
    steps, rows = [], []
    for sl in run_slices(rec):
        step = sample_step_s(rec.take(sl))
        if step is not None:
            steps.append(step)
            rows.append(sl.stop - sl.start)
    order = np.argsort(steps)               # fastest first
    cum = np.cumsum(np.asarray(rows)[order])
    k = int(np.searchsorted(cum, min_share * cum[-1] * (1.0 - 1e-12)))
    return float(np.asarray(steps)[order][min(k, len(steps) - 1)])


def cutoff_grid(step_s, settings):
    """Return the candidate cut-offs [Hz], ascending."""
    top = max_cutoff_hz(step_s, settings)
    return [float(v) for v in np.geomspace(top / settings.accel_cutoff_grid_span, top,
                                           settings.accel_cutoff_grid_points)]


def _fold_mse(cols, r, folds):
    """
    Return the per-fold mean square error of blocked K-fold CV of r on ``cols``.

    From per-fold cross-products of the columns (views of each fold, no n x k design): each
    training fit is the total minus its fold, so no training copy of the rows is made, and
    the fold's error comes from the same products (a 10-minute 1 kHz recording: 8 cut-offs;
    the stacked design was measured at 13 MB per candidate).
    """
    n = r.size
    edges = np.linspace(0, n, folds + 1).astype(int)
    parts = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        c = [col[lo:hi] for col in cols]
        parts.append((np.array([[float(u @ v) for v in c] for u in c]),
                      np.array([float(u @ r[lo:hi]) for u in c]), float(r[lo:hi] @ r[lo:hi])))
    g_all = sum(g for g, _, _ in parts)
    b_all = sum(b for _, b, _ in parts)
    out = np.empty(folds)
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        g, b, rr = parts[k]
        coef, *_ = np.linalg.lstsq(g_all - g, b_all - b, rcond=None)
        sse = rr - 2.0 * float(coef @ b) + float(coef @ g @ coef)
        out[k] = max(sse, 0.0) / max(hi - lo, 1)
    return out


def choose_cutoff(rec, settings, usable):
    """
    Choose the acceleration cut-off of Recording ``rec`` (module docstring).

    ``usable(rec)`` returns (mask of analysable samples, dropped counts), as the workflow's.
    Return a CutoffChoice; None when the recording has no sample step or carries its own
    acceleration (the CSV column).
    """
    step = sample_step_s(rec)
    if step is None or rec.nut_accel_rad_s2 is not None:
        return None
    # a file of several recorder runs may mix rates (the RViMLab exports: 4-156 Hz): the
    # grid reaches the safe cut-off of the fastest rate that holds accel_grid_min_share of
    # the samples (a short fast run among slow ones set 400 Hz for a file 99 % filtered at
    # 10 Hz); each run is still capped at its own
    step = grid_step_s(rec, settings.accel_grid_min_share)
    rate = 1.0 / step
    top = max_cutoff_hz(step, settings)
    if settings.accel_cutoff_hz > 0:
        if settings.accel_cutoff_hz < settings.accel_min_cutoff_hz:
            raise ConfigError(
                f"discrepancy.accel_cutoff_hz: {settings.accel_cutoff_hz:g} Hz is below "
                f"accel_min_cutoff_hz = {settings.accel_min_cutoff_hz:g} Hz (the filter "
                "would lag by more than any acceleration phase); set 0 to choose it from the "
                "data")
        if settings.accel_cutoff_hz > top * (1 + 1e-9):
            raise ConfigError(
                f"discrepancy.accel_cutoff_hz: {settings.accel_cutoff_hz:g} Hz is above the "
                f"highest safe cut-off of {rec.info.get('input', 'the recording')}: "
                f"{settings.accel_max_cutoff_fraction:g} x its sample rate {rate:.4g} Hz = "
                f"{top:.4g} Hz (accel_max_cutoff_fraction; Nyquist {rate / 2:.4g} Hz); set "
                "it lower, or 0 to choose it from the data")
        return CutoffChoice(settings.accel_cutoff_hz, "settings (accel_cutoff_hz)", rate, [])
    grid = cutoff_grid(step, settings)

    def alpha(fc):
        return with_acceleration(rec, settings, {"accel_cutoff_hz": fc})[0].nut_accel_rad_s2
    # which samples lack an alpha depends on the segments only, not on the cut-off
    ok = usable(dataclasses.replace(rec, nut_accel_rad_s2=alpha(grid[-1])))[0]
    idx = np.flatnonzero(ok)
    n_fit = int(math.floor((1.0 - settings.holdout_fraction) * idx.size))
    idx = idx[:n_fit]           # the fit part only: the held-out part stays unseen
    folds = settings.cv_folds
    if idx.size < 4 * folds:
        return CutoffChoice(grid[-1], "too few samples to choose (the highest safe cut-off)",
                            rate, [], None, False, "too few usable samples to cross-validate")
    if idx.size and idx[-1] == idx.size - 1:
        idx = slice(0, idx.size)            # every sample usable: views, not copies
    w = rec.nut_velocity_rad_s[idx]
    r = rec.torque_meas_nm[idx] - rec.torque_pred_nm[idx]
    base = [w, np.sign(w), np.ones_like(w)]
    m0 = _fold_mse(base, r, folds)
    scores = [_fold_mse([alpha(fc)[idx]] + base, r, folds) for fc in grid]
    means = [float(np.mean(m)) for m in scores]
    best = int(np.argmin(means))
    # the standard error of the best score: the scatter of its fold errors (ESL 7.10)
    one_se = float(np.std(scores[best], ddof=1)) / math.sqrt(folds)
    within = [means[k] <= means[best] + one_se for k in range(len(grid))]
    chosen = max(k for k in range(len(grid)) if within[k])
    candidates = [{"cutoff_hz": fc, "cv_mse_nm2": means[k], "cv_rmse_nm": math.sqrt(means[k]),
                   "within_one_se": bool(within[k])} for k, fc in enumerate(grid)]
    m0_mean = float(np.mean(m0))
    choice = CutoffChoice(grid[chosen], "blocked cross-validation (the highest cut-off within "
                          "one standard error of the lowest error)", rate, candidates,
                          math.sqrt(m0_mean), lowest_score_cutoff_hz=grid[best],
                          one_se_nm2=one_se)
    # the score still falls at the highest candidate: edges faster than it are not resolved
    choice.bandwidth_limited = best == len(grid) - 1
    if not means[best] < m0_mean:
        choice.bandwidth_limited = False
        choice.inertia_identifiable = False
        choice.reason = (
            f"at {rate:.4g} samples/s (fastest run) no acceleration, at any cut-off up to "
            f"{top:.3g} Hz, lowers the cross-validated error of the rigid-body fit (best "
            f"{math.sqrt(means[best]):.4g} N m against {math.sqrt(m0_mean):.4g} N m without "
            "the acceleration): the sample rate or the excitation cannot tell the inertia "
            "torque from noise")
        choice.chosen_by += "; inertia not identifiable"
    return choice
