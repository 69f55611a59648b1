"""
The reference the workflow is measured against: the standard rigid-body drive model.

T = J alpha + c omega + T_c sign(omega) + T_0, fitted by least squares to the measured torque
minus the prediction, with alpha from the workflow's own filter.  It is what a servo
engineer would fit first; the bench (bench/bench_discrepancy.py) and the real-data tests
require the workflow's augmented model to be no worse than it on a validation recording.
"""

import numpy as np


def rigid_body_columns(rec):
    """Return the design matrix [alpha, omega, sign(omega), 1] of a Recording."""
    w = rec.nut_velocity_rad_s
    return np.column_stack([rec.nut_accel_rad_s2, w, np.sign(w), np.ones_like(w)])


def rigid_body_fit(rec):
    """Return the least-squares (J, c, T_c, T_0) of measured - predicted on ``rec``."""
    r = rec.torque_meas_nm - rec.torque_pred_nm
    coef, *_ = np.linalg.lstsq(rigid_body_columns(rec), r, rcond=None)
    return coef


def rigid_body_relative_error(coef, rec):
    """Return ||meas - pred - rigid body|| / ||meas|| on ``rec``."""
    e = rec.torque_meas_nm - rec.torque_pred_nm - rigid_body_columns(rec) @ coef
    return float(np.linalg.norm(e) / np.linalg.norm(rec.torque_meas_nm))


def rigid_body_on(fit_rec, val_rec, settings):
    """
    Fit the rigid-body model on ``fit_rec`` and return (coef, relative error on ``val_rec``).

    Both recordings get their acceleration from the workflow's zero-phase filter (the same
    cut-off) and are restricted to their usable samples, as the workflow does; the fit uses
    the workflow's fit part (the first 1 - holdout_fraction of the samples), so both models
    learn from the same samples.
    """
    from bb_friction_ros.discrepancy.workflow import usable, with_acceleration
    fit_rec, spec = with_acceleration(fit_rec, settings)
    val_rec, _ = with_acceleration(val_rec, settings, spec)
    fit_rec = fit_rec.take(usable(fit_rec)[0])
    val_rec = val_rec.take(usable(val_rec)[0])
    n_fit = int(np.floor((1.0 - settings.holdout_fraction) * len(fit_rec)))
    fit_rec = fit_rec.take(np.arange(len(fit_rec)) < n_fit)
    coef = rigid_body_fit(fit_rec)
    return coef, rigid_body_relative_error(coef, val_rec)
