"""
Ball-to-ball (B2B) contact along the helix (Eqs. 56-61).

Two touching balls sit on the exact helix at the azimuth separation for which their chord is
2 R_B (``geometry.b2b_contact_separation``).  The contact normal is that chord; the contact
is a Coulomb point contact (the B2B contact ellipse is tiny and its spin moment is
neglected, as Eq. 57 does).  The slip of the rear ball relative to the front one at the
contact point is computed with exact 3-D vectors (Eq. 57 is its component form), projected
into the contact plane; the friction force is -mu F slip/|slip| on the rear ball (Eq. 58) and
the loss mu F |slip| (the analogue of Eq. 7).  With equal orbit rates the two balls move by
the same screw motion, an isometry, so the normal relative velocity is exactly zero.

The projected slip is linear in the two balls' states, st = B_r x_r + B_f x_f, and the unit
force terms are affine in its direction e = st/|st|: g = c + K e (``linear_terms``).  The
compiled solver uses this form for the exact derivative of the friction direction.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (56)-(61), Fig. 16.

"""

import numpy as np

from bb_friction_ros.ball_screw import geometry as geo
from bb_friction_ros.ball_screw import kernel

_TINY = 1e-300


class B2BContactModel:
    """B2B contact constants for both directions of motion."""

    def __init__(self, config, ball_model):
        """Chord frames for a front ball ahead in +phi (sign +1) and in -phi (sign -1)."""
        g = config.geometry
        self.ball = ball_model
        self.mu = config.material.friction_coefficient
        self.separation = geo.b2b_contact_separation(g.ball_radius_m, g.lead_m,
                                                     g.pitch_radius_m)
        self.paper_separation = 2.0 * geo.b2b_contact_angle(g.ball_radius_m, g.lead_m,
                                                            g.pitch_radius_m)
        self.frames = {s: geo.b2b_chord_frames(s * self.separation, g.pitch_radius_m,
                                               g.lead_m) for s in (1.0, -1.0)}
        self._linear = {s: self._build_linear(s) for s in (1.0, -1.0)}

    def _build_linear(self, sign):
        """Matrices of ``linear_terms`` for one direction of motion."""
        m_r, m_f, rot = self.frames[sign]
        r_b, ell = self.ball.r_b, self.ball.ell
        eye = np.eye(3)
        a_r = np.zeros((3, 6))
        a_f = np.zeros((3, 6))
        a_r[1, 2] = ell
        a_f[:, 2] = -ell * rot[:, 1]
        for k in range(3):
            a_r[:, 3 + k] = r_b * np.cross(eye[k], m_r)
            a_f[:, 3 + k] = r_b * rot @ np.cross(eye[k], m_f)
        proj = eye - np.outer(m_r, m_r)

        def skew(v):
            return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])

        c_r = np.concatenate([-m_r, np.zeros(3)])
        c_f = np.concatenate([m_f, np.zeros(3)])
        k_r = -self.mu * np.vstack([eye, skew(m_r)])
        k_f = self.mu * np.vstack([eye, -skew(m_f)]) @ rot.T
        terms = (proj @ a_r, proj @ a_f, c_r, c_f, k_r, k_f)
        return tuple(np.ascontiguousarray(v) for v in terms)

    def linear_terms(self, sign):
        """
        Return (B_r, B_f, c_r, c_f, K_r, K_f) for the direction of motion ``sign``.

        Projected slip st = B_r x_r + B_f x_f (3 x 6 each, rows in the rear CS_3); unit force
        terms g_rear = c_r + K_r e and g_front = c_f + K_f e (6, and 6 x 3) with e = st/|st|.
        """
        return self._linear[1.0 if sign > 0 else -1.0]

    def speed(self, x, rear, front, sign):
        """Slip speed |slip| per |omega_N| of the pairs (x[rear], x[front]) (K,)."""
        b_r, b_f = self.linear_terms(sign)[:2]
        return kernel.pair_speed(x, rear, front, b_r, b_f)

    def slip(self, x_rear, x_front, sign):
        """Eq. (57): rear-on-front velocity at each B2B point, as K rows in the rear CS_3."""
        m_r, m_f, rot = self.frames[sign]
        r_b, ell = self.ball.r_b, self.ball.ell
        v_r = np.zeros((x_rear.shape[0], 3))
        v_r[:, 1] = x_rear[:, 2] * ell
        v_f = np.zeros_like(v_r)
        v_f[:, 1] = x_front[:, 2] * ell
        s_rear = v_r + r_b * np.cross(x_rear[:, 3:6], m_r)
        s_front = v_f - r_b * np.cross(x_front[:, 3:6], m_f)
        s = s_rear - s_front @ rot.T
        return s - np.outer(s @ m_r, m_r)

    def unit_terms(self, x_rear, x_front, sign):
        """
        Eqs. (58)-(59) per unit B2B force: (K, 6) force and moment/R_B on rear and front.

        Also returns the slip speed |slip| (K,) per |omega_N|, so that the loss is
        mu F |slip| |omega_N|.
        """
        m_r, m_f, rot = self.frames[sign]
        st = self.slip(x_rear, x_front, sign)
        speed = np.linalg.norm(st, axis=1)
        unit = st / np.maximum(speed, _TINY)[:, None]
        fr_r = -self.mu * unit
        g_rear = np.concatenate([-m_r + fr_r, np.cross(m_r, fr_r)], axis=1)
        fr_f = -fr_r @ rot          # rear-frame vector -> front-frame components
        g_front = np.concatenate([m_f + fr_f, -np.cross(m_f, fr_f)], axis=1)
        return g_rear, g_front, speed
