"""
Identifiability of a physical choice: its twin among the empirical terms, said out loud.

A change of mu scales the whole model torque, which is nearly the ``load_dependent`` column
(k |W| sign w) when the torque is nearly proportional to the load; an angle ripple can mimic
part of a B2B signature.  After the choice the twin is swapped in and refitted; a BIC
difference below ``bic_threshold`` names the pair as one ambiguous effect.  A tie with the
twin on the fit part is decided on the whole recording (``_heldout_gap``).
"""

import math

import numpy as np

from bb_friction_ros.discrepancy.data import inputs_of
from bb_friction_ros.discrepancy.physical.trials import PHYSICAL, TWINS
from bb_friction_ros.discrepancy.selection import candidates, fit, swap_evidence


def _heldout_gap(o, none, rec_all, ok, fit_mask, r, tau):
    """
    Return the held-out part's evidence for "none" against the physical outcome ``o``.

    Both readings as fitted on the fit part (``o``: its change d(p) and its terms; "none":
    its terms, the twin among them) predict the held-out part, and the gap is
    n'_h ln(RSS_h(o) / RSS_h(none)), n'_h = n_h / tau: the held-out part's -2 ln of the
    likelihood ratio, in the units of the penalised BIC (both readings pay the same price,
    so the prices cancel).  Positive: "none" predicts the held-out part better.  The noise
    of the two parts is independent, so this evidence adds to the fit part's gap.  A tie
    (``_tie``) is the fit part's statement that it cannot choose between the parameter and
    its twin; the held-out part, which the choice between the two has not seen, holds more
    evidence on the same question (the 30 % of samples the selection left out).
    """
    hold = ~fit_mask
    if not hold.any():
        return 0.0
    x = inputs_of(rec_all, np.flatnonzero(ok)[hold])
    r_hold = r[hold]
    d_hold = np.nan_to_num(o.run.delta_nm[ok])[hold]

    def rss(e):
        return max(float(e @ e), 1e-300)

    args = (x.t_s, x.nut_angle_rad, x.nut_velocity_rad_s, x.axial_load_n, x.nut_accel_rad_s2)
    e_o = r_hold - d_hold - (o.terms.torque_nm(*args) if len(o.terms) else 0.0)
    e_none = r_hold - (none.terms.torque_nm(*args) if len(none.terms) else 0.0)
    return r_hold.size / max(tau, 1.0) * math.log(rss(e_o) / rss(e_none))


def _cv_judges(o, none, ties):
    """
    Tell whether the blocked cross-validation may veto the physical outcome ``o``.

    The empirical selection (``selection.select``) lets cross-validation veto only the
    larger model against the next smaller choice: a smaller model that wins in penalised
    BIC is never vetoed by a larger one's folds.  The same rule here, with the terms counted
    as the selection counts sizes and the physical parameter counted as one term (as
    ``_penalised`` charges it one term's price): a reading with fewer terms than the "none"
    it beats is not judged against it.  Bench seed 14: mu 0.07842 alone (the truth to
    0.01 %) beat seal_drag + load_dependent + offset by 28 and was vetoed because the three
    free terms fit the folds a little better.  A reading of the same size or larger, and a
    reading kept on a tie (``_tie``: it does not beat "none"; it is judged against "none"
    without the twin, as before), are judged as before.
    """
    if ties or not o.score < none.score:
        return True
    return not len(o.terms.names) + 1 < len(none.terms.names)


def _tie(o, none, settings):
    """
    Tell whether the physical outcome ``o`` ties with its twin in "none" (``TWINS``).

    A tie: "none" holds the twin, ``o`` does not, and ``o``'s empirical terms are among
    "none"'s other terms (the parameter takes the twin's place one for one, with no term
    "none" does not need), and ``o`` scores within ``bic_threshold`` of "none" (penalised
    BIC, the parameter counted like the twin): the threshold at which the workflow calls
    any two explanations one ambiguous effect.
    """
    twin = TWINS[o.kind.name]
    names = set(none.terms.names)
    return twin in names and twin not in o.terms.names and \
        set(o.terms.names) <= names - {twin} and o.score - none.score < settings.bic_threshold


def identifiability(choice, best, none, x, r, settings, tau, skip, fixed, other=None):
    """
    Say which near-twin the chosen physical effect was told from, and on what evidence.

    The twin (``TWINS``: load_dependent for mu, angle_ripple for theta, seal_drag for the
    preload) replaces the physical change, with the same empirical terms on top, fitted to
    the plain residual; the BIC of the two models is compared.  A difference below
    ``bic_threshold``: one ambiguous effect (the physical parameter is kept).  The best
    empirical-only model is compared as well.  ``other``: the Outcome of the second reading,
    the parameter at another value with the twin beside it (or the twin's reading, when the
    chosen one has it); within ``bic_threshold`` the value itself is ambiguous.
    """
    name = choice.kind.name
    twin = TWINS[name]
    cands = {c.name: c for c in candidates(x, settings, skip, fixed)}
    n_eff = r.size / max(tau, 1.0)
    f_phys = fit(best.members, x, r - best.delta_fit, tau)
    bic_phys = f_phys.bic + math.log(n_eff)
    out = []
    if twin in cands:
        members = tuple(m for m in best.members if m[0].name != twin) + ((cands[twin], None),)
        delta, separated = swap_evidence(members, bic_phys, x, r, tau, settings)
        if separated:
            text = (f"{name} rather than the empirical {twin}: BIC {delta:.1f} worse with "
                    f"{twin} in its place")
        else:
            text = (f"{name} and {twin} are one ambiguous effect here (BIC difference "
                    f"{delta:.1f} < {settings.bic_threshold}); {name}, the model's own "
                    "parameter, was kept")
            if delta < 0.0:
                text += f" on the tie ({twin} fits better by {-delta:.1f})"
        out.append({"pair": [name, twin], "chosen": name, "bic_difference":
                    delta if math.isfinite(delta) else None, "separated": bool(separated),
                    "statement": text})
    if other is not None:
        gap = other.score - best.score
        p, u = choice.kind.param, choice.kind.unit
        read = (f"{p} = {best.value:.4g} with {', '.join(best.terms.names) or 'no term'} "
                f"and {p} = {other.value:.4g} with {', '.join(other.terms.names) or 'no term'}")
        same = gap < settings.bic_threshold
        text = (f"{name}'s value is ambiguous with {twin} beside it: {read} fit within a "
                f"penalised BIC of {gap:.1f} < {settings.bic_threshold} (the 95 % interval "
                "covers both)" if same else
                f"{name}: {read}; the first fits better by a penalised BIC of {gap:.1f}")
        out.append({"pair": [name, twin], "chosen": name, "bic_difference": gap,
                    "separated": not same, "statement": text,
                    "values": {p: [best.value, other.value]}, "unit": u,
                    "terms": [list(best.terms.names), list(other.terms.names)]})
    gap = none.score - best.score
    emp = ", ".join(none.terms.names) or "no term"
    text = (f"{name} rather than the best empirical-only model ({emp}): penalised BIC "
            f"{gap:.1f} lower" if gap >= 0.0 else
            f"{name} rather than the best empirical-only model ({emp}), which fits better by "
            f"a penalised BIC of {-gap:.1f} < {settings.bic_threshold}: a tie with {twin}, "
            "and the model's own parameter is kept")
    out.append({"pair": [name, "best empirical model"], "chosen": name,
                "bic_difference": gap, "separated": bool(gap >= settings.bic_threshold),
                "statement": text})
    return out


def _other_parameters(kind, best, bounds, finals, points, settings):
    """
    Name another of the model's parameters the data cannot tell from the chosen one.

    Its best penalised BIC (its refined reading, or the bound of a bracket run's change at
    its free scale) within ``bic_threshold`` of the chosen reading's: the two are one
    ambiguous effect.  Below its onset a preload's change is a load column, as a small
    change of mu is (bench seed 9: mu 0.1007 hidden, preload 1.352 um chosen 0.64 ahead of
    mu 0.10074); no prior prefers one model parameter to another, so the pair is named.
    """
    out = []
    for name in PHYSICAL:
        if name == kind.name or not points[name]:
            continue
        score = min([bounds[name]] + [o.score for o in finals if o.kind.name == name])
        gap = score - best.score
        if math.isfinite(gap) and gap < settings.bic_threshold:
            out.append({"pair": [kind.name, name], "chosen": kind.name, "bic_difference": gap,
                        "separated": False,
                        "statement": f"{kind.name} and {name} are one ambiguous effect here "
                                     f"(a change of {PHYSICAL[name].param} of the model's "
                                     f"shape comes within a penalised BIC of {gap:.1f} < "
                                     f"{settings.bic_threshold} of the chosen reading); "
                                     f"{kind.name} was chosen"})
    return out


def _unchosen_twins(bounds, points, none, settings, kind=None, broken=None):
    """
    When no physical effect is chosen, name a physical twin the data cannot exclude.

    ``bounds``: each candidate's best penalised BIC at the free scale of a run's change (an
    optimistic bound); within ``bic_threshold`` of the chosen empirical model, the twin term
    and the parameter are one ambiguous effect.  ``broken``: the (fit part, held-out part)
    gaps of ``kind``'s tie that the held-out part broke (``_heldout_gap``): the whole
    recording tells that pair apart, and the evidence is said.
    """
    out = []
    for name, twin in TWINS.items():
        if twin not in none.terms.names or not points[name] or not math.isfinite(bounds[name]):
            continue
        if broken is not None and kind is not None and name == kind.name:
            fit_gap, held_gap = broken
            out.append({"pair": [twin, name], "chosen": twin,
                        "bic_difference": fit_gap + held_gap, "separated": True,
                        "statement": f"{twin} rather than {name}: {twin} fits the fit part "
                                     f"better by a penalised BIC of {fit_gap:.1f} and "
                                     f"predicts the held-out part better by {held_gap:.1f} "
                                     f"(-2 ln of the likelihood ratio), "
                                     f"{fit_gap + held_gap:.1f} >= {settings.bic_threshold} "
                                     "over the whole recording"})
            continue
        gap = bounds[name] - none.score
        if gap < settings.bic_threshold:
            out.append({"pair": [twin, name], "chosen": twin, "bic_difference": gap,
                        "separated": False,
                        "statement": f"{twin} and {name} are one ambiguous effect here (a "
                                     f"change of {PHYSICAL[name].param} of the model's shape "
                                     f"comes within a penalised BIC of {gap:.1f} < "
                                     f"{settings.bic_threshold}); {twin} fitted better and "
                                     "was kept"})
    return out
