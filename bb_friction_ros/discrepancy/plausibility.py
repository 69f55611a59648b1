"""
Checks that a measured torque is plausible before anything is fitted to it.

Two errors give no clue in the fit itself and produce a model that is worse than none:

- **The sign.** Friction is dissipated at the contacts, so in the model's convention (the torque
  the drive spends on it) it has the sign of the nut velocity.  A motor current that is positive
  in the other direction makes the measured friction follow the motion; the workflow would fit a
  negative friction coefficient, and a controller feeding the result forward would push the axis
  along its motion.  The Coulomb part of the measured torque (least squares on 1 and
  sign(omega), the constant absorbing gravity or a bias) must not be significantly negative.
- **The scale.** A torque constant off by orders of magnitude (a typo, mA for A) still "finds"
  effects.  The constant must lie within a motor's range, and the measured torque within a
  factor of the model's prediction.
"""

import math

import numpy as np

from bb_friction_ros.discrepancy.data import CURRENT_FLAG, InputProblem


def measured_sign_check(rec, settings):
    """
    Return (coulomb N m, standard error N m, share against, moving samples) of ``rec``.

    ``share against``: the share of moving samples whose measured torque has the sign opposite
    to the velocity.  ``coulomb`` is None when the recording moves in one direction only.
    """
    w = rec.nut_velocity_rad_s
    ok = np.isfinite(rec.torque_meas_nm) & (np.abs(w) > settings.standstill_speed_rad_s)
    torque, sign = rec.torque_meas_nm[ok], np.sign(w[ok])
    n = int(ok.sum())
    if n == 0:
        return None, None, 0.0, 0
    against = float(np.mean(torque * sign < 0.0))
    if not (np.any(sign > 0) and np.any(sign < 0)) or n < 3:
        return None, None, against, n
    design = np.column_stack([np.ones(n), sign])
    coef, *_ = np.linalg.lstsq(design, torque, rcond=None)
    resid = torque - design @ coef
    cov = np.linalg.inv(design.T @ design) * float(resid @ resid) / (n - 2)
    return float(coef[1]), float(np.sqrt(cov[1, 1])), against, n


def check_measured_sign(rec, settings, path):
    """Refuse (InputProblem) a measured torque whose friction follows the motion."""
    coulomb, se, against, n = measured_sign_check(rec, settings)
    source = rec.info.get("measured_torque_source", "the measured torque")
    if coulomb is not None:
        wrong = coulomb < -settings.sign_error_z * se
        how = (f"its Coulomb part is {coulomb:.4g} N m (+- {se:.2g}), and {against:.0%} of "
               f"the {n} moving samples have the sign opposite to the nut velocity")
    else:
        wrong = against >= settings.sign_error_fraction
        how = (f"{against:.0%} of the {n} moving samples (one direction only) have the sign "
               "opposite to the nut velocity")
    if wrong:
        raise InputProblem(
            f"{path}: the measured torque ({source}) follows the motion: {how}.  Friction has "
            "the sign of the nut velocity (the torque the drive spends on it), so this is a "
            "sign error: a motor current positive in the other direction, or a torque logged "
            "as the reaction.  Negate the measurement; nothing was fitted")


def check_torque_constant(k_nm_per_a, settings):
    """Refuse a torque constant outside a motor's range, naming the flag."""
    if k_nm_per_a is None or not (math.isfinite(k_nm_per_a) and k_nm_per_a > 0.0):
        return      # not a number > 0: data.load_recording refuses it, naming the flag
    lo, hi = settings.min_torque_constant_nm_per_a, settings.max_torque_constant_nm_per_a
    if not lo <= k_nm_per_a <= hi:
        raise InputProblem(
            f"{CURRENT_FLAG}: {k_nm_per_a:g} N m/A is not a motor's torque constant (accepted "
            f"{lo:g} to {hi:g} N m/A, settings min_torque_constant_nm_per_a and "
            "max_torque_constant_nm_per_a); check its unit: N m per A of phase current")


def check_measured_scale(rec, settings, path):
    """Refuse a measured torque orders of magnitude off the model's prediction."""
    moving = np.abs(rec.nut_velocity_rad_s) > settings.standstill_speed_rad_s
    ok = moving & np.isfinite(rec.torque_meas_nm) & np.isfinite(rec.torque_pred_nm)
    if rec.info.get("baseline") == "zero" or not ok.any():
        return
    meas = float(np.sqrt(np.mean(rec.torque_meas_nm[ok] ** 2)))
    pred = float(np.sqrt(np.mean(rec.torque_pred_nm[ok] ** 2)))
    if pred <= 0.0:
        return
    ratio, limit = meas / pred, settings.max_measured_scale_ratio
    if not 1.0 / limit <= ratio <= limit:
        source = rec.info.get("measured_torque_source", "the measured torque")
        raise InputProblem(
            f"{path}: the measured torque ({source}) is {ratio:.3g} times the model's "
            f"prediction (RMS {meas:.4g} against {pred:.4g} N m on moving samples; accepted "
            f"within a factor {limit:g}, setting max_measured_scale_ratio): check its unit "
            f"or the torque constant ({CURRENT_FLAG})")
