"""
Ball screw geometry: helix, moving frame CS_3, groove arcs and B2B separation (Eqs. 34-56).

Cross-section coordinates (x, z) are along x_3 (radial, away from the screw axis) and z_3
(in the plane normal to the helix, about axial).  Contacts are indexed SL, SR, NR, NL = 0..3;
the unit vector n from the ball centre to a contact points into that groove.  Each groove
side is a circular arc of radius R_G = 2 conf R_B whose centre lies on the nominal contact
line at distance R_G - R_B beyond the nominal ball centre, so the contact normal always
passes through the arc centre: the paper's 18-unknown state per ball (Eq. 55) reduces
exactly to the ball-centre offset (2) and the kinematics (4).

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (34)-(42), (45), (56), Figs. 12-13, 15-17, 19.

"""

import math

import numpy as np

from bb_friction_ros.contact.friction_maps import cached_arrays
from bb_friction_ros.contact.hertz import HertzContact, effective_modulus

CONTACTS = ("SL", "SR", "NR", "NL")
ON_NUT = np.array([0.0, 0.0, 1.0, 1.0])   # 1 for the nut's (moving) contacts


def lead_angle(lead_m, pitch_radius_m):
    """Eq. (42): nominal lead angle alpha = atan(p / (2 pi R_P))."""
    return math.atan2(lead_m, 2.0 * math.pi * pitch_radius_m)


def helix_length_per_turn(lead_m, pitch_radius_m):
    """Eq. (45): L = sqrt((2 pi R_P)^2 + p^2), length of one turn of the ball-centre helix."""
    return math.hypot(2.0 * math.pi * pitch_radius_m, lead_m)


def nominal_ball_centre(phi, pitch_radius_m, lead_m):
    """Eq. (35): point of the nominal ball-centre helix at azimuth phi (screw frame)."""
    r_g = lead_m / (2.0 * math.pi)
    return np.array([pitch_radius_m * math.cos(phi), pitch_radius_m * math.sin(phi),
                     r_g * phi])


def frame_cs3(phi, alpha):
    """Eq. (41): columns x_3, y_3, z_3 of CS_3 = rot_z(phi) rot_x(alpha), in the screw frame."""
    c, s = math.cos(phi), math.sin(phi)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array([[c, -s * ca, s * sa], [s, c * ca, -c * sa], [0.0, sa, ca]])


def b2b_contact_angle(ball_radius_m, lead_m, pitch_radius_m):
    """Eq. (56): B2B contact angle beta_B2B = asin(2 pi R_B / L) (balls on a circle L/2pi)."""
    return math.asin(2.0 * math.pi * ball_radius_m
                     / helix_length_per_turn(lead_m, pitch_radius_m))


def b2b_contact_separation(ball_radius_m, lead_m, pitch_radius_m):
    """
    Azimuth separation of two touching balls on the exact helix: |chord| = 2 R_B.

    Eq. (56) puts the balls on a circle of radius L/2pi, for which the separation would be
    2 beta_B2B; on the true helix the chord is slightly shorter, and only this separation
    keeps the distance of two balls with equal omega_B exactly 2 R_B (exact power balance).
    """
    r_g = lead_m / (2.0 * math.pi)

    def chord_minus_diameter(dphi):
        return math.hypot(2.0 * pitch_radius_m * math.sin(0.5 * dphi), r_g * dphi) \
            - 2.0 * ball_radius_m

    def build():
        # scipy only when the table cache misses: its import is most of the node's
        # start-up import time (``hertz._ellipse`` says why).
        from scipy.optimize import brentq
        hi = 2.0 * b2b_contact_angle(ball_radius_m, lead_m, pitch_radius_m)
        while chord_minus_diameter(hi) < 0.0:
            hi *= 1.5
        return {"separation": np.array(
            brentq(chord_minus_diameter, 1e-12, hi, xtol=1e-15, rtol=1e-15))}

    key = (float(ball_radius_m), float(lead_m), float(pitch_radius_m))
    return float(cached_arrays("b2b-separation", key, build)["separation"])


def b2b_chord_frames(separation_rad, pitch_radius_m, lead_m):
    """
    Return the unit chord from rear to front ball in each ball's CS_3 and the rotation.

    ``separation_rad`` is signed: front azimuth minus rear azimuth.  Returns (m_rear,
    m_front, rot) with m_* the chord direction in the rear's / front's CS_3 components and
    rot mapping front-frame components to rear-frame components.
    """
    alpha = lead_angle(lead_m, pitch_radius_m)
    rear = frame_cs3(0.0, alpha)
    front = frame_cs3(separation_rad, alpha)
    chord = nominal_ball_centre(separation_rad, pitch_radius_m, lead_m) \
        - nominal_ball_centre(0.0, pitch_radius_m, lead_m)
    chord /= np.linalg.norm(chord)
    return rear.T @ chord, front.T @ chord, rear.T @ front


def theta_deviation(phi, amplitude_rad, cycles_per_rev, phase_rad, offset_rad):
    """Fig. 19: screw contact-angle deviation theta(phi), sinusoidal in the azimuth."""
    return offset_rad + amplitude_rad * np.sin(cycles_per_rev * np.asarray(phi) + phase_rad)


def arc_centres(theta, screw_shift_m, nut_shift_m, groove_radius_m, ball_radius_m,
                contact_angle_rad):
    """
    Figs. 15, 17: groove-arc centres (x, z) relative to the nominal ball centre.

    The screw profile is rotated rigidly by -theta about the nominal ball centre
    (beta_SL = beta_0 - theta, beta_SR = beta_0 + theta) and shifted by ``screw_shift_m``
    along z_3; the nut profile is shifted by ``nut_shift_m`` along z_3.  Arrays broadcast;
    result has shape (..., 4, 2) in the order SL, SR, NR, NL.
    """
    theta = np.asarray(theta, dtype=float)
    e = groove_radius_m - ball_radius_m
    b0 = contact_angle_rad
    sl = b0 - theta
    sr = b0 + theta
    shape = np.broadcast(theta, screw_shift_m, nut_shift_m).shape
    out = np.empty(shape + (4, 2))
    out[..., 0, 0] = e * np.cos(sl)
    out[..., 0, 1] = e * np.sin(sl) + screw_shift_m
    out[..., 1, 0] = e * np.cos(sr)
    out[..., 1, 1] = -e * np.sin(sr) + screw_shift_m
    out[..., 2, 0] = -e * math.cos(b0)
    out[..., 2, 1] = -e * math.sin(b0) + nut_shift_m
    out[..., 3, 0] = -e * math.cos(b0)
    out[..., 3, 1] = e * math.sin(b0) + nut_shift_m
    return out


def groove_relative_curvatures(contact, ball_radius_m, groove_radius_m, pitch_radius_m,
                               lead_m, contact_angle_rad, step=1e-4):
    """
    Eq. (53)'s Hertz constants need the relative curvatures of ball and helical groove.

    The groove surface is the normal-section arc swept along the helix.  Its curvature
    tensor at the nominal contact point is computed from the second fundamental form (finite
    differences of the exact surface), added to the ball's 1/R_B and diagonalised; returns
    (across, along) principal relative curvatures [1/m] (across < along).  The principal
    axes differ from (across-groove, helix) by ~0.2 deg for Table 4, which is neglected.
    """
    idx = CONTACTS.index(contact)
    alpha = lead_angle(lead_m, pitch_radius_m)
    cb, sb = math.cos(contact_angle_rad), math.sin(contact_angle_rad)
    n2 = [(-cb, -sb), (-cb, sb), (cb, sb), (cb, -sb)][idx]
    e = groove_radius_m - ball_radius_m
    centre = (-e * n2[0], -e * n2[1])
    g0 = math.atan2(n2[1], n2[0])

    def surface(phi, g):
        f = frame_cs3(phi, alpha)
        return (nominal_ball_centre(phi, pitch_radius_m, lead_m)
                + f[:, 0] * (centre[0] + groove_radius_m * math.cos(g))
                + f[:, 2] * (centre[1] + groove_radius_m * math.sin(g)))

    h = step
    s_p = (surface(h, g0) - surface(-h, g0)) / (2 * h)
    s_g = (surface(0, g0 + h) - surface(0, g0 - h)) / (2 * h)
    s_pp = (surface(h, g0) - 2 * surface(0, g0) + surface(-h, g0)) / h ** 2
    s_gg = (surface(0, g0 + h) - 2 * surface(0, g0) + surface(0, g0 - h)) / h ** 2
    s_pg = (surface(h, g0 + h) - surface(h, g0 - h) - surface(-h, g0 + h)
            + surface(-h, g0 - h)) / (4 * h * h)
    f0 = frame_cs3(0.0, alpha)
    n = n2[0] * f0[:, 0] + n2[1] * f0[:, 2]
    # Curvature is positive where the groove bends away from the ball (convex screw).
    second = np.array([[s_pp @ n, s_pg @ n], [s_pg @ n, s_gg @ n]])
    pinv = np.linalg.pinv(np.stack([s_p, s_g], axis=1))
    y = f0[:, 1]
    x = np.cross(y, n)
    basis = [pinv @ x, pinv @ y]
    tensor = np.array([[ca @ second @ cb_ for cb_ in basis] for ca in basis])
    eig = np.linalg.eigvalsh(tensor + np.eye(2) / ball_radius_m)
    return float(eig[0]), float(eig[1])


def hertz_contacts(config):
    """Hertz constants of the screw-side and nut-side contacts (Eq. 53), E* = E/(2(1-nu^2))."""
    g, m = config.geometry, config.material
    e_star = effective_modulus(m.youngs_modulus_pa, m.poisson_ratio)
    r_g = 2.0 * g.conformity * g.ball_radius_m
    out = []
    for name in ("SL", "NR"):
        ca, cb = groove_relative_curvatures(name, g.ball_radius_m, r_g, g.pitch_radius_m,
                                            g.lead_m, g.nominal_contact_angle_rad)
        out.append(HertzContact.from_curvatures(ca, cb, e_star))
    return tuple(out)
