"""
Analytical model of ball velocity and B2B contact, Eqs. (13)-(33); vectorised over arrays.

Every function broadcasts over numpy arrays (e.g. a theta x rho grid).  Angles in rad, forces
in N, lengths in m.  Contact order BL, BR, TR, TL.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (11), (13)-(33), Secs. 2.3.1-2.3.3.

"""

import numpy as np
from scipy.special import ellipe


def spin_moment_factor(ellipticity):
    """Ellip(e) of Eq. (11), e = sqrt(1 - (b/a)^2); scipy takes the parameter m = e^2."""
    return ellipe(1.0 - np.asarray(ellipticity, dtype=float) ** 2)


def velocity_centre_deviation(dbeta, loads_n, beta_rad, ball_radius_m, psi, ellipticity, k_f):
    """
    Eqs. (16) + (19): angular deviations d_eta_i of the velocity centres  [rad].

    ``dbeta``, ``loads_n``, ``beta_rad``: arrays (..., 4).  Eq. (16) is linear in d_eta once
    the moments take their pure-spin value (Eq. 11); Eq. (19) closes the 4x4 system.
    """
    dbeta, loads, beta = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                               for x in (dbeta, loads_n, beta_rad)))
    c, s = np.cos(beta), np.sin(beta)
    ones = np.ones_like(c[..., 0])
    zeros = np.zeros_like(ones)
    a_force = np.stack([np.stack([ones] * 4, -1),
                        np.stack([-c[..., 0], -c[..., 1], c[..., 2], c[..., 3]], -1),
                        np.stack([s[..., 0], -s[..., 1], -s[..., 2], s[..., 3]], -1)], -2)
    a_moment = np.stack([np.stack([zeros] * 4, -1),
                         np.stack([s[..., 0], -s[..., 1], -s[..., 2], s[..., 3]], -1),
                         np.stack([c[..., 0], c[..., 1], -c[..., 2], -c[..., 3]], -1)], -2)
    sign_f = np.array([1.0, 1.0, -1.0, -1.0])
    sign_m = np.array([-1.0, 1.0, 1.0, -1.0])
    mu = 1.0   # mu multiplies both terms of Eq. (16) and cancels
    coef = (k_f / psi) * mu * (ball_radius_m * loads) ** (2.0 / 3.0) * sign_f
    moment = (3.0 / 8.0) * psi * spin_moment_factor(ellipticity) * mu \
        * ball_radius_m ** (-2.0 / 3.0) * loads ** (4.0 / 3.0) * sign_m
    lhs = np.zeros(a_force.shape[:-2] + (4, 4))
    lhs[..., :3, :] = a_force * coef[..., None, :]
    rhs = np.zeros(a_force.shape[:-2] + (4,))
    rhs[..., :3] = -np.einsum("...ij,...j->...i", a_moment, moment)
    lhs[..., 3, :] = [1.0, -1.0, -1.0, 1.0]                       # Eq. (19)
    rhs[..., 3] = -(dbeta[..., 0] - dbeta[..., 1] - dbeta[..., 2] + dbeta[..., 3])
    return np.linalg.solve(lhs, rhs[..., None])[..., 0]


def velocity_deviation_eq21(dbeta, d_eta, beta0_rad):
    """Eq. (21): epsilon = (1 - cos 2 beta_0)(-dbeta_BR - d_eta_BR + dbeta_TL + d_eta_TL)/2."""
    dbeta, d_eta = np.asarray(dbeta, dtype=float), np.asarray(d_eta, dtype=float)
    return (1.0 - np.cos(2.0 * beta0_rad)) * 0.5 * (
        -dbeta[..., 1] - d_eta[..., 1] + dbeta[..., 3] + d_eta[..., 3])


def velocity_deviation_eq22(dbeta, f_u_n, f_d_n, beta0_rad):
    """
    Eq. (22): ball-velocity deviation epsilon with diagonal loads.

    Parameters
    ----------
    dbeta : array_like, shape (..., 4)
        Contact-angle deviations (BL, BR, TR, TL), Eq. (18)  [rad].
    f_u_n, f_d_n : array_like
        Diagonal contact loads F_U = F_BL = F_TR and F_D = F_BR = F_TL  [N].
    beta0_rad : float
        Nominal contact angle beta_0  [rad].

    Returns
    -------
    ndarray
        epsilon: v_B = (1 + epsilon) v/2, as a fraction (not %)  [1].

    """
    dbeta = np.asarray(dbeta, dtype=float)
    wu, wd = np.asarray(f_u_n, float) ** (2.0 / 3.0), np.asarray(f_d_n, float) ** (2.0 / 3.0)
    return (1.0 - np.cos(2.0 * beta0_rad)) * (
        (-dbeta[..., 0] + dbeta[..., 2]) * wu + (-dbeta[..., 1] + dbeta[..., 3]) * wd
    ) / (2.0 * (wu + wd))


def velocity_deviation_eq33(theta_rad, rho):
    """
    Eq. (33): velocity deviations of the two balls of the Sec. 2.4.1 case (beta_0 = 45 deg).

    Parameters
    ----------
    theta_rad : array_like
        Bottom-groove deviation theta: dbeta_BL = -theta, dbeta_BR = +theta  [rad].
    rho : array_like
        Side force ratio N_x / N_y of ball 1 (ball 2 carries -rho N_y), |rho| < 1  [1].

    Returns
    -------
    (ndarray, ndarray)
        (epsilon_1, epsilon_2), fractions of v/2  [1]; epsilon_2 = -epsilon_1.

    """
    theta, rho = np.asarray(theta_rad, dtype=float), np.asarray(rho, dtype=float)
    r = ((1.0 + rho) / (1.0 - rho)) ** (2.0 / 3.0)
    eps1 = (1.0 - r) / (1.0 + r) * theta / 2.0
    return eps1, -eps1


def b2b_force_eq30(eps1, eps2, loads1_ud_n, loads2_ud_n, ball_radius_m, psi, beta0_rad, mu,
                   k_f):
    """
    Eq. (30): B2B contact force, analytical; zero where ball 1 is not faster.

    The gap condition is the caller's (the two balls are taken as touching).

    Parameters
    ----------
    eps1, eps2 : array_like
        Velocity deviations of ball 1 (rear) and ball 2 (front), Eq. (22)  [1].
    loads1_ud_n, loads2_ud_n : array_like, shape (..., 2)
        (F_U, F_D) of each ball  [N].
    ball_radius_m : float
        Ball radius R_B  [m].
    psi : float
        Hertz constant Psi of Eq. (15)  [(m^2/N)^(1/3)].
    beta0_rad : float
        Nominal contact angle beta_0  [rad].
    mu : float
        Coulomb friction coefficient  [1].
    k_f : float
        Slope of the linearised friction force, Eq. (14)  [1].

    Returns
    -------
    ndarray
        F_B2B >= 0  [N].

    """
    l1, l2 = np.asarray(loads1_ud_n, dtype=float), np.asarray(loads2_ud_n, dtype=float)
    s1 = l1[..., 0] ** (2.0 / 3.0) + l1[..., 1] ** (2.0 / 3.0)
    s2 = l2[..., 0] ** (2.0 / 3.0) + l2[..., 1] ** (2.0 / 3.0)
    d_eps = np.asarray(eps1, dtype=float) - np.asarray(eps2, dtype=float)
    force = (2.0 * k_f * mu / (psi * (1.0 - np.cos(2.0 * beta0_rad)))
             * ball_radius_m ** (2.0 / 3.0) * s1 * s2 / (s1 + s2) * d_eps)
    return np.where(d_eps > 0.0, force, 0.0)


def b2b_slip_speed_eq31(groove_velocity_m_s, beta0_rad):
    """Eq. (31): sliding speed at the B2B contact, |dv| = v / cos(beta_0)  [m/s]."""
    return np.abs(groove_velocity_m_s) / np.cos(beta0_rad)


def b2b_loss_eq32(b2b_force_n, groove_velocity_m_s, beta0_rad, mu):
    """
    Eq. (32): B2B friction loss P_fB2B = mu F_B2B v / cos(beta_0).

    Parameters
    ----------
    b2b_force_n : array_like
        B2B contact force F_B2B  [N].
    groove_velocity_m_s : float
        Velocity v of the top groove  [m/s].
    beta0_rad : float
        Nominal contact angle beta_0  [rad].
    mu : float
        Coulomb friction coefficient  [1].

    Returns
    -------
    ndarray
        P_fB2B  [W].

    """
    return mu * np.asarray(b2b_force_n, float) * b2b_slip_speed_eq31(groove_velocity_m_s,
                                                                     beta0_rad)


def groove_loss_pure_spin(loads_n, semi_major_m, ellipticity, groove_velocity_m_s,
                          beta0_rad, ball_radius_m, mu):
    """
    Ball-groove loss of one ball at the analytical model's pure-spin limit (Eq. 11)  [W].

    With c_i ~ 0 (Sec. 2.3.1) each contact only spins: P_i = |w_i| M_i,O with
    M_i,O = 3/8 mu F_i a_i Ellip and |w_i| = w_x sin beta_0, w_x = v / (2 R_B cos beta_0).
    The paper gives no analytical P_f; this is its own approximation carried to the loss.
    """
    spin = np.abs(groove_velocity_m_s) * np.tan(beta0_rad) / (2.0 * ball_radius_m)
    m0 = 0.375 * mu * np.asarray(loads_n, float) * np.asarray(semi_major_m, float) \
        * spin_moment_factor(ellipticity)
    return np.sum(m0, axis=-1) * spin
