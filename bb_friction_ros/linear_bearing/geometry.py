"""
Cross-section geometry and rigid statics of a ball between bottom rail and top carriage.

Contact order everywhere: BL, BR, TR, TL (bottom/top, left/right; paper Fig. 2).  Angles
beta_i are measured from the -y axis (bottom) or +y axis (top) to the contact normal.
Global frame: x across, y up, z along the rail (the top groove moves at +v along z).

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Fig. 2, Eq. (18), Sec. 2.4.1 (diagonal loads F_1U, F_1D).

"""

import numpy as np

CONTACTS = ("BL", "BR", "TR", "TL")
TOP = np.array([False, False, True, True])


def deviated_contact_angles(beta0_rad, dbeta_bl, dbeta_br, dbeta_tr, dbeta_tl):
    """Eq. (18): beta_i = beta_0 + delta beta_i, in contact order  [rad]."""
    return beta0_rad + np.array([dbeta_bl, dbeta_br, dbeta_tr, dbeta_tl], dtype=float)


def outward_normals(beta_rad):
    """Return unit vectors from the ball centre to the four contact points, shape (4, 2) (x, y)."""
    b = np.asarray(beta_rad, dtype=float)
    sx = np.array([-1.0, 1.0, 1.0, -1.0])
    sy = np.array([-1.0, -1.0, 1.0, 1.0])
    return np.stack([sx * np.sin(b), sy * np.cos(b)], axis=-1)


def contact_forces_rigid(beta_rad, side_force_n, vertical_load_n):
    """
    Solve the normal contact loads from rigid statics of the top groove and of the ball  [N].

    The external load (N_x, -N_y) acts on the top groove, which rests on the ball at TR, TL;
    the ball rests on the bottom rail at BL, BR.  Two 2x2 systems, exact for any deviation.
    """
    n = outward_normals(beta_rad)
    # top groove: F_TR n_TR + F_TL n_TL (push of the ball on the groove) = -(N_x, -N_y)
    rhs = np.array([-side_force_n, vertical_load_n], dtype=float)
    # ball: F_BL n_BL + F_BR n_BR = -(F_TR n_TR + F_TL n_TL) (loads push toward the centre)
    # Two 2 x 2 systems by Cramer's rule (np.linalg.solve costs ~0.1 ms of overhead each).
    return np.concatenate([_solve_columns(n[0], n[1], -rhs), _solve_columns(n[2], n[3], rhs)])


def _solve_columns(c0, c1, rhs):
    """(f0, f1) with f0 c0 + f1 c1 = rhs for 2-vectors; raises on parallel columns."""
    det = c0[0] * c1[1] - c0[1] * c1[0]
    if det == 0.0:
        raise np.linalg.LinAlgError("contact normals are parallel: no rigid statics")
    return np.array([(rhs[0] * c1[1] - rhs[1] * c1[0]) / det,
                     (c0[0] * rhs[1] - c0[1] * rhs[0]) / det])


def contact_forces_diagonal(beta0_rad, side_force_n, vertical_load_n):
    """Sec. 2.4.1 approximation: F_BL = F_TR = F_U and F_BR = F_TL = F_D at nominal angles."""
    half_y = 0.5 * vertical_load_n / np.cos(beta0_rad)
    half_x = 0.5 * side_force_n / np.sin(beta0_rad)
    f_u, f_d = half_y - half_x, half_y + half_x
    return np.array([f_u, f_d, f_u, f_d])
