"""
Mitigation advisor for a four-point-contact linear bearing (paper Sec. 2.4.2, Eq. 22).

Given the measured contact-angle deviations of the bottom rail (dbeta_BL, dbeta_BR), the
carriage (top groove) deviations that null the velocity deviation of every ball, whatever
the load, are dbeta_TR = dbeta_BL and dbeta_TL = dbeta_BR (``matched_top_deviations``).
The advisor returns them and the B2B friction the numerical model predicts for the two-ball
case of Sec. 2.4 before (the carriage as it is) and after (matched), at each side force ratio
asked for.

With several measuring stations along the rail one carriage cannot match them all: Eq. (22)
is affine in (dbeta_TR - dbeta_BL) and (dbeta_TL - dbeta_BR) with load-dependent weights,
so the mean of the stations' deviations minimises the sum over stations of the squared
velocity deviation for every load.  That single carriage is evaluated at every station.
"""

import math

import numpy as np

from bb_friction_ros.config import ConfigError
from bb_friction_ros.linear_bearing.mitigation import matched_top_deviations
from bb_friction_ros.sweep.models import run_linear_pair

# Outputs shown before / after.
SHOWN = ("eps1", "eps2", "eps_diff", "f_b2b_n", "p_b2b_w", "friction_ratio")


def predict(cfg, bottom_rad, top_rad, rho):
    """Return the numerical two-ball prediction as {output: value, status, reason}."""
    params = {"dbeta_bl_rad": bottom_rad[0], "dbeta_br_rad": bottom_rad[1],
              "dbeta_tr_rad": top_rad[0], "dbeta_tl_rad": top_rad[1], "rho": rho}
    out, status, reason = run_linear_pair(cfg, params, {"method": "numerical"})
    row = {k: (float(out[k]) if k in out else None) for k in SHOWN}
    row.update(status=status, reason=reason)
    return row


def _check_angle(name, value_rad):
    if not math.isfinite(value_rad) or abs(value_rad) >= math.pi / 2:
        raise ConfigError(f"--{name}: must be finite and within (-90, 90) deg, got "
                          f"{math.degrees(value_rad)}")


def advise(cfg, dbeta_bl_rad, dbeta_br_rad, rho_values=None, top_now_rad=(0.0, 0.0)):
    """
    Return the matched carriage deviations and the before/after predictions.

    ``dbeta_bl_rad``, ``dbeta_br_rad``: measured bottom deviations, one value per station;
    ``rho_values``: side force ratios to predict at (default: the config's);
    ``top_now_rad``: the carriage's present (dbeta_TR, dbeta_TL).
    """
    bl = np.atleast_1d(np.asarray(dbeta_bl_rad, dtype=float))
    br = np.atleast_1d(np.asarray(dbeta_br_rad, dtype=float))
    if bl.shape != br.shape:
        raise ConfigError(f"--dbeta-br-deg: one value per station, as --dbeta-bl-deg "
                          f"({bl.size} given, {br.size} here)")
    named = (("dbeta-bl-deg", bl), ("dbeta-br-deg", br), ("dbeta-tr-deg", [top_now_rad[0]]),
             ("dbeta-tl-deg", [top_now_rad[1]]))
    for name, values in named:
        for v in values:
            _check_angle(name, v)
    rhos = [cfg.side_force_ratio] if not rho_values else list(rho_values)
    for r in rhos:
        if not (math.isfinite(r) and -1.0 < r < 1.0):
            raise ConfigError(f"--rho: must be within (-1, 1), got {r}")
    stations = []
    for b_l, b_r in zip(bl, br):
        tr, tl = (float(x) for x in matched_top_deviations(b_l, b_r))
        stations.append({
            "dbeta_bl_rad": float(b_l), "dbeta_br_rad": float(b_r),
            "matched_dbeta_tr_rad": tr, "matched_dbeta_tl_rad": tl,
            "cases": [{"rho": r,
                       "before": predict(cfg, (b_l, b_r), top_now_rad, r),
                       "after": predict(cfg, (b_l, b_r), (tr, tl), r)} for r in rhos]})
    result = {"rule": "Eq. (22): dbeta_TR = dbeta_BL, dbeta_TL = dbeta_BR null the velocity "
                      "deviation irrespective of the load",
              "model": "numerical, two-ball case of Sec. 2.4",
              "carriage_now_rad": [float(top_now_rad[0]), float(top_now_rad[1])],
              "stations": stations}
    if bl.size > 1:
        tr, tl = (float(x) for x in matched_top_deviations(bl.mean(), br.mean()))
        result["single_carriage"] = {
            "dbeta_tr_rad": tr, "dbeta_tl_rad": tl,
            "why": "mean of the stations: least squares of Eq. (22) over stations, any load",
            "cases": [{"station": i, "rho": r,
                       "after": predict(cfg, (b_l, b_r), (tr, tl), r)}
                      for i, (b_l, b_r) in enumerate(zip(bl, br)) for r in rhos]}
    return result


def format_advice(result):
    """Return the advice as text lines (angles in deg, powers in mW)."""
    lines = [f"rule: {result['rule']}", f"model: {result['model']}", ""]

    def fmt(row):
        if row["f_b2b_n"] is None:
            return f"{row['status']}: {row['reason']}"
        return (f"eps1-eps2 {row['eps_diff'] * 100:+.4f} %  F_B2B {row['f_b2b_n']:.4f} N  "
                f"P_fB2B {row['p_b2b_w'] * 1e3:.4f} mW  "
                f"(P_f+P_fB2B)/P_f {row['friction_ratio'] * 100:.1f} %")

    for i, st in enumerate(result["stations"]):
        deg = {k: math.degrees(v) for k, v in st.items() if k.endswith("_rad")}
        lines.append(f"station {i}: bottom dbeta_BL {deg['dbeta_bl_rad']:+.4f} deg, "
                     f"dbeta_BR {deg['dbeta_br_rad']:+.4f} deg")
        lines.append(f"  matched carriage: dbeta_TR {deg['matched_dbeta_tr_rad']:+.4f} deg, "
                     f"dbeta_TL {deg['matched_dbeta_tl_rad']:+.4f} deg")
        for case in st["cases"]:
            lines.append(f"  rho {case['rho']:+.3f} before: {fmt(case['before'])}")
            lines.append(f"  rho {case['rho']:+.3f} after:  {fmt(case['after'])}")
    single = result.get("single_carriage")
    if single:
        lines += ["", f"one carriage for all stations: dbeta_TR "
                      f"{math.degrees(single['dbeta_tr_rad']):+.4f} deg, dbeta_TL "
                      f"{math.degrees(single['dbeta_tl_rad']):+.4f} deg ({single['why']})"]
        for case in single["cases"]:
            lines.append(f"  station {case['station']} rho {case['rho']:+.3f}: "
                         f"{fmt(case['after'])}")
    return lines
