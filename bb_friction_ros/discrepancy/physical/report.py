"""The physical choice in the outputs: the calibrated config, summary.json, report, plot."""

import math

import numpy as np

from bb_friction_ros.config import EDGE_UNITS, si_key
from bb_friction_ros.discrepancy.physical.trials import chosen, PHYSICAL
from bb_friction_ros.empirical_terms import LIBRARY


def calibrated_section(section, search):
    """
    Return the ``ball_screw:`` mapping ``section`` with the chosen physical value set.

    The value is written in its edge unit (``theta_amplitude_deg``, ``ball_oversize_um``);
    a key of the same field in another unit (``theta_amplitude_rad``) is removed, so the file
    holds the value once.
    """
    choice = chosen(search)
    if choice is None:
        return section
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in section.items()}
    sub = out.setdefault(choice.kind.section, {})
    target = si_key(choice.kind.param, {_si_name(choice.kind.param)})
    for key in list(sub):
        if si_key(key, {target[0]}) is not None:
            del sub[key]
    sub[choice.kind.param] = float(choice.value)
    return out


def _si_name(param):
    for edge, si, _ in EDGE_UNITS:
        if param.endswith(edge):
            return param[: -len(edge)] + si
    return param


def effects(search, terms):
    """Return summary.json → ``effects``: the physical effect (if any), then the terms."""
    out = [chosen(search).effect()] if chosen(search) else []
    return out + [dict(e, kind="empirical") for e in terms.effects()]


def summary(search):
    """Return summary.json → ``physical`` (None without physical candidates)."""
    if search is None:
        return None
    out = search.as_dict()
    if search.rejected is not None:
        out["rejected"] = search.rejected.effect()
    if search.validation_runs:
        out["validation_model_runs"] = search.validation_runs
        out["validation_model_run_wall_s"] = search.validation_wall_s
    return out


def names(search, terms):
    """Return the names of the chosen effects: the physical one first, then the terms."""
    return ((chosen(search).kind.name,) if chosen(search) else ()) + tuple(terms.names)


# ------------------------------------------------------------------------------------------
# report.md and its figure

B2B_FIGURE = "b2b_share.png"
# Samples whose calibrated model torque is below this fraction of its median magnitude are
# left out of the B2B share: near a reversal or at standstill the share is 0/0.
SHARE_MIN_TORQUE_FRACTION = 0.05


def meaning(effect):
    """Return the report's meaning of an effect of summary.json (physical or a term)."""
    if effect.get("kind") == "physical":
        return PHYSICAL[effect["name"]].meaning
    return LIBRARY[effect["name"]].meaning


def b2b_share(run, usable):
    """
    Return (share of B2B friction in the model torque per usable sample, B2B added).

    B2B added = sum |T_b2b| / sum |T - T_b2b| over the usable samples: how much the B2B
    friction adds to the ball-groove friction of this recording.  The share is NaN where the
    torque is too small for a ratio (``SHARE_MIN_TORQUE_FRACTION``).
    """
    total, b2b = run.total_nm[usable], run.b2b_nm[usable]
    mag = np.abs(total)
    ok = mag > SHARE_MIN_TORQUE_FRACTION * float(np.nanmedian(mag))
    share = np.full(total.size, np.nan)
    share[ok] = b2b[ok] / total[ok]
    groove = float(np.nansum(np.abs(total - b2b)))
    return share, (float(np.nansum(np.abs(b2b))) / groove if groove > 0 else math.nan)


def _explained(a, delta, part=None):
    """Share of the residual's mean square removed by the physical change alone."""
    sel = slice(None) if part is None else part
    r = a.residual_nm[sel]
    ms = float(np.mean(r ** 2))
    return 1.0 - float(np.mean((r - delta[sel]) ** 2)) / ms if ms > 0 else math.nan


def _g(v, digits=3):
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def statement(a):
    """Return the report's sentence on the chosen physical effect ("" when none)."""
    choice = chosen(a.physical)
    if choice is None:
        return ""
    lo, hi = choice.interval_95
    u = _unit(choice)
    ci = f"95 %: {_g(lo)}–{_g(hi)}{u}" if lo is not None else \
        "95 % interval not bracketed by the trials"
    paren = f" ({ci}; the config says {_g(choice.base_value)}{u})"
    explained = _explained(a, choice.delta_nm)
    explained_hold = _explained(a, choice.delta_nm, ~a.fit_mask)
    _, added = b2b_share(choice.run, a.physical.usable)
    _, added_base = b2b_share(a.physical.base, a.physical.usable)
    value = f"{_g(choice.value)}{u}"
    what = {"contact_angle_deviation": "Ball-to-ball contact from a contact-angle deviation "
                                       f"of about {value}",
            "friction_coefficient": f"A friction coefficient of about {value}",
            "preload": f"A preload of about {value} ball oversize"}[choice.kind.name]
    return (f"{what}{paren} explains {explained:.0%} of the residual ({explained_hold:.0%} "
            "of the held-out part's, where it was not fitted); B2B friction "
            f"adds {added:.0%} to the friction torque of this recording (with the config's "
            f"value: {added_base:.0%}).")


def _unit(choice):
    return {"deg": "°", "um": " µm"}.get(choice.kind.unit, "")


def report_lines(a, summary):
    """Return the report's section on the physical candidates ([] when none were tried)."""
    p = summary.get("physical")
    if not p:
        return []
    lines = ["", "## The model's own parameters (physical candidates)", ""]
    text = statement(a)
    lines += [f"**{text}**" if text else
              "No physical parameter of the model explains the residual better than the "
              "empirical terms (or nothing): the config's contact-angle deviation, friction "
              "coefficient and preload stand.", ""]
    lines += [f"Note: {n}." for n in p.get("notes", [])]
    if p.get("rejected"):
        lines += [f"`{p['rejected']['name']}` was chosen on the fit part but does not improve "
                  "the held-out part, so it is not adopted.", ""]
    base = "the config's values kept from the prediction's own run, not run again; " if \
        p.get("base_run_kept") else "the config's values, "
    lines += [f"Cost: {p['model_runs']} model runs over the recording ({base}"
              f"a bracket per candidate, the refinement; {p.get('coarse_runs', 0)} of them "
              f"{p.get('coarse_step_factor', 1)}x coarser: the smooth candidates' search) in "
              f"{p['model_run_wall_s']:.1f} s on {p['workers']} worker(s), "
              f"{p.get('threads', 1)} thread(s); penalised BIC of the empirical terms alone: "
              f"{p['penalised_bic_none']:.1f}.", "",
              "Each trial is scored with the empirical terms held (its profile); where "
              "marked *, the empirical selection was re-run at that value.", "",
              "| candidate | value | model step | penalised BIC (1 parameter counted) | "
              "terms on top |",
              "|---|---|---|---|---|"]
    for t in p["trials"]:
        bic = "-" if t["penalised_bic"] is None else f"{t['penalised_bic']:.1f}"
        terms = t.get("note") or (", ".join(t["terms"]) or "(none)") + \
            (" *" if t.get("selection") else "")
        step = "coarse" if t.get("coarse") else "replay" + (" (again)" if t.get("rerun") else "")
        lines.append(f"| `{t['candidate']}` | {t['param']} = {t['value']:.4g} | {step} | {bic} "
                     f"| {terms} |")
    return lines


def plot_b2b_share(out, a):
    """Write ``b2b_share.png``: the B2B share of the calibrated model over the recording."""
    from matplotlib.figure import Figure
    choice = chosen(a.physical)
    ok = a.physical.usable
    t = a.recording.t_s
    share, added = b2b_share(choice.run, ok)
    base_share, base_added = b2b_share(a.physical.base, ok)
    fig = Figure(figsize=(10, 6))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(t, choice.run.total_nm[ok], lw=0.7, label="model torque, calibrated")
    ax1.plot(t, choice.run.b2b_nm[ok], lw=0.7, label="its B2B part")
    ax1.plot(t, a.physical.base.total_nm[ok], lw=0.5, alpha=0.6, label="model, config values")
    ax1.set_ylabel("torque [N m]")
    ax1.legend(loc="upper right", fontsize=8)
    ax2.plot(t, 100.0 * share, lw=0.7,
             label=f"calibrated ({choice.kind.param} = {choice.value:.3g}): B2B adds "
                   f"{added:.0%}")
    ax2.plot(t, 100.0 * base_share, lw=0.7,
             label=f"config ({choice.base_value:.3g}): B2B adds {base_added:.0%}")
    ax2.set_ylabel("B2B share of the torque [%]")
    ax2.set_xlabel("time [s]")
    ax2.legend(loc="upper right", fontsize=8)
    fig.suptitle("Ball-to-ball friction over the recording")
    fig.tight_layout()
    fig.savefig(out / B2B_FIGURE, dpi=100)
    return B2B_FIGURE
