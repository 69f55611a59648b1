"""
``report.md`` and its PNGs for the discrepancy workflow.

Figures: ``residual_where.png`` (the residual against nut speed, angle within a revolution,
axial load and time, with the regime means; significant regimes in red),
``heldout_before_after.png`` (the same on the held-out part, before and after the selected
terms) and ``time_series.png`` (measured, predicted and augmented torque over time).
"""

import math

import numpy as np

from bb_friction_ros.discrepancy import physical
from bb_friction_ros.discrepancy.data import inputs_of

# Points per scatter panel: beyond a few thousand a scatter shows no more and costs seconds
# per figure (a 25,000-sample recording); an even stride keeps every regime.
MAX_SCATTER_POINTS = 4000
FIGURES = ("residual_where.png", "heldout_before_after.png", "time_series.png")
VALIDATION_FIGURE = "validation.png"


def _f(v, digits=4):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}g}"


def _regime_rows(rows):
    out = ["| variable | regime | n | mean residual [N m] | mean drag excess [N m] | z |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        z = max((abs(v) for v in (r["z_mean"], r["z_drag"]) if v is not None), default=None)
        out.append(f"| {r['variable']} | {r['label']} | {r['n']} | {_f(r['mean_residual_nm'])}"
                   f" | {_f(r['mean_drag_excess_nm'])} | {_f(z, 3)} |")
    return out


def _holdout_table(a):
    out = ["| variable | regime | n | RMSE before [N m] | RMSE after [N m] | mean before "
           "[N m] | mean after [N m] |", "|---|---|---|---|---|---|---|"]
    for b, after in zip(a.holdout_before, a.holdout_after):
        if b["n"] == 0:
            continue
        out.append(f"| {b['variable']} | {b['label']} | {b['n']} | {_f(b['rms_residual_nm'])} | "
                   f"{_f(after['rms_residual_nm'])} | {_f(b['mean_residual_nm'])} | "
                   f"{_f(after['mean_residual_nm'])} |")
    return out


def _effects_table(summary):
    out = ["| term | meaning | parameters |", "|---|---|---|"]
    for e in summary["effects"]:
        params = ", ".join(f"{k} = {v:.4g} {e['units'][k]}" for k, v in e["params"].items())
        out.append(f"| `{e['name']}` | {physical.meaning(e)} | {params} |")
    return out


def _trace_table(trace):
    out = ["| terms | BIC | BIC + threshold x terms | cross-validated RMSE [N m] | chosen |",
           "|---|---|---|---|---|"]
    for t in trace:
        out.append(f"| {', '.join(t['terms']) or '(none)'} | {t['bic']:.1f} | "
                   f"{t['penalised_bic']:.1f} | {_f(t['cv_rmse_nm'])} | "
                   f"{'yes' if t['chosen'] else ''} |")
    return out


def write_report(out, a, summary, plots=True, validation=None):
    """Write ``report.md`` (and the PNGs unless ``plots`` is false) into ``out``."""
    info = summary.get("input", {})
    s = summary["samples"]
    nm = summary.get("noise") or {}
    acc = summary.get("acceleration", {})
    lines = ["# Discrepancy report", ""]
    # where the workflow is worse than the rigid-body reference, say so first
    for w in summary.get("warnings", []):
        lines += [f"**Warning:** {w}.", ""]
    lines += [f"**Verdict: {summary['verdict']}.** {summary['reason']}.", ""]
    if summary.get("identified_from_data_only"):
        lines += ["**No model of this screw:** the prediction is zero, so every term below "
                  "was identified from the measured torque alone. It describes this drive "
                  "as measured, not a deviation from the ball-screw model.", ""]
    lines += [
        f"- input: `{info.get('input', '?')}` ({info.get('format', '?')}); prediction: "
        f"{info.get('prediction_source', '?')}; baseline {info.get('baseline', '?')}; "
        f"measured torque: {info.get('measured_torque_source', '?')}",
        f"- samples: {s['usable']} usable ({s['fit']} fit, first part; {s['holdout']} held "
        f"out, last part); dropped: {s['dropped']}",
        f"- noise level estimated from the residual (MAD of lag-{nm.get('lag_samples', 1)} "
        f"differences, read where the estimate stops growing with the lag): "
        f"{_f(summary['noise_std_nm'])} N m (lag-1 estimate {_f(nm.get('std_lag1_nm'))} N m; "
        f"autocorrelation time {_f(nm.get('autocorrelation_time_samples'), 3)} samples)",
        "- acceleration: " + acceleration_sentence(acc),
        f"- held-out RMSE: before {_f(summary['rmse_before_nm'])} N m, after "
        f"{_f(summary['rmse_after_nm'])} N m",
    ]
    if summary.get("reducible_removed_fraction") is not None:
        lines.append(f"- share of the reducible held-out RMSE (RMSE before - noise) removed: "
                     f"{summary['reducible_removed_fraction']:.0%}")
    if "augmented_config" in summary:
        lines.append(f"- augmented config: `{summary['augmented_config']}` (replay with "
                     f"`bb-friction replay BAG --config {summary['augmented_config']}`)")
    lines += reference_lines(summary)
    lines += ["", "## Which effect", ""]
    lines += _effects_table(summary) if summary["effects"] else ["No term selected."]
    for amb in summary.get("ambiguities", []):
        lines += ["", f"**{'Evidence' if amb['separated'] else 'Ambiguous'}:** "
                  f"{amb['statement']}."]
    if summary.get("rejected_effects"):
        lines += ["", "Selected on the fit part but not adopted (no better on the held-out "
                  "part): " + ", ".join(f"`{e['name']}`" for e in summary["rejected_effects"])
                  + "."]
    if a.untested:
        lines += ["", "Not tested on this recording:", ""]
        lines += [f"- `{k}`: {v}" for k, v in a.untested.items()]
    lines += physical.report_lines(a, summary)        # the model's own parameters
    lines += ["", "Selection (best subset per size, fit part):", ""] + _trace_table(a.trace)
    lines += ["", "## Where the model disagreed (all samples, before)", ""]
    flagged = [r for r in a.regions_before if r["significant"]]
    lines += _regime_rows(flagged) if flagged else ["No regime deviates significantly from "
                                                    "the noise."]
    remaining = [r for r in a.regions_after if r["significant"]]
    lines += ["", "### Still significant after adding the terms", ""]
    lines += _regime_rows(remaining) if remaining else ["None."]
    lines += ["", "## Held-out part, per regime", ""] + _holdout_table(a)
    if validation is not None:
        v = summary["validation"]
        lines += ["", "## Validation on a second recording (no refit)", "",
                  f"Input: `{v['input']}` (baseline {v.get('baseline', '?')}), {v['n']} "
                  "samples; the written terms (refitted on all usable samples of the fit "
                  "recording), unchanged; rows in `validation/prediction.csv`.", "",
                  "| | RMSE [N m] | relative error ‖meas − pred‖ / ‖meas‖ |", "|---|---|---|",
                  f"| model | {_f(v['rmse_before_nm'])} | {_f(v['relative_error_before'], 3)} |",
                  f"| model + terms | {_f(v['rmse_after_nm'])} | "
                  f"{_f(v['relative_error_after'], 3)} |",
                  f"| rigid-body reference (least squares on the same samples) | "
                  f"{_f(v.get('reference_rmse_nm'))} | "
                  f"{_f(v.get('reference_relative_error'), 3)} |"]
    if plots:
        plot_all(out, a)
        figures = list(FIGURES)
        if validation is not None:
            plot_validation(out, validation)
            figures.append(VALIDATION_FIGURE)
        if physical.chosen(a.physical):
            figures.append(physical.plot_b2b_share(out, a))
        lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def acceleration_sentence(acc):
    """Return the report's sentence on the acceleration cut-off: value, how chosen, lag."""
    text = acc.get("source", "?")
    if "cutoff_hz" not in acc:
        return text
    text += (f"; cut-off {_f(acc['cutoff_hz'], 3)} Hz, chosen by {acc.get('chosen_by', '?')}")
    cands = acc.get("candidates") or []
    if cands:
        text += (" over " + ", ".join(f"{_f(c['cutoff_hz'], 3)}" for c in cands) + " Hz "
                 "(cross-validated RMSE " + ", ".join(_f(c["cv_rmse_nm"], 4) for c in cands)
                 + " N m; without acceleration "
                 f"{_f(acc.get('no_acceleration_cv_rmse_nm'), 4)} N m)")
    if acc.get("inertia_identifiable") is False:
        text += f". **Inertia cannot be identified here:** {acc.get('inertia_reason')}"
    elif acc.get("bandwidth_limited"):
        text += f". **Bandwidth-limited:** {acc.get('statement')}"
    text += (f"; segments split at gaps > {_f(acc['max_gap_s'], 3)} s; the live node's and "
             f"replay's causal filter at this cut-off lags by {_f(acc['live_lag_s'] * 1e3, 3)}"
             " ms")
    return text


def reference_lines(summary):
    """Return the report lines of the rigid-body reference and of which fit gives what."""
    h = summary.get("heldout")
    if not h:
        return []
    refit = summary.get("refit") or {}
    out = ["", "| held-out part | RMSE [N m] | relative error |", "|---|---|---|",
           f"| model | {_f(h['rmse_before_nm'])} | {_f(h['relative_error_before'], 3)} |",
           f"| model + terms (fitted on the fit part) | {_f(h['rmse_after_nm'])} | "
           f"{_f(h['relative_error_after'], 3)} |",
           f"| rigid-body reference (least squares on the fit part, same alpha) | "
           f"{_f(h['reference_rmse_nm'])} | {_f(h['reference_relative_error'], 3)} |", ""]
    if refit.get("refitted"):
        out.append(f"The held-out figures come from the terms fitted on the fit part; "
                   f"`augmented.yaml`, the validation and the node use the same terms "
                   f"refitted on all {refit['samples']} usable samples.")
    elif refit:
        out.append(f"The written terms are the fit part's: {refit.get('reason')}.")
    return out


def write_insufficient_report(out, summary):
    """Write ``report.md`` stating what the recording lacks."""
    info = summary.get("input", {})
    lines = ["# Discrepancy report", "",
             "**Verdict: none — the recording cannot tell.** Nothing was fitted, because:", ""]
    lines += [f"- {m}" for m in summary["missing"]]
    lines += ["", f"Input: `{info.get('input', '?')}`.", "",
              "Record both directions of motion at several speeds (e.g. slow, medium, fast), "
              "ideally with a varying axial load and over several nut revolutions."]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def _panels(fig_axes, x, residuals, labels, colors, bins=None, rows=None):
    """Scatter each residual against speed, angle, load and time."""
    variables = (("speed", x.nut_velocity_rad_s, "nut speed [rad/s]"),
                 ("angle", np.degrees(np.mod(x.nut_angle_rad, 2 * math.pi)),
                  "nut angle within a revolution [deg]"),
                 ("load", x.axial_load_n, "axial load [N]"),
                 ("time", x.t_s, "time [s]"),
                 ("acceleration", x.nut_accel_rad_s2 if x.nut_accel_rad_s2 is not None
                  else np.zeros_like(x.t_s), "nut acceleration [rad/s^2]"),
                 ("stroke", x.nut_angle_rad / (2 * math.pi), "nut travel [rev]"))
    pick = np.unique(np.linspace(0, x.t_s.size - 1, min(x.t_s.size, MAX_SCATTER_POINTS))
                     .astype(int))
    for ax, (var, values, label) in zip(fig_axes, variables):
        for r, lab, col in zip(residuals, labels, colors):
            ax.plot(values[pick], r[pick], ".", ms=2, color=col, alpha=0.5, label=lab)
        if bins is not None:
            _bin_means(ax, var, bins, rows)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel(label)
        ax.set_ylabel("residual [N m]")
        ax.grid(True)
    fig_axes[0].legend(fontsize=8, markerscale=4)


def _bin_means(ax, var, bins, rows):
    for b, row in zip(bins, rows):
        if b.variable != var or row["n"] == 0:
            continue
        lo, hi = b.lo, b.hi
        if var == "speed":
            lo, hi = (lo, hi) if b.direction > 0 else (-hi, -lo)
        if var == "angle":
            lo, hi = math.degrees(lo), math.degrees(hi)
        if var == "stroke":
            lo, hi = lo / (2 * math.pi), hi / (2 * math.pi)
        value = row["mean_residual_nm"]
        ax.plot([lo, hi], [value, value], lw=2.5,
                color="C3" if row["significant"] else "k")


def _layout(fig):
    # fixed margins: tight_layout measures every label and takes seconds on a loaded machine
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.08, top=0.92, wspace=0.28,
                        hspace=0.32)


def plot_all(out, a):
    """Write the three figures of the report."""
    from matplotlib.figure import Figure
    x = inputs_of(a.recording)
    fig = Figure(figsize=(15, 7))
    axes = fig.subplots(2, 3)
    _panels(axes.ravel(), x, [a.residual_nm], ["residual (measured - predicted)"], ["0.5"],
            a.bins, a.regions_before)
    fig.suptitle("Where: residual before (bars: regime means, red = significant)")
    _layout(fig)
    fig.savefig(out / FIGURES[0], dpi=100)

    hold = ~a.fit_mask
    xh = inputs_of(a.recording, hold)
    fig = Figure(figsize=(15, 7))
    axes = fig.subplots(2, 3)
    _panels(axes.ravel(), xh, [a.residual_nm[hold], (a.residual_nm - a.added_nm)[hold]],
            ["before", "after (with the selected terms)"], ["0.6", "C0"])
    fig.suptitle(f"Held-out part: RMSE {a.rmse_before_nm:.4g} -> {a.rmse_after_nm:.4g} N m")
    _layout(fig)
    fig.savefig(out / FIGURES[1], dpi=100)

    rec = a.recording
    t = rec.t_s - rec.t_s[0]
    fig = Figure(figsize=(11, 7))
    axes = fig.subplots(2, 1, sharex=True)
    axes[0].plot(t, rec.torque_meas_nm, lw=0.6, color="0.5", label="measured")
    axes[0].plot(t, rec.torque_pred_nm, lw=0.9, label="model")
    axes[0].plot(t, rec.torque_pred_nm + a.added_nm, lw=0.9, label="model + empirical terms")
    axes[0].set_ylabel("friction torque [N m]")
    axes[1].plot(t, a.residual_nm, lw=0.6, color="0.5", label="residual before")
    axes[1].plot(t, a.residual_nm - a.added_nm, lw=0.6, color="C0", label="residual after")
    axes[1].set_ylabel("residual [N m]")
    axes[1].set_xlabel("time [s]")
    split = t[int(a.fit_mask.sum())] if (~a.fit_mask).any() else t[-1]
    for ax in axes:
        ax.axvline(split, color="C3", ls="--", lw=1.0)
        ax.grid(True)
        ax.legend(fontsize=8, loc="upper right")
    axes[0].set_title("fit part | held-out part (right of the dashed line)")
    _layout(fig)
    fig.savefig(out / FIGURES[2], dpi=100)


def plot_validation(out, v):
    """Write ``validation.png``: measured, model and model + terms on the second recording."""
    from matplotlib.figure import Figure
    rec = v.recording
    t = rec.t_s - rec.t_s[0]
    fig = Figure(figsize=(11, 7))
    axes = fig.subplots(2, 1, sharex=True)
    axes[0].plot(t, rec.torque_meas_nm, lw=0.6, color="0.5", label="measured")
    axes[0].plot(t, rec.torque_pred_nm, lw=0.9, label="model")
    axes[0].plot(t, rec.torque_pred_nm + v.added_nm, lw=0.9, label="model + terms (no refit)")
    axes[0].set_ylabel("torque [N m]")
    axes[1].plot(t, rec.torque_meas_nm - rec.torque_pred_nm, lw=0.6, color="0.5",
                 label="residual before")
    axes[1].plot(t, rec.torque_meas_nm - rec.torque_pred_nm - v.added_nm, lw=0.6, color="C0",
                 label="residual after")
    s = v.summary
    if v.reference_nm is not None:
        axes[0].plot(t, rec.torque_pred_nm + v.reference_nm, lw=0.8, ls="--", color="C3",
                     label="model + rigid-body reference")
        axes[1].plot(t, rec.torque_meas_nm - rec.torque_pred_nm - v.reference_nm, lw=0.6,
                     color="C3", alpha=0.7, label="residual, reference")
    axes[1].set_ylabel("residual [N m]")
    axes[1].set_xlabel("time [s]")
    axes[0].set_title(f"validation: relative error {s['relative_error_after']:.3g} (terms) vs "
                      f"{s['reference_relative_error']:.3g} (rigid-body reference); RMSE "
                      f"{s['rmse_before_nm']:.4g} -> {s['rmse_after_nm']:.4g} N m")
    for ax in axes:
        ax.grid(True)
        ax.legend(fontsize=8, loc="upper right")
    _layout(fig)
    fig.savefig(out / VALIDATION_FIGURE, dpi=100)
