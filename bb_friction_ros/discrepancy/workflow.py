"""
The discrepancy workflow: residual, where, which effect, add it, show the gap shrink.

``analyse(recording, settings)`` is the pure core (arrays in, an Analysis out);
``run_discrepancy`` adds reading the input and writing ``augmented.yaml``, ``summary.json``
and ``report.md`` with its PNGs.

1. Residual = measured - predicted, the prediction from the replay path (data.py).
2. Where: the noise level is estimated from the residual itself (regimes.noise_std_nm) and
   the residual is binned by direction, speed, angle within a revolution, load and time;
   significant bins are the ``regions``.
3. Which effect: selection.select on the first (1 - holdout_fraction) of the samples.
4. The selected terms go into ``augmented.yaml`` (base config + ``empirical_terms``).
5. RMSE before/after, regime table and plots on the held-out last part.

A recording that cannot tell effects apart raises InsufficientData listing everything
missing (the CLI writes it to summary.json with verdict "none" and exits 2): fewer than
``min_samples`` usable samples, no motion, motion in one direction only, or one speed only.
A recording that only cannot test some terms (constant load: load_dependent; less than a
revolution: lead_error) is analysed without them, and the summary names them as untested.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.discrepancy import regimes
from bb_friction_ros.discrepancy.data import inputs_of
from bb_friction_ros.discrepancy.selection import candidates, select
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.model_file import read_model_file, write_model_file


class InsufficientData(ValueError):
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
    counts, _ = np.histogram(np.mod(x_fit.nut_angle_rad, 2 * math.pi),
                             bins=settings.angle_bins, range=(0.0, 2 * math.pi))
    if counts.min() < settings.min_samples_per_angle_bin:
        untested["lead_error"] = (
            f"the nut angle does not cover a whole revolution ({int((counts >= 1).sum())} of "
            f"{settings.angle_bins} angle bins hold samples; need "
            f"{settings.min_samples_per_angle_bin} in each)")
    return missing, untested


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

    @property
    def verdict(self):
        """Return "found" when terms were selected, else "none"."""
        return "found" if len(self.terms) else "none"


def _rms(a):
    return float(np.sqrt(np.mean(a ** 2))) if a.size else float("nan")


def usable(rec):
    """Return (mask of analysable samples, counts of the dropped ones by reason)."""
    measured = np.isfinite(rec.torque_meas_nm)
    predicted = np.isfinite(rec.torque_pred_nm) & rec.converged
    dropped = {"no_measurement": int((~measured).sum()),
               "model_not_converged": int((measured & ~predicted).sum())}
    return measured & predicted, dropped


def analyse(rec, settings):
    """Run steps 1-3 and 5 on a Recording; raise InsufficientData when it cannot tell."""
    ok, dropped = usable(rec)
    if not ok.any():
        what = "no measured torque" if dropped["no_measurement"] == len(rec) else \
            "no sample with both a measured torque and a converged prediction"
        raise InsufficientData([what])
    rec = rec.take(ok)
    n = len(rec)
    n_fit = int(math.floor((1.0 - settings.holdout_fraction) * n))
    fit_mask = np.zeros(n, dtype=bool)
    fit_mask[:n_fit] = True
    x_fit = inputs_of(rec, fit_mask)
    missing, untested = adequacy(x_fit, n, settings)
    if missing:
        raise InsufficientData(missing)
    if "stribeck" not in untested:
        grid = [c for c in candidates(x_fit, settings) if c.name == "stribeck"][0].grid
        if not grid[-1] > grid[0]:
            untested["stribeck"] = ("no low-speed samples below the fast ones: the Stribeck "
                                    "velocity grid is empty")
    r = rec.torque_meas_nm - rec.torque_pred_nm
    noise = regimes.noise_std_nm(r)
    terms, trace = select(x_fit, r[fit_mask], settings, skip=tuple(untested))
    x = inputs_of(rec)
    added = terms.torque_nm(x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s, x.axial_load_n) \
        if len(terms) else np.zeros(n)
    after = r - added
    bins = regimes.make_bins(x, settings)
    hold = ~fit_mask
    x_hold = inputs_of(rec, hold)
    return Analysis(
        rec, fit_mask, r, added, noise, terms, trace, untested, bins,
        regimes.regime_table(bins, x, r, noise, settings),
        regimes.regime_table(bins, x, after, noise, settings),
        regimes.regime_table(bins, x_hold, r[hold], noise, settings),
        regimes.regime_table(bins, x_hold, after[hold], noise, settings),
        _rms(r[hold]), _rms(after[hold]), dropped)


def _region(row):
    return {k: row[k] for k in ("variable", "label", "n", "mean_residual_nm",
                                "mean_drag_excess_nm", "z_mean", "z_drag")}


def summary_of(a, info=None):
    """Return the summary.json dict of an Analysis."""
    regions = [_region(row) for row in a.regions_before if row["significant"]]
    remaining = [_region(row) for row in a.regions_after if row["significant"]]
    if a.verdict == "found":
        reason = (f"{', '.join(a.terms.names)} explain(s) the residual: held-out RMSE "
                  f"{a.rmse_before_nm:.4g} -> {a.rmse_after_nm:.4g} N m (noise "
                  f"{a.noise_nm:.3g} N m)")
    elif regions:
        reason = ("no library term brings strong evidence, but the residual is significant in "
                  f"{len(regions)} regime(s): an effect outside the library")
    else:
        reason = ("no library term brings strong evidence and no regime deviates from the "
                  "noise: the model agrees with the measurement")
    noise = a.noise_nm
    reducible = a.rmse_before_nm - noise
    return {
        "verdict": a.verdict,
        "reason": reason,
        "effects": a.terms.effects(),
        "rmse_before_nm": a.rmse_before_nm,
        "rmse_after_nm": a.rmse_after_nm,
        "noise_std_nm": noise,
        "reducible_removed_fraction": (a.rmse_before_nm - a.rmse_after_nm) / reducible
        if reducible > 0 else None,
        "regions": regions,
        "regions_remaining": remaining,
        "untested": a.untested,
        "samples": {"usable": len(a.recording), "fit": int(a.fit_mask.sum()),
                    "holdout": int((~a.fit_mask).sum()), "dropped": a.dropped},
        "selection": a.trace,
        "input": info or a.recording.info,
    }


def insufficient_summary(exc, info=None):
    """Return the summary.json dict of a recording too short or flat to tell."""
    return {"verdict": "none", "reason": "insufficient data: " + "; ".join(exc.missing),
            "missing": exc.missing, "effects": [], "rmse_before_nm": None,
            "rmse_after_nm": None, "regions": [], "input": info or {}}


AUGMENTED_HEADER = (
    "# Written by bb-friction discrepancy: the base ball-screw config plus the empirical terms\n"
    "# selected from a recording (docs/discrepancy.md).  Replay and the live node add\n"
    "# empirical_terms to the physics prediction as a separate part.\n")


def write_augmented(path, config_path, terms):
    """
    Write ``augmented.yaml``: the base ``ball_screw`` mapping plus ``empirical_terms``.

    Terms already in the base config are kept (the new ones were fitted on top of them).
    """
    base, existing = read_model_file(config_path)
    return write_model_file(path, base, TermSet(existing.terms + terms.terms),
                            AUGMENTED_HEADER + f"# base config: {config_path}\n")


def run_discrepancy(input_path, out, config=None, settings=None, replay_settings=None,
                    topics=None, recompute=False, plots=True, progress=False):
    """
    Run the whole workflow on a bag or CSV into directory ``out``; return (status, summary).

    Status 0: analysed (verdict "found" or "none").  Status 2: the recording is too short or
    too flat to tell (summary.json and report.md say what is missing).  An unreadable input
    raises data.InputProblem; a bad config raises ConfigError.
    """
    from pathlib import Path
    import json
    from bb_friction_ros.bags import Topics
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.discrepancy.report import write_report, write_insufficient_report
    from bb_friction_ros.discrepancy.settings import DiscrepancySettings
    from bb_friction_ros.node_parameters import NodeParameters
    settings = settings or DiscrepancySettings()
    config = Path(config) if config else bundled_config("ball_screw.yaml")
    rec = load_recording(input_path, config, replay_settings or NodeParameters(),
                         topics or Topics(), recompute=recompute, progress=progress)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        a = analyse(rec, settings)
    except InsufficientData as exc:
        summary = insufficient_summary(exc, rec.info)
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
        write_insufficient_report(out, summary)
        return 2, summary
    augmented = write_augmented(out / "augmented.yaml", config, a.terms)
    summary = summary_of(a, rec.info)
    summary["augmented_config"] = str(augmented)
    summary["base_config"] = str(config)
    summary["settings"] = dataclasses.asdict(settings)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    write_report(out, a, summary, plots=plots)
    return 0, summary
