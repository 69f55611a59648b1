"""
The discrepancy workflow: residual, where, which effect, add it, show the gap shrink.

``analyse(recording, settings)`` is the pure core (arrays in, an Analysis out);
``run_discrepancy`` adds reading the input and writing ``augmented.yaml``, ``summary.json``
and ``report.md`` with its PNGs.

0. The nut acceleration: the CSV's column, or derived per continuous segment with the
   zero-phase filter (``with_acceleration``).
1. Residual = measured - predicted, the prediction from the replay path (data.py).
2. Where: the noise level and its autocorrelation time are estimated from the residual
   itself (regimes.noise_model) and the residual is binned by direction, speed, angle within
   a revolution, load, time, acceleration and stroke position; significant bins are the
   ``regions``.
3. Which effect: selection.select on the first (1 - holdout_fraction) of the samples.
4. The selected terms go into ``augmented.yaml`` (base config + ``empirical_terms``).
5. RMSE before/after, regime table and plots on the held-out last part; terms that do not
   lower the held-out RMSE are not adopted (verdict "none", ``rejected_terms``).
6. ``--validate``: the terms applied, unchanged, to a second recording (``validate``).

A recording that cannot tell effects apart raises InsufficientData listing everything
missing (the CLI writes it to summary.json with verdict "none" and exits 2): fewer than
``min_samples`` usable samples, no motion, motion in one direction only, or one speed only.
A recording that only cannot test some terms (constant load: load_dependent; less than a
revolution: lead_error) is analysed without them, and the summary names them as untested.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.config import BBFrictionError
from bb_friction_ros.discrepancy import physical, plausibility, regimes
from bb_friction_ros.discrepancy.bandwidth import (acceleration_filter_of, choose_cutoff,
                                                   with_acceleration)
from bb_friction_ros.discrepancy.data import inputs_of
from bb_friction_ros.discrepancy.reference import RigidBody
from bb_friction_ros.discrepancy.selection import (ambiguities, candidates,
                                                   pre_rolling_grid, refit_all,
                                                   RIGID_BODY_TERMS, select, to_termset)
from bb_friction_ros.empirical_terms import filter_lag_s, TermSet
from bb_friction_ros.model_file import physics_of, read_model_file, write_model_file
from bb_friction_ros.runner import FrictionSignError, load_checked_model


# Two least-squares fits of the same terms solved two ways differ by rounding only (3e-17 of
# 0.135 where the workflow chose exactly the reference's terms, driveNo2).
SAME_FIT_RTOL = 1e-9
# Relative difference above which the workflow's error is reported worse than the rigid-body
# reference's.  Where the workflow found exactly the hidden effects, the reference, fitted
# with more free parameters, still beat it on a validation recording by the noise (0.0175734
# against 0.0175737, 1.7e-5 apart).  A workflow that misses an effect is worse by percents
# (a missed inertia term: 20 % and more), so differences below 0.5 % are one fit to a user.
WORSE_THAN_REFERENCE_RTOL = 5e-3


def worse_than_reference(workflow, reference):
    """Tell whether the workflow's relative error is above the reference's (beyond noise)."""
    return reference is not None and workflow > reference * (1.0 + WORSE_THAN_REFERENCE_RTOL)


class InsufficientData(BBFrictionError):
    """The recording is too short or too flat to tell effects apart; ``missing`` says why."""

    def __init__(self, missing):
        """Keep the list of what is missing."""
        super().__init__("; ".join(missing))
        self.missing = list(missing)


def adequacy(x_fit, n_usable, settings):
    """
    Check what the fit part can tell apart.

    Return (missing, untested): ``missing`` lists fatal gaps (the analysis cannot run),
    ``untested`` maps a term name to the reason it cannot be tested here.
    """
    missing, untested = [], {}
    if n_usable < settings.min_samples:
        missing.append(f"too short: {n_usable} usable samples (measured and predicted), "
                       f"need at least {settings.min_samples} (min_samples)")
        return missing, untested
    if not float(np.ptp(x_fit.t_s)) > 0.0:
        # a bag whose stamps never advance (a CSV is refused earlier, naming t_s)
        missing.append("the time stamps (t_s) never advance in the fit part: no sample "
                       "period, so no acceleration, time regime or thermal time scale")
        return missing, untested
    w = x_fit.nut_velocity_rad_s
    moving = np.abs(w) > settings.standstill_speed_rad_s
    if not moving.any():
        missing.append("no motion: the nut never turns faster than "
                       f"{settings.standstill_speed_rad_s} rad/s, so the friction model "
                       "predicts nothing to compare with")
        return missing, untested
    share_pos = float(np.mean(w[moving] > 0))
    if min(share_pos, 1.0 - share_pos) < settings.min_direction_fraction:
        which = "positive" if share_pos >= 0.5 else "negative"
        missing.append(f"one direction only: {max(share_pos, 1 - share_pos):.0%} of the "
                       f"moving samples turn {which}; need at least "
                       f"{settings.min_direction_fraction:.0%} in each direction to tell a drag "
                       "from a torque offset (min_direction_fraction)")
    speed = np.abs(w[moving])
    p10, p90 = np.percentile(speed, [10, 90])
    if p90 < settings.min_speed_ratio * p10:
        missing.append(f"one speed only: |nut speed| spans {p10:.3g}-{p90:.3g} rad/s (10th-"
                       f"90th percentile); need a ratio of at least {settings.min_speed_ratio} "
                       "to tell viscous from constant drag (min_speed_ratio)")
    load = np.abs(x_fit.axial_load_n)
    l10, l50, l90 = np.percentile(load, [10, 50, 90])
    if l50 <= 0 or (l90 - l10) < settings.min_load_variation_fraction * l50:
        untested["load_dependent"] = (
            f"axial load nearly constant ({l10:.4g}-{l90:.4g} N): a load-proportional term "
            "cannot be told from seal_drag (min_load_variation_fraction)")
    if "load_dependent" in untested:
        untested["lead_error"] = (
            "axial load nearly constant: the load-scaled lead-error ripple is the same column "
            "as angle_ripple (which is tested)")
    counts, _ = np.histogram(np.mod(x_fit.nut_angle_rad, 2 * math.pi),
                             bins=settings.angle_bins, range=(0.0, 2 * math.pi))
    if counts.min() < settings.min_samples_per_angle_bin:
        reason = (f"the nut angle does not cover a whole revolution ({int((counts >= 1).sum())} "
                  f"of {settings.angle_bins} angle bins hold samples; need "
                  f"{settings.min_samples_per_angle_bin} in each)")
        untested["lead_error"] = reason
        untested["angle_ripple"] = reason
    stroke = _stroke_gap(x_fit, settings)
    if stroke:
        untested["stroke_position"] = stroke
    accel = x_fit.nut_accel_rad_s2
    if accel is None or not np.any(np.abs(accel) > 0):
        untested["inertia"] = "no acceleration in the fit part"
    return missing, untested


def _stroke_gap(x, settings):
    """
    Return why stroke_position cannot be tested on inputs ``x`` ("" when it can).

    A change along the stroke is told from a change in time, speed or direction only when
    the nut passes the same stretch of the stroke in both directions: the travel (P5-P95 of
    the cumulative angle) must reach ``min_stroke_revolutions`` and every one of
    ``stroke_bins`` equal stretches must hold ``min_bin_samples`` moving samples in each
    direction.
    """
    phi = x.nut_angle_rad
    lo, hi = np.percentile(phi, [5, 95])
    if hi - lo < settings.min_stroke_revolutions * 2 * math.pi:
        return (f"the nut travels {(hi - lo) / (2 * math.pi):.3g} rev (P5-P95) in the fit "
                f"part; need {settings.min_stroke_revolutions} rev to tell a change along the "
                "stroke from a change in time (min_stroke_revolutions)")
    w = x.nut_velocity_rad_s
    moving = np.abs(w) > settings.standstill_speed_rad_s
    edges = np.linspace(lo, hi, settings.stroke_bins + 1)
    for sign in (+1, -1):
        counts, _ = np.histogram(phi[moving & (np.sign(w) == sign)], bins=edges)
        if counts.min() < settings.min_bin_samples:
            return ("the nut does not pass every stretch of its stroke in both directions "
                    f"(fewer than {settings.min_bin_samples} samples moving "
                    f"{'+' if sign > 0 else '-'} in a stretch): a change along the stroke "
                    "cannot be told from one with direction or time")
    return ""


@dataclasses.dataclass
class Analysis:
    """Everything the summary and the report need."""

    recording: object          # data.Recording of the usable samples
    fit_mask: np.ndarray
    residual_nm: np.ndarray    # measured - predicted
    added_nm: np.ndarray       # torque of the selected terms
    noise_nm: float
    terms: TermSet
    trace: list
    untested: dict
    bins: list
    regions_before: list       # regime rows over all usable samples, before
    regions_after: list        # same, after the selected terms
    holdout_before: list       # regime rows over the held-out part, before
    holdout_after: list
    rmse_before_nm: float      # held-out
    rmse_after_nm: float
    dropped: dict
    noise: object = None       # regimes.NoiseModel
    accel_filter: dict = None  # the acceleration filter's settings (None: CSV column)
    ambiguities: list = dataclasses.field(default_factory=list)
    rejected_terms: TermSet = None     # selected, but no better on the held-out part
    # the terms as fitted on the fit part (the held-out figures); ``terms`` is
    # their refit on all usable samples (augmented.yaml, --validate, the node)
    terms_fit_part: TermSet = None
    refit: dict = None                 # summary.json["refit"]
    accel_choice: object = None        # bandwidth.CutoffChoice (None: the CSV's column)
    reference: object = None           # reference.RigidBody fitted on all usable samples
    heldout: dict = None               # summary.json["heldout"]: workflow and reference
    physical: object = None            # physical.PhysicalSearch (None: not run)

    @property
    def verdict(self):
        """Return "found" when terms were selected (and improve the held-out part)."""
        return "found" if len(self.terms) or physical.chosen(self.physical) else "none"


def _rms(a):
    return float(np.sqrt(np.mean(a ** 2))) if a.size else float("nan")


def usable(rec):
    """Return (mask of analysable samples, counts of the dropped ones by reason)."""
    measured = np.isfinite(rec.torque_meas_nm)
    predicted = np.isfinite(rec.torque_pred_nm) & rec.converged
    dropped = {"no_measurement": int((~measured).sum()),
               "model_not_converged": int((measured & ~predicted).sum())}
    ok = measured & predicted
    if rec.nut_accel_rad_s2 is not None:
        accel = np.isfinite(rec.nut_accel_rad_s2)
        dropped["no_acceleration"] = int((ok & ~accel).sum())
        ok &= accel
    return ok, dropped


def analyse(rec, settings, physics=None):
    """
    Run steps 0-3 and 5 on a Recording; raise InsufficientData when it cannot tell.

    ``physics`` (a physical.PhysicsContext): the model's own parameters are candidates too.
    """
    choice = choose_cutoff(rec, settings, usable)
    rec, spec = with_acceleration(rec, settings, choice and {"accel_cutoff_hz":
                                                             choice.cutoff_hz})
    ok, dropped = usable(rec)
    if not ok.any():
        if dropped["no_measurement"] == len(rec):
            what = "no measured torque"
        elif dropped.get("no_acceleration"):
            what = (f"too short to derive the acceleration: no continuous segment has "
                    f"{settings.accel_min_segment_samples} samples (accel_min_segment_samples; "
                    f"a step longer than {settings.segment_gap_factor} median steps splits "
                    "segments)")
        else:
            what = "no sample with both a measured torque and a converged prediction"
        raise InsufficientData([what])
    rec_in = rec              # every input sample drives a physical trial's model
    if not ok.all():          # a copy of every column only when samples are dropped
        rec = rec.take(ok)
    n = len(rec)
    n_fit = int(math.floor((1.0 - settings.holdout_fraction) * n))
    fit_mask = np.zeros(n, dtype=bool)
    fit_mask[:n_fit] = True
    # the split is by sample order: the parts are slices, so their inputs are views, not
    # copies (a 10-minute 1 kHz recording: 17 MB for the fit part's columns)
    fit_part, hold = slice(0, n_fit), slice(n_fit, n)
    x_fit = inputs_of(rec, fit_part)
    missing, untested = adequacy(x_fit, n, settings)
    if missing:
        raise InsufficientData(nonconvergence_first(missing, dropped, rec_in))
    if choice is not None and not choice.inertia_identifiable:
        untested.setdefault("inertia", choice.reason)
    if "pre_rolling" not in untested:
        grid = pre_rolling_grid(x_fit, settings)
        if isinstance(grid, str):
            untested["pre_rolling"] = grid
    if "stribeck" not in untested:
        grid = [c for c in candidates(x_fit, settings) if c.name == "stribeck"][0].grid
        if not grid[-1] > grid[0]:
            untested["stribeck"] = ("no low-speed samples below the fast ones: the Stribeck "
                                    "velocity grid is empty")
    r = rec.torque_meas_nm - rec.torque_pred_nm
    noise = regimes.noise_model(r, settings.noise_max_lag, settings.noise_plateau_ratio,
                                rec.nut_velocity_rad_s, rec.t_s)
    fixed = {"inertia": spec} if spec else {}
    if physics is None:
        # without a model of the drive the rigid-body terms are the textbook floor, not
        # discoveries: plain BIC decides them (selection.penalty, docs/discrepancy.md)
        known = RIGID_BODY_TERMS if rec.info.get("baseline") == "zero" else ()
        terms, trace, ctx = select(x_fit, r[fit_part], settings, skip=tuple(untested),
                                   fixed=fixed, tau=noise.tau, known=known)
        search = None
    else:
        terms, trace, ctx, search = physical.select(physics, rec_in, ok, fit_mask, r, x_fit,
                                                    settings, tuple(untested), fixed,
                                                    noise.tau)
        physical.use_replay_change(search, rec_in, ok)      # what replay will do with it
    shift = physical.shift_nm(search, n)      # the chosen physical change, or 0
    ambiguous = ambiguities(ctx, x_fit, (r - shift)[fit_part], settings) if len(terms) else []
    ambiguous += search.identifiability if search is not None else []   # chosen, or a twin
    x = inputs_of(rec)
    rejected = None
    added = shift + (terms.torque_nm(x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s,
                                     x.axial_load_n, x.nut_accel_rad_s2)
                     if len(terms) else np.zeros(n))
    # a chosen physical change alone that the held-out part cannot see (B2B contacts that
    # close on the fit part only) is not judged there: its verdict would be the noise's
    unseen = not len(terms) and physical.unseen_on_hold(search, shift[hold], noise, n_fit,
                                                        settings)
    if (len(terms) or physical.chosen(search)) and not unseen and \
            not _rms((r - added)[hold]) < _rms(r[hold]):
        # selected on the fit part but no better on the held-out part (e.g. a recording
        # whose two halves disagree): not an effect this recording supports
        rejected, terms, added, shift = terms, TermSet(), np.zeros(n), np.zeros(n)
        physical.reject(search)
        ambiguous = []
    after = r - added
    bins = regimes.make_bins(x, settings)
    x_hold = inputs_of(rec, hold)
    tau = noise.tau
    refitted, refit = refit_terms(ctx, terms, x, r - shift)
    reference, heldout = reference_rows(rec, x, r, fit_mask, after)
    std = noise.std_nm
    return Analysis(
        recording=rec, fit_mask=fit_mask, residual_nm=r, added_nm=added, noise_nm=std,
        terms=refitted, trace=trace, untested=untested, bins=bins,
        regions_before=regimes.regime_table(bins, x, r, std, settings, tau),
        regions_after=regimes.regime_table(bins, x, after, std, settings, tau),
        holdout_before=regimes.regime_table(bins, x_hold, r[hold], std, settings, tau),
        holdout_after=regimes.regime_table(bins, x_hold, after[hold], std, settings, tau),
        rmse_before_nm=_rms(r[hold]), rmse_after_nm=_rms(after[hold]), dropped=dropped,
        noise=noise, accel_filter=spec, ambiguities=ambiguous, rejected_terms=rejected,
        terms_fit_part=terms, refit=refit, accel_choice=choice, reference=reference,
        heldout=heldout, physical=search)


def nonconvergence_first(missing, dropped, rec):
    """
    Put the samples the model could not solve first among what the recording is missing.

    A model that does not converge on part of the recording (theta 9.5 deg: 2417 steps)
    leaves a recording that may look like one direction only; the cause to fix is the model
    or its config, not the recording.
    """
    lost = dropped.get("model_not_converged", 0)
    if not lost:
        return missing
    config = rec.info.get("config", "the --config")
    return [f"{lost} of {len(rec)} samples were dropped because the model did not converge "
            f"on them (config {config}): what follows is what the rest can tell; check the "
            "model config (or --baseline zero: no model of this screw)"] + missing


def refit_terms(ctx, terms, x, r):
    """
    Return (the terms to write, summary.json["refit"]): the chosen terms refitted on all.

    The model written used to be fitted on the first 70 % only, and on a measured robot
    axis it validated worse than a least-squares fit of the same terms.  The refit keeps the
    selected nonlinear values; if an amplitude leaves its physical sign or range on all
    samples, the fit part's terms are kept and the summary says so.
    """
    if not len(terms):
        return terms, {"samples": 0, "refitted": False, "reason": "no term selected"}
    f = refit_all(ctx.best[ctx.chosen], x, r)
    if not f.physical:
        return terms, {"samples": int(r.size), "refitted": False,
                       "reason": "on all samples an amplitude leaves its physical sign or "
                                 "range; the fit part's terms are written"}
    return to_termset(f), {"samples": int(r.size), "refitted": True,
                           "reason": "the chosen terms refitted on all usable samples of "
                                     "the fit recording (their nonlinear values as "
                                     "selected)"}


def reference_rows(rec, x, r, fit_mask, after):
    """
    Return (RigidBody on all usable samples, summary.json["heldout"]).

    The held-out row: the workflow's terms and the rigid-body reference, both fitted on the
    fit part, on the held-out part (the same reference row as the validation).
    """
    n_fit = int(np.count_nonzero(fit_mask))      # the fit part is the first samples
    fit_part, hold = slice(0, n_fit), slice(n_fit, None)
    meas = rec.torque_meas_nm[hold]
    norm = float(np.linalg.norm(meas))

    def rel(e):
        return float(np.linalg.norm(e)) / norm if norm > 0 else None
    ref_fit = RigidBody.fit(inputs_of(rec, fit_part), r[fit_part])
    e_ref = r[hold] - ref_fit.torque_nm(inputs_of(rec, hold))
    heldout = {"n": int(r.size - n_fit), "fitted_on": "the fit part (first samples)",
               "rmse_before_nm": _rms(r[hold]), "rmse_after_nm": _rms(after[hold]),
               "relative_error_before": rel(r[hold]), "relative_error_after": rel(after[hold]),
               "reference_rmse_nm": _rms(e_ref), "reference_relative_error": rel(e_ref),
               "reference_params": ref_fit.params()}
    return RigidBody.fit(x, r), heldout


def _region(row):
    return {k: row[k] for k in ("variable", "label", "n", "mean_residual_nm",
                                "mean_drag_excess_nm", "z_mean", "z_drag")}


def summary_of(a, info=None):
    """Return the summary.json dict of an Analysis."""
    regions = [_region(row) for row in a.regions_before if row["significant"]]
    remaining = [_region(row) for row in a.regions_after if row["significant"]]
    if a.verdict == "found":
        reason = (f"{', '.join(physical.names(a.physical, a.terms))} explain(s) the residual: "
                  f"held-out RMSE "
                  f"{a.rmse_before_nm:.4g} -> {a.rmse_after_nm:.4g} N m (noise "
                  f"{a.noise_nm:.3g} N m)")
    elif a.rejected_terms is not None:
        bad = a.rejected_terms.torque_nm(*_xargs(a))
        after = _rms((a.residual_nm - bad)[~a.fit_mask])
        reason = (f"the terms selected on the fit part ({', '.join(a.rejected_terms.names)}) "
                  f"do not improve the held-out part (RMSE {a.rmse_before_nm:.4g} -> "
                  f"{after:.4g} N m), so none is adopted: the two parts of the recording "
                  "disagree, or the effect is outside the library")
    elif regions:
        reason = ("no library term brings strong evidence, but the residual is significant in "
                  f"{len(regions)} regime(s): an effect outside the library")
    else:
        reason = ("no library term brings strong evidence and no regime deviates from the "
                  "noise: the model agrees with the measurement")
    noise = a.noise_nm
    reducible = a.rmse_before_nm - noise
    rec_info = info or a.recording.info
    out = {
        "verdict": a.verdict,
        "reason": reason,
        "effects": physical.effects(a.physical, a.terms),
        "physical": physical.summary(a.physical),
        "ambiguities": a.ambiguities,
        "rmse_before_nm": a.rmse_before_nm,
        "rmse_after_nm": a.rmse_after_nm,
        "noise_std_nm": noise,
        "noise": a.noise.as_dict() if a.noise is not None else None,
        "reducible_removed_fraction": (a.rmse_before_nm - a.rmse_after_nm) / reducible
        if reducible > 0 else None,
        "regions": regions,
        "regions_remaining": remaining,
        "untested": a.untested,
        "samples": {"usable": len(a.recording), "fit": int(a.fit_mask.sum()),
                    "holdout": int((~a.fit_mask).sum()), "dropped": a.dropped},
        "selection": a.trace,
        "acceleration": _acceleration_info(a, rec_info),
        "identified_from_data_only": rec_info.get("baseline") == "zero",
        "input": rec_info,
    }
    if a.rejected_terms is not None:
        out["rejected_effects"] = a.rejected_terms.effects()
    out.update(reference_summary(a))
    return out


def reference_summary(a):
    """
    Return the summary.json keys that say which fit gives which figure, and the reference.

    ``effects`` are the written terms (refitted on all usable samples); ``effects_fit_part``
    the same terms as fitted on the fit part, which give the held-out figures; ``heldout``
    holds the workflow's and the rigid-body reference's held-out errors; ``warnings`` says
    plainly where the workflow is worse than the reference.
    """
    from bb_friction_ros.discrepancy.reference import FORMULA
    out = {"effects_fit_part": a.terms_fit_part.effects() if a.terms_fit_part else [],
           "refit": a.refit, "heldout": a.heldout,
           "reference": {"model": FORMULA,
                         "params_all_samples": a.reference.params() if a.reference else None},
           "warnings": []}
    h = a.heldout
    if h and worse_than_reference(h["relative_error_after"], h["reference_relative_error"]):
        out["warnings"].append(
            f"on the held-out part the workflow is worse than the rigid-body reference "
            f"({FORMULA}): relative error {h['relative_error_after']:.4g} against "
            f"{h['reference_relative_error']:.4g}")
    return out


def _xargs(a):
    x = inputs_of(a.recording)
    return x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s, x.axial_load_n, x.nut_accel_rad_s2


def _acceleration_info(a, info):
    out = {"source": info.get("acceleration_source", "derived (zero-phase filter)")}
    if a.accel_choice is not None:
        out.update(a.accel_choice.as_dict())
    else:
        out["chosen_by"] = out["source"]
    if a.accel_filter:
        fc = a.accel_filter["accel_cutoff_hz"]
        out.update(cutoff_hz=fc, max_gap_s=a.accel_filter["max_gap_s"],
                   live_lag_s=filter_lag_s(fc))
    if "acceleration_run_cutoff_hz" in info:
        out["run_cutoff_hz"] = info["acceleration_run_cutoff_hz"]
    return out


def insufficient_summary(exc, info=None):
    """Return the summary.json dict of a recording too short or flat to tell."""
    return {"verdict": "none", "reason": "insufficient data: " + "; ".join(exc.missing),
            "missing": exc.missing, "effects": [], "rmse_before_nm": None,
            "rmse_after_nm": None, "regions": [], "input": info or {}}


AUGMENTED_HEADER = (
    "# Written by bb-friction discrepancy: the base ball-screw config plus the empirical terms\n"
    "# selected from a recording (docs/discrepancy.md).  Replay and the live node add\n"
    "# empirical_terms to the physics prediction as a separate part.\n")


def write_augmented(path, config_path, terms, zero_baseline=False, physical_search=None):
    """
    Write ``augmented.yaml``: the base ``ball_screw`` mapping plus ``empirical_terms``.

    Terms already in the base config are kept (the new ones were fitted on top of them).
    With a zero baseline the terms are the whole torque: the file says ``physics: none``, so
    replay and the node predict with the terms alone (adding them to the
    ball-screw model counted the friction twice), and no base term is kept (the zero
    prediction held none).  A chosen physical effect sets its value in
    ``ball_screw:``.
    """
    base, existing = read_model_file(config_path)
    base = physical.calibrated_section(base, physical_search)
    physics = physics_of(config_path)
    note = ""
    if zero_baseline:
        existing, physics = TermSet(), "none"
        note = ("# --baseline zero: the terms were fitted to the measured torque alone (no model\n"
                "# of this screw); they are the whole torque.  physics: none makes replay and\n"
                "# the node predict with the terms alone; the ball_screw part is only the base\n"
                "# config the runner needs.\n")
    write_model_file(path, base, TermSet(existing.terms + terms.terms),
                     AUGMENTED_HEADER + note + f"# base config: {config_path}\n",
                     physics=None if physics == "ball_screw" else physics)
    try:    # never leave a model behind that the runner would refuse, or that pushes along
        load_checked_model(path)
    except FrictionSignError:
        path.unlink()
        raise
    return path


@dataclasses.dataclass
class Validation:
    """The augmented model applied, unchanged, to a second recording."""

    recording: object          # data.Recording of the usable samples (with acceleration)
    added_nm: np.ndarray       # the selected terms' torque on it
    summary: dict              # summary.json["validation"]
    reference_nm: np.ndarray = None    # the rigid-body reference's torque on it


def validate(a, rec, settings):
    """
    Apply the selected terms of Analysis ``a`` to Recording ``rec``: no refit.

    The acceleration uses the fitted filter's cut-off (the inertia term's, or the analysis
    one) with ``rec``'s own gap rule.  Relative error = ||meas - pred|| / ||meas||.
    """
    spec = acceleration_filter_of(rec, settings)
    if spec is not None and a.accel_filter:
        spec["accel_cutoff_hz"] = a.accel_filter["accel_cutoff_hz"]
    rec, _ = with_acceleration(rec, settings, spec)
    ok, dropped = usable(rec)
    if not ok.any():
        raise InsufficientData([f"validation recording {rec.info.get('input', '?')}: no "
                                f"usable sample (dropped: {dropped})"])
    shift = physical.validation_shift(a.physical, rec, ok)     # a chosen physical change
    rec = rec.take(ok)
    x = inputs_of(rec)
    added = shift + (a.terms.torque_nm(x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s,
                                       x.axial_load_n, x.nut_accel_rad_s2)
                     if len(a.terms) else np.zeros(len(rec)))
    meas, pred = rec.torque_meas_nm, rec.torque_pred_nm
    norm = float(np.linalg.norm(meas))

    def rel(e):
        return float(np.linalg.norm(e)) / norm if norm > 0 else None

    ref = a.reference.torque_nm(x) if a.reference is not None else np.zeros(len(rec))
    summary = {"n": len(rec), "rmse_before_nm": _rms(meas - pred),
               "rmse_after_nm": _rms(meas - pred - added),
               "relative_error_before": rel(meas - pred),
               "relative_error_after": rel(meas - pred - added),
               "reference_rmse_nm": _rms(meas - pred - ref),
               "reference_relative_error": rel(meas - pred - ref),
               "reference_fitted_on": "all usable samples of the fit recording, as the "
                                      "written terms",
               "input": rec.info.get("input"), "baseline": baseline_of(rec),
               "dropped": dropped,
               "terms": list(a.terms.names)}
    return Validation(rec, added, summary, ref)


def write_validation_csv(path, v):
    """Write ``validation/prediction.csv``: t_s, torque_meas_nm, torque_pred_nm, augmented."""
    rec = v.recording
    table = np.column_stack([rec.t_s, rec.torque_meas_nm, rec.torque_pred_nm,
                             rec.torque_pred_nm + v.added_nm])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, table, delimiter=",", fmt="%.17g", comments="",
               header="t_s,torque_meas_nm,torque_pred_nm,torque_augmented_nm")
    return path


def baseline_of(rec):
    """Return the baseline of a recording: "zero" (no model) or "model" (its prediction)."""
    return rec.info.setdefault("baseline", "model")


def check_same_baseline(rec, rec2):
    """
    Refuse a validation recording whose baseline differs from the fit recording's (23.4).

    Terms fitted to the whole torque (zero baseline) added to a model's prediction count
    the friction twice; terms fitted on top of a model, added to a zero prediction, lack it.
    Before, both ran silently (relative error 1.00 -> 0.814 against 0.20 -> 0.017).
    """
    if rec2 is None or baseline_of(rec) == baseline_of(rec2):
        return
    from bb_friction_ros.discrepancy.data import InputProblem

    def said(r):
        return (f"{r.info.get('input')} has baseline {baseline_of(r)} "
                f"({r.info.get('prediction_source', '?')})")
    raise InputProblem(
        f"--validate: the two recordings use different baselines: {said(rec)}, but "
        f"{said(rec2)}; the terms would be compared with another prediction than they were "
        "fitted on. Use --baseline zero for both (no model of this screw), or give both the "
        "model's prediction (a CSV whose torque_pred_nm is 0 counts as zero)")


def run_discrepancy(input_path, out, config=None, settings=None, replay_settings=None,
                    topics=None, recompute=False, plots=True, progress=False, validate_path=None,
                    baseline="model", torque_constant_nm_per_a=None,
                    current_topic="motor_current", physical_asked=False):
    """
    Run the whole workflow on a bag or CSV into directory ``out``; return (status, summary).

    Status 0: analysed (verdict "found" or "none").  Status 2: the recording is too short or
    too flat to tell (summary.json and report.md say what is missing).  An unreadable input
    raises data.InputProblem; a bad config raises ConfigError.  ``validate_path``: a second
    recording the augmented model is applied to without refitting (``DIR/validation/``).
    ``baseline`` "zero": no model of this screw; every term is identified from the data.
    ``torque_constant_nm_per_a``: the measured torque is K times the motor current (CSV
    column ``motor_current_a``, bag topic ``current_topic``), for both recordings.
    ``physical_asked``: the physical candidates were asked for explicitly (``--physical``),
    so a run that cannot try them warns; on by default, they are skipped silently (the
    reason is in summary.json's ``physical_skipped``).
    """
    from pathlib import Path
    from bb_friction_ros.bags import Topics
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.discrepancy.settings import DiscrepancySettings
    from bb_friction_ros.node_parameters import NodeParameters
    settings = settings or DiscrepancySettings()
    config = Path(config) if config else bundled_config("ball_screw.yaml")
    load = dict(replay_settings=replay_settings or NodeParameters(), topics=topics or Topics(),
                recompute=recompute, progress=progress, baseline=baseline,
                torque_constant_nm_per_a=torque_constant_nm_per_a, current_topic=current_topic)
    plausibility.check_torque_constant(torque_constant_nm_per_a, settings)
    rec = load_recording(input_path, config, **load)
    rec2 = load_recording(validate_path, config, **load) if validate_path else None
    for path, r in ((input_path, rec), (validate_path, rec2)):
        if r is not None:
            r.info["config"] = str(config)
            plausibility.check_measured_sign(r, settings, path)
            plausibility.check_measured_scale(r, settings, path)
    check_same_baseline(rec, rec2)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with _only_run_in(out):
        remove_earlier_outputs(out)
        try:
            return _analyse_into(out, rec, rec2, config, settings, load, plots,
                                 physical_asked)
        except BaseException as exc:        # Ctrl-C, a full disk: mark the outputs partial
            try:
                _write_summary(out, {"complete": False, "error": "interrupted" if isinstance(
                    exc, KeyboardInterrupt) else f"{type(exc).__name__}: {exc}"})
            except OSError:                 # the disk that is full: the error says it
                pass
            raise


def _physical_ignored(settings, rec, config):
    """Return why the physical candidates cannot apply to this run, or None."""
    if not settings.physical.enabled:
        return None
    if rec.info.get("baseline") == "zero":
        return ("with no model of this screw (--baseline zero, or a torque_pred_nm of 0) "
                "there are no model parameters to try")
    if physics_of(config) != "ball_screw":
        return (f"{config} says physics: none, so there are no model parameters to try")
    return None


def _analyse_into(out, rec, rec2, config, settings, load, plots, physical_asked=False):
    """Analyse ``rec`` (and validate on ``rec2``) and write every output into ``out``."""
    import json
    from bb_friction_ros.discrepancy.report import write_report, write_insufficient_report
    ignored = _physical_ignored(settings, rec, config)
    try:
        physics = None          # the model's own parameters as candidates
        if settings.physical.enabled and ignored is None:
            physics = physical.PhysicsContext(config, physical.runner_args(
                load["replay_settings"]), settings.physical,
                load["replay_settings"].schedule())
        a = analyse(rec, settings, physics)
        v = validate(a, rec2, settings) if rec2 is not None else None
    except InsufficientData as exc:
        summary = insufficient_summary(exc, rec.info)
        write_insufficient_report(out, summary)
        _write_summary(out, summary)
        return 2, summary
    augmented = write_augmented(out / "augmented.yaml", config, a.terms,
                                zero_baseline=rec.info.get("baseline") == "zero",
                                physical_search=a.physical)
    summary = summary_of(a, rec.info)
    summary["augmented_config"] = str(augmented)
    summary["base_config"] = str(config)
    summary["warnings"] += rec.info.get("notes", []) + (
        [f"--physical was ignored: {ignored}"] if ignored and physical_asked else [])
    summary["physical_skipped"] = ignored
    if v is not None:
        write_validation_csv(out / "validation" / "prediction.csv", v)
        summary["validation"] = v.summary
        if worse_than_reference(v.summary["relative_error_after"],
                                v.summary["reference_relative_error"]):
            summary["warnings"].insert(0, (
                f"on the validation recording the workflow is WORSE than the rigid-body "
                f"reference: relative error {v.summary['relative_error_after']:.4g} against "
                f"{v.summary['reference_relative_error']:.4g}"))
    summary["settings"] = dataclasses.asdict(settings)
    json.dumps(summary, allow_nan=False)     # a figure that is not JSON fails before writing
    write_report(out, a, summary, plots=plots, validation=v)
    _write_summary(out, summary)            # last: its "complete" vouches for the rest
    return 0, summary


# What a run writes into its --out (and nothing else there is ever removed).
def _outputs():
    from bb_friction_ros.discrepancy.report import FIGURES, VALIDATION_FIGURE
    return (SUMMARY_FILE, AUGMENTED_FILE, REPORT_FILE) + FIGURES \
        + (VALIDATION_FIGURE, physical.B2B_FIGURE)


SUMMARY_FILE, AUGMENTED_FILE, REPORT_FILE = "summary.json", "augmented.yaml", "report.md"
VALIDATION_DIR = "validation"


def remove_earlier_outputs(out):
    """
    Remove what an earlier run wrote into ``out``, before this one writes anything.

    An earlier ``augmented.yaml``, ``validation/`` or plot beside a new summary whose verdict
    is none was taken for this run's.  Only this command's own file names are removed.
    """
    import shutil
    for name in _outputs():
        (out / name).unlink(missing_ok=True)
    shutil.rmtree(out / VALIDATION_DIR, ignore_errors=True)


def _write_summary(out, summary):
    """Write ``summary.json`` with ``complete`` (True unless the summary says otherwise)."""
    import json
    summary.setdefault("complete", True)
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2, allow_nan=False))


class OutputInUse(BBFrictionError):
    """Another run writes into the same output directory."""


def _only_run_in(out):
    """
    Return a context that holds an exclusive lock on the directory ``out`` for one run.

    Two runs into one --out mixed their files; the second is refused while the first runs.
    The lock is the directory's own (flock on its descriptor): nothing is left behind.
    """
    import contextlib
    import fcntl
    import os

    @contextlib.contextmanager
    def held():
        fd = os.open(out, os.O_RDONLY)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputInUse(f"{out}: another bb-friction discrepancy is writing into it; "
                                  "wait for it, or choose another --out") from None
            yield
        finally:
            os.close(fd)
    return held()
