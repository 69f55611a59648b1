"""
The servo test's outputs: ``modes/<mode>.csv``, ``summary.json``, plots and ``report.md``.

``modes/<mode>.csv`` columns: ``t_s`` (from the recording's first row),
``nut_angle_ref_rad``, ``nut_angle_rad`` (the simulated axis), ``torque_command_nm`` (the
controller's output after the limit, command offset included), ``torque_friction_nm`` (the
plant's friction; the held torque at rest), then ``nut_angle_measured_rad`` (the encoder),
``nut_velocity_rad_s``, ``torque_feedforward_nm`` and ``following_error_um``.  A circle's Y
axis follows with the same names prefixed ``y_``, and ``radial_deviation_um``.
"""

import json
import math

import numpy as np

from bb_friction_ros.servo.metrics import circle_path, to_um

CSV_COLUMNS = ("t_s", "nut_angle_ref_rad", "nut_angle_rad", "torque_command_nm",
               "torque_friction_nm", "nut_angle_measured_rad", "nut_velocity_rad_s",
               "torque_feedforward_nm", "following_error_um")
# The ballbar plot's scale per division [um]: the smallest of these that puts the largest
# radial deviation within two divisions of the nominal circle (ballbar software's steps).
BALLBAR_DIVISIONS_UM = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0)


def _axis_columns(run, lead_m):
    return [run.t_s, run.ref_rad, run.angle_rad, run.command_nm, run.friction_nm,
            run.measured_rad, run.velocity_rad_s, run.feedforward_nm,
            to_um(run.ref_rad - run.angle_rad, lead_m)]


def write_mode_csv(path, reference, runs, lead_m):
    """Write ``modes/<mode>.csv`` of one mode (module docstring)."""
    names = list(CSV_COLUMNS)
    cols = _axis_columns(runs[0], reference.leads_m[0] if reference.leads_m else lead_m)
    if reference.kind == "circle":
        names += ["y_" + c for c in CSV_COLUMNS[1:]]
        cols += _axis_columns(runs[1], reference.leads_m[1])[1:]
        x, y, _, _ = circle_path(reference.t_s, runs, reference.leads_m)
        names.append("radial_deviation_um")
        cols.append((np.hypot(x, y) - reference.radius_m) * 1e6)
    data = np.column_stack(cols)
    with open(path, "w") as fh:
        fh.write(",".join(names) + "\n")
        for row in data:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")


def _json_ready(value):
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (np.floating, np.integer)):
        return _json_ready(value.item())
    return value


def write_summary(path, summary):
    """Write summary.json (NaN and inf as null)."""
    path.write_text(json.dumps(_json_ready(summary), indent=2, allow_nan=False) + "\n")


def _fmt(v, digits=3):
    if v is None:
        return "-"
    return f"{v:.{digits}g}"


PRODUCT = ("model", "model_commanded", "node", "planned", "node_planned")
BASELINES = ("coulomb_viscous", "coulomb_viscous_commanded", "lugre", "lugre_commanded")


def verdict(summary):
    """Return the one-sentence verdict: the product beside the best baseline (by RMS)."""
    m = summary["modes"]

    def best(names):
        have = [(m[n]["following_error_rms_um"], n) for n in names if n in m]
        return min(have) if have else None

    prod, base = best(PRODUCT), best(BASELINES)
    none = m["none"]["following_error_rms_um"]
    if prod is None or base is None:
        only = prod or base
        if only is None:
            return (f"Only the loop without friction feedforward was run: following error "
                    f"RMS {none:.3g} um.")
        return (f"{only[1]} gives a following error RMS of {only[0]:.3g} um against "
                f"{none:.3g} um without friction feedforward.")
    if prod[0] < base[0]:
        word = "beats"
    elif prod[0] > base[0]:
        word = "loses to"
    else:
        word = "ties with"
    return (f"The product's feedforward ({prod[1]}, following error RMS {prod[0]:.3g} um) "
            f"{word} the best baseline a user has ({base[1]}, {base[0]:.3g} um); without "
            f"friction feedforward {none:.3g} um.")


def write_report(path, summary):
    """Write report.md: the table of modes, the measured-loop check, the verdict."""
    lines = ["# Servo test", "", f"Reference: {summary['reference']['source']} "
             f"({summary['reference']['kind']}, {summary['reference']['duration_s']:.3g} s at "
             f"{summary['loop']['rate_hz']:g} Hz).  Plant: {summary['plant']['model_file']}; "
             f"feedforward model: {summary['model_file']}.", "",
             "**Verdict:** " + summary["verdict"], ""]
    if not summary.get("safety_gate", True):
        lines += ["**A study without the safety gate** (`--no-safety-gate`): feedforwards "
                  "against their own motion were fed as computed (counted under wrong-sign); "
                  "no controller should run them.", ""]
    lines += ["| mode | timing | following error RMS [um] | max [um] | reversal glitch max "
              "[um] | cruise RMS [um] | circle radial range [um] | wrong-sign "
              + ("zeroed |" if summary.get("safety_gate", True) else "fed |"),
              "|---|---|---|---|---|---|---|---|"]
    for name, v in summary["modes"].items():
        circle = v.get("circle", {}).get("radial_deviation_range_um")
        lines.append(f"| {name} | {v['timing']} | {_fmt(v['following_error_rms_um'])} | "
                     f"{_fmt(v['following_error_max_um'])} | "
                     f"{_fmt(v.get('reversal_glitch_max_um'))} | {_fmt(v.get('cruise_rms_um'))}"
                     f" | {_fmt(circle)} | {v['counters']['feedforward_wrong_sign']} |")
    ml = summary.get("measured_loop")
    if ml:
        lines += ["", "## The loop as recorded", "",
                  "Relative errors ||sim - meas|| / ||meas|| of the `none` run against the "
                  "recording (angle from its first sample), and of the same simulation with "
                  "the rigid-body model (J alpha + c omega + T_c sign(omega) + T_0) fitted by "
                  "least squares on the calibration recording.", "",
                  "| plant | angle | velocity | torque command | of it: moving | standing |",
                  "|---|---|---|---|---|---|"]
        for key, label in (("none", "the model file"), ("rigid_body", "rigid-body reference")):
            r = ml.get(key)
            if r:
                phase = r.get("torque_by_phase") or {}
                lines.append(f"| {label} | {_fmt(r['angle'])} | {_fmt(r['velocity'])} | "
                             f"{_fmt(r['torque'])} | {_fmt(phase.get('moving'))} | "
                             f"{_fmt(phase.get('standing'))} |")
        lines += ["", f"Rigid-body reference: {ml['rigid_body_source']}."]
        if ml.get("rigid_body"):
            better = ml["none_torque_error_at_most_rigid_body"]
            lines.append("The model file's torque error is "
                         + ("at most the rigid-body reference's." if better else
                            "ABOVE the rigid-body reference's: the simulation is not yet "
                            "to be trusted on this axis."))
    fits = summary.get("baselines", {})
    if fits:
        lines += ["", "## Baselines", "", f"Fitted on: {summary.get('calibration_source')}.", ""]
        for name, values in fits.items():
            text = ", ".join(f"{k} = {_fmt(v, 4) if isinstance(v, float) else v}"
                             for k, v in values.items() if k != "note")
            lines.append(f"- {name}: {text}")
            if values.get("note"):
                lines.append(f"  - {values['note']}")
    lines += ["", "Figures: following_error.png, reversals.png"
              + (", ballbar.png" if summary["reference"]["kind"] == "circle" else "") + ".",
              ""]
    path.write_text("\n".join(lines))


def write_plots(out, reference, results, lead_m):
    """Write following_error.png, reversals.png and (circle) ballbar.png."""
    from matplotlib.figure import Figure     # the caller's backend and pyplot stay untouched
    from bb_friction_ros.servo.metrics import reversal_indices, REVERSAL_WINDOW_S
    t = reference.t_s
    leads = reference.leads_m or (lead_m,)
    fig = Figure(figsize=(10, 3.2 * len(reference.axes)))
    axes = fig.subplots(len(reference.axes), 1, squeeze=False, sharex=True)
    for i, axis in enumerate(reference.axes):
        ax = axes[i][0]
        for name, runs in results.items():
            ax.plot(t, to_um(runs[i].ref_rad - runs[i].angle_rad, leads[i]), lw=0.8,
                    label=name)
        ax.set_ylabel(f"{axis.name}: following error [um]")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, ncol=4)
    axes[-1][0].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "following_error.png", dpi=110)
    runs0 = next(iter(results.values()))[0]
    rev = reversal_indices(np.gradient(runs0.ref_rad, t))[:4]
    if rev.size:
        fig = Figure(figsize=(3.2 * rev.size, 3.2))
        axes = fig.subplots(1, rev.size, squeeze=False)
        for j, i in enumerate(rev):
            ax = axes[0][j]
            w = (t >= t[i] - 0.2 * REVERSAL_WINDOW_S) & (t <= t[i] + 2 * REVERSAL_WINDOW_S)
            for name, runs in results.items():
                ax.plot((t[w] - t[i]) * 1e3, to_um(runs[0].ref_rad[w] - runs[0].angle_rad[w],
                                                   leads[0]), lw=0.9, label=name)
            ax.set_title(f"reversal at {t[i]:.3f} s", fontsize=9)
            ax.set_xlabel("t - t_reversal [ms]")
            ax.grid(alpha=0.3)
        axes[0][0].set_ylabel("following error [um]")
        axes[0][0].legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(out / "reversals.png", dpi=110)
    if reference.kind == "circle":
        ballbar_plot(out / "ballbar.png", reference, results)


def ballbar_division_um(largest_um):
    """Return the plot's micrometres per division for a largest |radial deviation| [um]."""
    for d in BALLBAR_DIVISIONS_UM:
        if largest_um <= 2.0 * d:
            return d
    return BALLBAR_DIVISIONS_UM[-1]


def ballbar_plot(path, reference, results):
    """
    Draw the circle test as ballbar software does: the radial deviation magnified.

    The nominal circle is the middle ring; each ring out (in) is one division more (less)
    radius, the division chosen by ``ballbar_division_um``; beyond two divisions the path is
    drawn at the plot's edge.
    """
    from matplotlib.figure import Figure     # the caller's backend and pyplot stay untouched
    from bb_friction_ros.servo.metrics import feed_mask
    t = reference.t_s
    paths = {}
    for name, runs in results.items():
        x, y, xr, yr = circle_path(t, runs, reference.leads_m)
        feed = feed_mask(t, xr, yr)
        paths[name] = (np.arctan2(y[feed], x[feed]),
                       (np.hypot(x[feed], y[feed]) - reference.radius_m) * 1e6)
    div = ballbar_division_um(max(float(np.abs(dr).max()) for _, dr in paths.values()))
    fig = Figure(figsize=(6.5, 6.8))
    ax = fig.add_subplot(projection="polar")
    for name, (theta, dr) in paths.items():
        ax.plot(theta, np.clip(2.0 + dr / div, 0.0, 4.0), lw=0.9, label=name)
    ring = np.linspace(0, 2 * np.pi, 361)
    ax.plot(ring, np.full_like(ring, 2.0), color="k", lw=0.6)
    ax.set_rmin(0.0)
    ax.set_rmax(4.0)
    ax.set_rticks([0.0, 1.0, 2.0, 3.0, 4.0])
    ax.set_yticklabels([f"{(k - 2) * div:+g}" for k in range(5)], fontsize=7)
    ax.set_title(f"ISO 230-4 circle, r = {reference.radius_m * 1e3:g} mm: radial deviation, "
                 f"{div:g} um per division", fontsize=9)
    ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
