"""
Single ball in the ball screw: kinematics, Hertz loads, friction and equilibrium (Eqs. 34-55).

All balls of a screw are evaluated at once (arrays over balls, then the four contacts SL, SR,
NR, NL), with the analytic Jacobian of each ball's six equilibrium equations.

State of a ball (6 unknowns, Eq. 55 reduced exactly for circular-arc grooves):
    x = (xi, zeta, w_B, Omega_x, Omega_y, Omega_z)
xi, zeta: ball-centre offset from the nominal helix point along x_3, z_3 in units of
``LENGTH_SCALE_M``; w_B: orbit rate; Omega: the ball's absolute angular velocity in CS_3
components (the paper's omega is Omega - w_B e_z).  Velocities are normalised by |omega_N|,
so they carry the sign s = sign(omega_N); quasi-static Coulomb friction is rate independent.
The global unknown u is the nut's axial displacement relative to the screw (same unit as xi):
it shifts the nut groove profile by u cos(alpha) along z_3.

Kinematics use exact 3-D vectors at the kinematic contact point q = R_B n from the nominal
ball centre (as Eqs. 37-40 do): the ball centre moves along the helix, the nut groove by the
screw motion (omega_N about z, p/2pi omega_N along z).  With n in the cross-section plane the
normal relative velocity at every contact is then exactly zero, so the power balance
omega_N T_f = sum of losses holds to solver precision.  Contact-plane frame of the sphere map:
Y = y_3 (rolling), X = Y x n (across the groove), Z = n.  In it (Eq. 44 without its typos):
    V_X = R_B (Omega_y - g s sin(alpha))
    V_Y = w_B l + R_B (Omega_z n_x - Omega_x n_z) - g s (l + R_B cos(alpha) n_x)
    w   = Omega_x n_x + Omega_z n_z - g s cos(alpha) n_z
with l = L / 2pi and g = 1 on the nut, 0 on the screw.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (34)-(55), (A9)-(A11), Figs. 13-14.

"""

import math

import numpy as np

from bb_friction_ros.ball_screw import geometry as geo
from bb_friction_ros.contact.friction_maps import FrictionMapSphere

LENGTH_SCALE_M = 1e-6   # unit of the displacement unknowns: keeps the Jacobian well scaled
N_STATE = 6
_TINY = 1e-300
_ANGLE_SIGN = np.array([-1.0, 1.0, 1.0, -1.0])   # beta_i from n: SL and NL lie at -z_3


class BallGrooveModel:
    """Load-independent constants of ball-groove contact and the batched equilibrium."""

    def __init__(self, config):
        """Derive helix, Hertz and friction-map constants from a BallScrewConfig."""
        g, m, s = config.geometry, config.material, config.solver
        self.config = config
        self.r_b = g.ball_radius_m
        self.r_groove = 2.0 * g.conformity * g.ball_radius_m
        self.beta0 = g.nominal_contact_angle_rad
        self.alpha = geo.lead_angle(g.lead_m, g.pitch_radius_m)
        self.sin_a, self.cos_a = math.sin(self.alpha), math.cos(self.alpha)
        self.ell = geo.helix_length_per_turn(g.lead_m, g.pitch_radius_m) / (2.0 * math.pi)
        self.r_gear = g.lead_m / (2.0 * math.pi)
        self.mu = m.friction_coefficient
        # Centre distance ball-arc at first touch; the oversize preloads all four contacts.
        self.free_distance = self.r_groove - self.r_b - 0.5 * g.ball_oversize_m
        self.hertz = geo.hertz_contacts(config)
        self.maps = tuple(FrictionMapSphere(h.ellipticity, s.map_polar_nodes,
                                            s.map_azimuth_nodes) for h in self.hertz)
        kd = np.array([h.coef_delta_m_per_n23 for h in self.hertz])
        ka = np.array([h.coef_a_m_per_n13 for h in self.hertz])
        self.k_load = np.repeat(kd ** -1.5, 2)      # Q = k_load delta^1.5, per contact
        self.k_axis = np.repeat(ka, 2)              # a = k_axis Q^(1/3)
        self.on_nut = geo.ON_NUT

    def arc_centres(self, theta, screw_shift_m, nut_shift_m):
        """Arc centres (N, 4, 2) for per-ball theta and profile shifts (z_3, metres)."""
        return geo.arc_centres(theta, screw_shift_m, nut_shift_m, self.r_groove, self.r_b,
                               self.beta0)

    def evaluate(self, x, u, centres, sign, jacobian=True, extra_oversize_m=0.0):
        """
        Eqs. (44), (48)-(54) for all balls: forces, moments, loss, nut torque, axial force.

        x: (N, 6) states; u: nut axial displacement [LENGTH_SCALE_M]; centres: (N, 4, 2) arc
        centres without u; sign: sign of omega_N (+1 or -1); ``extra_oversize_m`` adds a
        temporary ball oversize (used only by the solver's preload continuation).  Returns:
        force, moment (N, 3) on each ball from its grooves; loss (N,) per |omega_N| [N m];
        nut_torque (N,) [N m]; axial (N,) = z-force of the nut on the ball [N]; load (N, 4);
        angle (N, 4) contact angles; and with ``jacobian`` d_force, d_moment (N, 3, 7) and
        d_axial (N, 7), columns = the 6 states then u.
        """
        lam = LENGTH_SCALE_M
        r_b, ca, sa, ell, mu = self.r_b, self.cos_a, self.sin_a, self.ell, self.mu
        nb = x.shape[0]
        gs = self.on_nut * sign                                  # (4,)
        dx = lam * x[:, 0:1] - centres[..., 0]
        dz = lam * x[:, 1:2] - centres[..., 1] - self.on_nut * (lam * ca * u)
        dist = np.hypot(dx, dz)
        nx, nz = dx / dist, dz / dist
        delta = dist - (self.free_distance - 0.5 * extra_oversize_m)
        pos = delta > 0.0
        dpos = np.where(pos, delta, 0.0)
        sq = np.sqrt(dpos)
        q = self.k_load * dpos * sq
        a = self.k_axis * np.cbrt(q)
        a_safe = np.maximum(a, self.k_axis * 1e-9)
        wb, ox, oy, oz = x[:, 2:3], x[:, 3:4], x[:, 4:5], x[:, 5:6]
        vx = r_b * (oy - gs * sa)
        vy = wb * ell + r_b * (oz * nx - ox * nz) - gs * (ell + r_b * ca * nx)
        w = ox * nx + oz * nz - gs * ca * nz
        rx, ry = vx / a_safe, vy / a_safe
        rho = np.maximum(np.hypot(rx, ry), _TINY)
        s = np.hypot(rho, w)
        t = np.arctan2(rho, w)
        h = np.arctan2(ry, rx)
        val = np.empty((4, nb, 4))
        dvt = np.empty_like(val)
        dvh = np.empty_like(val)
        for k, cols in enumerate((slice(0, 2), slice(2, 4))):
            v_, t_, h_ = self.maps[k].evaluate_angles(t[:, cols], h[:, cols])
            val[:, :, cols], dvt[:, :, cols], dvh[:, :, cols] = v_, t_, h_
        fx, fy, mm, pp = val
        p_ = mu * q
        am = a * mm
        force = np.stack([-q * nx + p_ * fx * nz, p_ * fy, -q * nz - p_ * fx * nx], axis=-1)
        moment = np.stack([p_ * (-r_b * fy * nz + am * nx), p_ * r_b * fx,
                           p_ * (r_b * fy * nx + am * nz)], axis=-1)
        loss_c = p_ * a * s * pp
        # Nut torque: e_z . (P x F) + M_Z n . e_z, P = q_B + R_B n (Eqs. 35, 37); the lever
        # R_B n of the friction force is inside P x F, so only the spin moment is added.
        lever = np.stack([r_b * sa * nz, ell - self.r_gear * sa + r_b * ca * nx,
                          -self.r_gear * ca - r_b * sa * nx], axis=-1)
        torque_c = self.on_nut * (np.sum(force * lever, axis=-1) + p_ * am * nz * ca)
        axial_c = self.on_nut * (force[..., 1] * sa + force[..., 2] * ca)
        out = {
            "force": force.sum(axis=1), "moment": moment.sum(axis=1),
            "loss": loss_c.sum(axis=1), "nut_torque": torque_c.sum(axis=1),
            "axial": axial_c.sum(axis=1), "load": q, "contact_loss": loss_c,
            "angle": np.arctan2(_ANGLE_SIGN * nz, np.abs(nx)),
        }
        if not jacobian:
            return out
        # --- analytic Jacobian, columns (xi, zeta, w_B, Om_x, Om_y, Om_z, u) ---
        zero = np.zeros((nb, 4, 7))
        ddx = zero.copy()
        ddx[..., 0] = lam
        ddz = zero.copy()
        ddz[..., 1] = lam
        ddz[..., 6] = -self.on_nut * lam * ca
        dn_l = (nx[..., None] * ddx + nz[..., None] * ddz)
        inv = (1.0 / dist)[..., None]
        dnx = (ddx - nx[..., None] * dn_l) * inv
        dnz = (ddz - nz[..., None] * dn_l) * inv
        dq = (1.5 * self.k_load * sq)[..., None] * dn_l
        with np.errstate(divide="ignore", invalid="ignore"):
            a_over_3q = np.where(pos & (q > 0), a / (3.0 * np.where(q > 0, q, 1.0)), 0.0)
        da = a_over_3q[..., None] * dq
        dvx = zero.copy()
        dvx[..., 4] = r_b
        dvy = (r_b * (oz - gs * ca))[..., None] * dnx - (r_b * ox)[..., None] * dnz
        dvy[..., 2] += ell
        dvy[..., 5] += r_b * nx
        dvy[..., 3] -= r_b * nz
        dw = ox[..., None] * dnx + (oz - gs * ca)[..., None] * dnz
        dw[..., 3] += nx
        dw[..., 5] += nz
        ia = (1.0 / a_safe)[..., None]
        drx = (dvx - rx[..., None] * da) * ia
        dry = (dvy - ry[..., None] * da) * ia
        rr = rho[..., None]
        dt = (w[..., None] * (rx[..., None] * drx + ry[..., None] * dry) / rr
              - rr * dw) / (s * s)[..., None]
        dh = (rx[..., None] * dry - ry[..., None] * drx) / (rr * rr)
        dfx = dvt[0][..., None] * dt + dvh[0][..., None] * dh
        dfy = dvt[1][..., None] * dt + dvh[1][..., None] * dh
        dmm = dvt[2][..., None] * dt + dvh[2][..., None] * dh
        dp_ = mu * dq
        dam = mm[..., None] * da + a[..., None] * dmm
        e = lambda arr: arr[..., None]   # noqa: E731  (broadcast a per-contact scalar)
        d_fx = (-dq * e(nx) - e(q) * dnx + dp_ * e(fx * nz) + e(p_ * nz) * dfx
                + e(p_ * fx) * dnz)
        d_fy = dp_ * e(fy) + e(p_) * dfy
        d_fz = (-dq * e(nz) - e(q) * dnz - dp_ * e(fx * nx) - e(p_ * nx) * dfx
                - e(p_ * fx) * dnx)
        d_mx = (dp_ * e(-r_b * fy * nz + am * nx)
                + e(p_) * (-r_b * (dfy * e(nz) + e(fy) * dnz) + dam * e(nx) + e(am) * dnx))
        d_my = r_b * (dp_ * e(fx) + e(p_) * dfx)
        d_mz = (dp_ * e(r_b * fy * nx + am * nz)
                + e(p_) * (r_b * (dfy * e(nx) + e(fy) * dnx) + dam * e(nz) + e(am) * dnz))
        out["d_force"] = np.stack([d_fx.sum(1), d_fy.sum(1), d_fz.sum(1)], axis=1)
        out["d_moment"] = np.stack([d_mx.sum(1), d_my.sum(1), d_mz.sum(1)], axis=1)
        out["d_axial"] = (self.on_nut[:, None] * (d_fy * sa + d_fz * ca)).sum(axis=1)
        return out

    def rolling_guess(self, n_balls, sign, loaded_sl_nr=True):
        """Start state: rolling without slip on the loaded diagonal, spin along z_3."""
        cb = math.cos(self.beta0)
        wb = sign * (0.5 + self.r_b * self.cos_a * cb / (2.0 * self.ell))
        x = np.zeros((n_balls, N_STATE))
        x[:, 2] = wb
        x[:, 5] = wb * self.ell / (self.r_b * cb)
        x[:, 4] = 0.5 * sign * self.sin_a
        return x
