"""
The reference the workflow is measured against: the standard rigid-body drive model.

T = J alpha + c omega + T_c sign(omega) + T_0, fitted by ordinary least squares to the
measured torque minus the prediction, with alpha from the workflow's own filter (the same
cut-off, the same samples).  It is what a servo engineer would fit first.  Every run computes
it beside the workflow: on the held-out part (fitted on the fit part, like the
selection) and on the validation recording (fitted on all usable samples of the fit
recording, like the written model); ``summary.json`` carries both, and the report says so
first where the workflow is worse.
"""

import dataclasses

import numpy as np

PARAMS = ("j_kg_m2", "c_nm_s_per_rad", "coulomb_nm", "offset_nm")
FORMULA = "J alpha + c omega + T_c sign(omega) + T_0 (ordinary least squares)"


def _columns(x):
    """Return the columns [alpha, omega, sign(omega), 1] (1 and a missing alpha as scalars)."""
    w = x.nut_velocity_rad_s
    a = x.nut_accel_rad_s2
    return [np.zeros_like(w) if a is None else a, w, np.sign(w), np.ones_like(w)]


@dataclasses.dataclass
class RigidBody:
    """A fitted rigid-body model: J [kg m^2], c [N m s/rad], T_c, T_0 [N m]."""

    coef: np.ndarray

    @classmethod
    def fit(cls, x, r):
        """
        Least squares of residual ``r`` [N m] on the columns of inputs ``x``.

        From the 4 x 4 normal equations, one column pair at a time: the n x 4 design and
        lstsq's copy of it are never built (a 10-minute 1 kHz recording: 2 x 19 MB).
        Columns scaled to unit norm first, as ``selection._solve`` does.
        """
        cols = _columns(x)
        g = np.array([[float(a @ b) for b in cols] for a in cols])
        b = np.array([float(a @ r) for a in cols])
        d = np.sqrt(np.diag(g))
        d[d == 0.0] = 1.0
        coef, *_ = np.linalg.lstsq(g / np.outer(d, d), b / d, rcond=1e-12)
        return cls(coef / d)

    def torque_nm(self, x):
        """Return the model's torque [N m] at inputs ``x``."""
        out = np.zeros_like(x.nut_velocity_rad_s, dtype=float)
        for c, col in zip(self.coef, _columns(x)):
            out += c * col
        return out

    def params(self):
        """Return the coefficients by name (summary.json)."""
        return {k: float(v) for k, v in zip(PARAMS, self.coef)}


def rigid_body_fit(rec):
    """Return the least-squares (J, c, T_c, T_0) of measured - predicted on ``rec``."""
    return RigidBody.fit(rec, rec.torque_meas_nm - rec.torque_pred_nm).coef


def rigid_body_relative_error(coef, rec):
    """Return ||meas - pred - rigid body|| / ||meas|| on ``rec``."""
    e = rec.torque_meas_nm - rec.torque_pred_nm - RigidBody(np.asarray(coef)).torque_nm(rec)
    return float(np.linalg.norm(e) / np.linalg.norm(rec.torque_meas_nm))
