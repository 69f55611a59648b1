"""Mitigation of B2B contact (Sec. 2.4.2): the matched-deviation design rule and Fig. 10."""

import numpy as np


def matched_top_deviations(dbeta_bl_rad, dbeta_br_rad):
    """Eq. (22) design rule: dbeta_TR = dbeta_BL and dbeta_TL = dbeta_BR null epsilon."""
    return np.asarray(dbeta_bl_rad, dtype=float), np.asarray(dbeta_br_rad, dtype=float)


def two_ball_relative_motion(eps1, eps2, groove_velocity_m_s, initial_gap_m, t_s,
                             eps_contact=None):
    """
    Fig. 10: displacements of balls 1 (rear) and 2 from nominal motion v/2 t, and their gap.

    Each ball moves at (1 + eps_j) v/2 until the gap closes; from then on both move at
    (1 + eps_contact) v/2 (by default the mean, which Eq. 30 gives for the paper's
    centrally symmetric loads).  Exact piecewise-linear solution.  Returns (x1, x2, gap) [m].
    """
    t = np.asarray(t_s, dtype=float)
    half_v = 0.5 * groove_velocity_m_s
    v1, v2 = eps1 * half_v, eps2 * half_v              # relative to the nominal v/2
    if eps_contact is None:
        eps_contact = 0.5 * (eps1 + eps2)
    closing = v1 - v2
    t_hit = initial_gap_m / closing if closing > 0 else np.inf
    t_free = np.minimum(t, t_hit)
    t_joint = t - t_free
    x1 = v1 * t_free + eps_contact * half_v * t_joint
    x2 = v2 * t_free + eps_contact * half_v * t_joint
    gap = initial_gap_m - (x1 - x2)
    return x1, x2, gap
