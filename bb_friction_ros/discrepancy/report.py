"""
``report.md`` and its PNGs for the discrepancy workflow.

Figures: ``residual_where.png`` (the residual against nut speed, angle within a revolution,
axial load and time, with the regime means; significant regimes in red),
``heldout_before_after.png`` (the same on the held-out part, before and after the selected
terms) and ``time_series.png`` (measured, predicted and augmented torque over time).
"""

import math

import numpy as np

from bb_friction_ros.discrepancy.data import inputs_of
from bb_friction_ros.empirical_terms import LIBRARY

FIGURES = ("residual_where.png", "heldout_before_after.png", "time_series.png")


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
        out.append(f"| `{e['name']}` | {LIBRARY[e['name']].meaning} | {params} |")
    return out


def _trace_table(trace):
    out = ["| terms | BIC | BIC + threshold x terms | cross-validated RMSE [N m] | chosen |",
           "|---|---|---|---|---|"]
    for t in trace:
        out.append(f"| {', '.join(t['terms']) or '(none)'} | {t['bic']:.1f} | "
                   f"{t['penalised_bic']:.1f} | {_f(t['cv_rmse_nm'])} | "
                   f"{'yes' if t['chosen'] else ''} |")
    return out


def write_report(out, a, summary, plots=True):
    """Write ``report.md`` (and the PNGs unless ``plots`` is false) into ``out``."""
    info = summary.get("input", {})
    s = summary["samples"]
    lines = [
        "# Discrepancy report", "",
        f"**Verdict: {summary['verdict']}.** {summary['reason']}.", "",
        f"- input: `{info.get('input', '?')}` ({info.get('format', '?')}); prediction: "
        f"{info.get('prediction_source', '?')}",
        f"- samples: {s['usable']} usable ({s['fit']} fit, first part; {s['holdout']} held "
        f"out, last part); dropped: {s['dropped']}",
        f"- noise level estimated from the residual (MAD of first differences): "
        f"{_f(summary['noise_std_nm'])} N m",
        f"- held-out RMSE: before {_f(summary['rmse_before_nm'])} N m, after "
        f"{_f(summary['rmse_after_nm'])} N m",
    ]
    if summary.get("reducible_removed_fraction") is not None:
        lines.append(f"- share of the reducible held-out RMSE (RMSE before - noise) removed: "
                     f"{summary['reducible_removed_fraction']:.0%}")
    if "augmented_config" in summary:
        lines.append(f"- augmented config: `{summary['augmented_config']}` (replay with "
                     f"`bb-friction replay BAG --config {summary['augmented_config']}`)")
    lines += ["", "## Which effect", ""]
    lines += _effects_table(summary) if summary["effects"] else ["No term selected."]
    if a.untested:
        lines += ["", "Not tested on this recording:", ""]
        lines += [f"- `{k}`: {v}" for k, v in a.untested.items()]
    lines += ["", "Selection (best subset per size, fit part):", ""] + _trace_table(a.trace)
    lines += ["", "## Where the model disagreed (all samples, before)", ""]
    flagged = [r for r in a.regions_before if r["significant"]]
    lines += _regime_rows(flagged) if flagged else ["No regime deviates significantly from "
                                                    "the noise."]
    remaining = [r for r in a.regions_after if r["significant"]]
    lines += ["", "### Still significant after adding the terms", ""]
    lines += _regime_rows(remaining) if remaining else ["None."]
    lines += ["", "## Held-out part, per regime", ""] + _holdout_table(a)
    if plots:
        plot_all(out, a)
        lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in FIGURES]
    (out / "report.md").write_text("\n".join(lines) + "\n")


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
                 ("time", x.t_s, "time [s]"))
    for ax, (var, values, label) in zip(fig_axes, variables):
        for r, lab, col in zip(residuals, labels, colors):
            ax.plot(values, r, ".", ms=2, color=col, alpha=0.5, label=lab)
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
        value = row["mean_residual_nm"]
        ax.plot([lo, hi], [value, value], lw=2.5,
                color="C3" if row["significant"] else "k")


def plot_all(out, a):
    """Write the three figures of the report."""
    from matplotlib.figure import Figure
    x = inputs_of(a.recording)
    fig = Figure(figsize=(11, 7))
    axes = fig.subplots(2, 2)
    _panels(axes.ravel(), x, [a.residual_nm], ["residual (measured - predicted)"], ["0.5"],
            a.bins, a.regions_before)
    fig.suptitle("Where: residual before (bars: regime means, red = significant)")
    fig.tight_layout()
    fig.savefig(out / FIGURES[0], dpi=100)

    hold = ~a.fit_mask
    xh = inputs_of(a.recording, hold)
    fig = Figure(figsize=(11, 7))
    axes = fig.subplots(2, 2)
    _panels(axes.ravel(), xh, [a.residual_nm[hold], (a.residual_nm - a.added_nm)[hold]],
            ["before", "after (with the selected terms)"], ["0.6", "C0"])
    fig.suptitle(f"Held-out part: RMSE {a.rmse_before_nm:.4g} -> {a.rmse_after_nm:.4g} N m")
    fig.tight_layout()
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
    fig.tight_layout()
    fig.savefig(out / FIGURES[2], dpi=100)
