"""
Mitigation of B2B contact (Sec. 2.4.2): the matched-deviation design rule and Fig. 10.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Sec. 2.4.2, Eq. (22), Table 2 case (b), Fig. 10.

"""

import numpy as np


def matched_top_deviations(dbeta_bl_rad, dbeta_br_rad):
    """
    Eq. (22) design rule: top deviations that null epsilon for any load (Sec. 2.4.2).

    Parameters
    ----------
    dbeta_bl_rad, dbeta_br_rad : array_like
        Measured bottom-groove (rail) deviations  [rad].

    Returns
    -------
    (ndarray, ndarray)
        (dbeta_TR, dbeta_TL) = (dbeta_BL, dbeta_BR) for the carriage  [rad].

    """
    return np.asarray(dbeta_bl_rad, dtype=float), np.asarray(dbeta_br_rad, dtype=float)


def two_ball_relative_motion(eps1, eps2, groove_velocity_m_s, initial_gap_m, t_s,
                             eps_contact=None):
    """
    Fig. 10: displacements of balls 1 (rear) and 2 from nominal motion v/2 t, and their gap.

    Each ball moves at (1 + eps_j) v/2 until the gap closes; from then on both move at
    (1 + eps_contact) v/2 (by default the mean, which Eq. 30 gives for the paper's
    centrally symmetric loads).  Exact piecewise-linear solution.

    Parameters
    ----------
    eps1, eps2 : float
        Velocity deviations of ball 1 (rear) and ball 2 (front)  [1].
    groove_velocity_m_s : float
        Velocity v of the top groove  [m/s].
    initial_gap_m : float
        Gap between the balls at t = 0  [m].
    t_s : array_like
        Times  [s].
    eps_contact : float, optional
        Common velocity deviation once in contact  [1]; default (eps1 + eps2) / 2.

    Returns
    -------
    (ndarray, ndarray, ndarray)
        x1, x2: displacements from v/2 t; gap: initial_gap_m - (x1 - x2)  [m].

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
