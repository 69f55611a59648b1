"""
Low-order numerical model, Eqs. (1)-(10): single balls and B2B contact groups in a row.

Each ball has the unknowns v_B, w_x, w_y (w_z = 0, Sec. 2.1); a group of g touching balls
shares v_B and adds g - 1 B2B forces (Eq. 9): 3g equations in 3g unknowns.  The kinematics
are written with vectors rather than the paper's per-contact component formulas: for contact
i with outward normal n_i and centre P_i = R_B n_i,
    slip at the centre  V_i = (v_B - v_groove,i) z + Omega x P_i       (along z only)
    spin               w_i = Omega . n_i
which is Eqs. (1)-(3), (A1)-(A3) with one sign convention for all four contacts.  The friction
force (along z) and the moment about n_i come from the friction map (Eqs. A4-A7).

Newton with an analytic Jacobian: measured 3.6 ms per two-ball solve with scipy's fsolve
against well under 1 ms here, which is what lets the whole-screw and live models afford it.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (1)-(10) and (A1)-(A3), Secs. 2.1-2.2, Fig. 4.

"""

from dataclasses import dataclass, field
import math

import numpy as np

from bb_friction_ros.contact.friction_maps import FrictionMapLine
from bb_friction_ros.contact.hertz import HertzContact
from bb_friction_ros.linear_bearing import kernel
from bb_friction_ros.linear_bearing.geometry import TOP, outward_normals


@dataclass
class Ball:
    """One ball's contact set: contact angles [rad], normal loads [N] and Hertz semi-axes [m]."""

    beta_rad: np.ndarray
    load_n: np.ndarray
    semi_major_m: np.ndarray

    def __post_init__(self):
        """Derive the contact normals once."""
        self.normals = outward_normals(self.beta_rad)
        self.loaded = self.load_n > 0.0


@dataclass
class BallMotion:
    """Solved motion and friction of one ball."""

    v_b_m_s: float
    omega_rad_s: np.ndarray              # (w_x, w_y)
    friction_n: np.ndarray               # z-force on the ball at each contact
    moment_nm: np.ndarray                # moment about each contact normal
    loss_w: np.ndarray                   # friction loss at each contact
    c_over_a: np.ndarray                 # paper's velocity-centre offset (inf: pure sliding)


@dataclass
class GroupSolution:
    """Solution of one group of touching balls (a single free ball is a group of one)."""

    balls: list
    b2b_force_n: np.ndarray              # g - 1 forces, rear-front pairs, >= 0 if valid
    b2b_slip_m_s: np.ndarray             # |relative velocity| at each B2B contact, Eq. (5)
    b2b_loss_w: np.ndarray               # Eq. (7)
    converged: bool
    residual: float
    iterations: int
    z: np.ndarray = field(repr=False, default=None)   # scaled unknowns, for warm starts


class LinearBearingModel:
    """Numerical model of balls between a fixed bottom rail and a top groove moving at v."""

    def __init__(self, cfg):
        """Build the Hertz contact and the friction map for ``cfg`` (LinearBearingConfig)."""
        self.cfg = cfg
        self.hertz = HertzContact.ball_in_straight_groove(
            cfg.ball_radius_m, cfg.conformity, cfg.youngs_modulus_pa, cfg.poisson_ratio)
        self.fmap = FrictionMapLine(self.hertz.ellipticity, n_nodes=cfg.map_nodes)
        # Compiled Newton (``kernel.solve_group``); the numpy path without numba, or with
        # ``use_kernel = False`` (the reference the tests compare with).
        self.use_kernel = kernel.HAVE_NUMBA
        self._vg = np.where(TOP, cfg.groove_velocity_m_s, 0.0)

    def ball(self, beta_rad, load_n):
        """Make a Ball from contact angles and normal loads (loads below the threshold unload)."""
        load = np.where(np.asarray(load_n, float) > self.cfg.min_contact_load_n,
                        np.asarray(load_n, float), 0.0)
        a, _ = self.hertz.semi_axes(load)
        return Ball(np.asarray(beta_rad, float), load, a)

    # --- kinematics and equilibrium of a group -------------------------------------------
    def _prepare(self, balls):
        """Stack the group's load-dependent arrays once per solve (they are fixed in it)."""
        q = np.array([b.load_n for b in balls])
        loaded = q > 0.0
        a = np.array([b.semi_major_m for b in balls])
        return {"nx": np.array([b.normals[:, 0] for b in balls]),     # (g, 4)
                "ny": np.array([b.normals[:, 1] for b in balls]),
                "q": q, "a": a, "loaded": loaded, "a_safe": np.where(loaded, a, 1.0),
                "q_ref": self._q_ref(balls), "g": len(balls)}

    def _residual(self, balls, z, v, jacobian=True, prep=None):
        """Scaled residuals and Jacobian of a group (see ``_residual_impl``)."""
        with np.errstate(over="ignore", invalid="ignore"):
            return self._residual_impl(prep or self._prepare(balls), z, v, jacobian)

    def _residual_impl(self, prep, z, v, jacobian):
        """
        Scaled equilibrium residuals (3 per ball) and their Jacobian for a group.

        z = [v_B/v, (w_x R/v, w_y R/v) per ball, F_B2B/(mu Q_ref) per contact].
        Residuals: z-force, x-moment/R, y-moment/R of each ball, divided by mu Q_ref.
        """
        g = prep["g"]
        cfg = self.cfg
        r_b, mu = cfg.ball_radius_m, cfg.friction_coefficient
        q_ref = prep["q_ref"]
        nx, ny, q, a = prep["nx"], prep["ny"], prep["q"], prep["a"]
        loaded, a_safe = prep["loaded"], prep["a_safe"]
        wx = z[1:1 + 2 * g:2][:, None] * (v / r_b)
        wy = z[2:2 + 2 * g:2][:, None] * (v / r_b)
        vg = np.where(TOP, v, 0.0)[None, :]
        slip = z[0] * v - vg + r_b * (wx * ny - wy * nx)        # V_i along z
        spin = wx * nx + wy * ny                                 # w_i
        y = slip / a_safe
        u = np.arctan2(y, spin)
        val, der = self.fmap.evaluate(u, derivative=True)
        fz = np.where(loaded, mu * q * val[0], 0.0) / (mu * q_ref)        # scaled z-force
        mom = np.where(loaded, mu * q * a * val[1], 0.0) / (mu * q_ref * r_b)  # scaled M / R
        res = np.empty(3 * g)
        res[0::3] = fz.sum(axis=1)
        res[1::3] = (ny * fz + nx * mom).sum(axis=1)
        res[2::3] = (-nx * fz + ny * mom).sum(axis=1)

        # B2B contacts between ball j (rear) and j+1 (front): Eqs. (5)-(8).
        fb = z[1 + 2 * g:]
        res[0:3 * g - 3:3] -= fb
        res[3::3] += fb
        dvx = (z[2:2 * g:2] + z[4:2 * g + 2:2])        # (w_y,j + w_y,j+1) R / v
        dvy = -(z[1:2 * g - 1:2] + z[3:2 * g + 1:2])   # -(w_x,j + w_x,j+1) R / v
        dvn = np.hypot(dvx, dvy)
        dvn_safe = np.where(dvn > 0, dvn, 1.0)
        tx, ty = -dvx / dvn_safe, -dvy / dvn_safe      # friction direction on the rear ball
        # moment R z x f, f = mu F t, on both balls: R (-f_y, f_x); scaled by mu Q_ref R
        # it is mu * fb * (-t_y, t_x) since fb = F / (mu Q_ref).
        for j in range(g - 1):
            for k in (j, j + 1):
                res[3 * k + 1] += -mu * fb[j] * ty[j]
                res[3 * k + 2] += mu * fb[j] * tx[j]
        if not jacobian:
            return res, None

        # d u / d(slip), d u / d(spin)
        s2 = y * y + spin * spin
        s2_safe = np.where(s2 > 0, s2, 1.0)
        du_dslip = spin / (a_safe * s2_safe)
        du_dspin = -y / s2_safe
        dslip = [np.full_like(nx, v), v * ny, -v * nx]           # d slip / d(z0, zx, zy)
        dspin = [np.zeros_like(nx), (v / r_b) * nx, (v / r_b) * ny]
        jac = np.zeros((3 * g, 3 * g))
        rows_idx = np.arange(3 * g)
        for col in range(3):
            du = du_dslip * dslip[col] + du_dspin * dspin[col]
            dfz = np.where(loaded, mu * q * der[0] * du, 0.0) / (mu * q_ref)
            dmom = np.where(loaded, mu * q * a * der[1] * du, 0.0) / (mu * q_ref * r_b)
            rows = np.stack([dfz.sum(axis=1), (ny * dfz + nx * dmom).sum(axis=1),
                             (-nx * dfz + ny * dmom).sum(axis=1)], axis=1).ravel()
            cols = 0 if col == 0 else 1 + 2 * (rows_idx // 3) + (col - 1)
            jac[rows_idx, cols] += rows
        for j in range(g - 1):
            cf = 1 + 2 * g + j
            jac[3 * j, cf] -= 1.0
            jac[3 * j + 3, cf] += 1.0
            # d(t)/d(dv) = -(I - t t^T)/|dv| applied to dv = (wy_j + wy_k, -(wx_j + wx_k))
            inv = 1.0 / dvn_safe[j]
            dtx_ddvx, dtx_ddvy = -(1 - tx[j] ** 2) * inv, tx[j] * ty[j] * inv
            dty_ddvx, dty_ddvy = tx[j] * ty[j] * inv, -(1 - ty[j] ** 2) * inv
            mfb = mu * fb[j]
            for k in (j, j + 1):
                jac[3 * k + 1, cf] += -mu * ty[j]
                jac[3 * k + 2, cf] += mu * tx[j]
                for m in (j, j + 1):
                    cwx, cwy = 1 + 2 * m, 2 + 2 * m
                    # dvx grows with w_y (+1), dvy with w_x (-1)
                    jac[3 * k + 1, cwy] += -mfb * dty_ddvx
                    jac[3 * k + 1, cwx] += mfb * dty_ddvy
                    jac[3 * k + 2, cwy] += mfb * dtx_ddvx
                    jac[3 * k + 2, cwx] += -mfb * dtx_ddvy
        return res, jac

    def _q_ref(self, balls):
        return max(float(np.max(b.load_n)) for b in balls)

    def initial_guess(self, balls):
        """Pure rolling about x at the nominal angle, zero B2B force."""
        g = len(balls)
        z = np.zeros(3 * g)
        z[0] = 0.5
        z[1:1 + 2 * g:2] = 0.5 / math.cos(self.cfg.nominal_contact_angle_rad)
        return z

    def solve_group(self, balls, z0=None, max_iter=60):
        """Solve the 3g equilibrium equations of a group of g touching balls (Eqs. 8-10)."""
        v = self.cfg.groove_velocity_m_s
        z = self.initial_guess(balls) if z0 is None else np.array(z0, dtype=float)
        tol = self.cfg.solver_tolerance
        prep = self._prepare(balls)
        if self.use_kernel:
            cfg = self.cfg
            z, norm, it = kernel.solve_group(
                z, prep["nx"], prep["ny"], prep["q"], prep["a"], self._vg, v,
                cfg.ball_radius_m, cfg.friction_coefficient, prep["q_ref"],
                *self.fmap.hermite_tables, tol, max_iter)
            return self._unpack(balls, z, v, converged=bool(norm <= tol),
                                residual=float(norm), iterations=int(it), prep=prep)
        res, jac = self._residual(balls, z, v, prep=prep)
        norm = np.max(np.abs(res))
        it = 0
        while norm > tol and it < max_iter:
            it += 1
            try:
                step = np.linalg.solve(jac, -res)
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(jac, -res, rcond=None)[0]
            lam = 1.0
            while True:       # backtracking keeps Newton honest far from the solution
                z_new = z + lam * step
                res_new, jac_new = self._residual(balls, z_new, v, prep=prep)
                norm_new = np.max(np.abs(res_new))
                if norm_new < (1.0 - 1e-4 * lam) * norm or lam < 1e-4:
                    break
                lam *= 0.5
            z, res, jac, norm = z_new, res_new, jac_new, norm_new
        return self._unpack(balls, z, v, converged=bool(norm <= tol), residual=float(norm),
                            iterations=it)

    def _unpack(self, balls, z, v, converged, residual, iterations, prep=None):
        cfg = self.cfg
        r_b, mu = cfg.ball_radius_m, cfg.friction_coefficient
        g = len(balls)
        q_ref = self._q_ref(balls)
        motions = []
        if self.use_kernel and prep is not None:
            fz, mom, loss, c_over_a = kernel.group_outputs(
                z, prep["nx"], prep["ny"], prep["q"], prep["a"], self._vg, v, r_b, mu,
                *self.fmap.hermite_tables)
            k_w = v / r_b
            motions = [BallMotion(z[0] * v, np.array([z[1 + 2 * j] * k_w, z[2 + 2 * j] * k_w]),
                                  fz[j], mom[j], loss[j], c_over_a[j]) for j in range(g)]
        for j, b in enumerate(balls if not motions else ()):
            wx, wy = z[1 + 2 * j] * v / r_b, z[2 + 2 * j] * v / r_b
            nx, ny = b.normals[:, 0], b.normals[:, 1]
            slip = z[0] * v - np.where(TOP, v, 0.0) + r_b * (wx * ny - wy * nx)
            spin = wx * nx + wy * ny
            a_safe = np.where(b.loaded, b.semi_major_m, 1.0)
            u = np.arctan2(slip / a_safe, spin)
            val = self.fmap.evaluate(u)
            fz = np.where(b.loaded, mu * b.load_n * val[0], 0.0)
            mom = np.where(b.loaded, mu * b.load_n * b.semi_major_m * val[1], 0.0)
            # Loss from the map identity P = -(F V + w M): exact power bookkeeping.
            loss = -(fz * slip + mom * spin)
            with np.errstate(divide="ignore", invalid="ignore"):
                c_over_a = np.where(b.loaded, -slip / (spin * a_safe), np.nan)
            motions.append(BallMotion(z[0] * v, np.array([wx, wy]), fz, mom, loss, c_over_a))
        fb = z[1 + 2 * g:] * mu * q_ref
        dv = np.array([math.hypot(z[2 + 2 * j] + z[4 + 2 * j], z[1 + 2 * j] + z[3 + 2 * j])
                       for j in range(g - 1)]) * v
        return GroupSolution(motions, fb, dv, mu * fb * dv, converged, residual, iterations,
                             z.copy())

    def solve_ball(self, ball, z0=None):
        """Eqs. (1)-(4): one free ball."""
        return self.solve_group([ball], z0)

    # --- many balls in a row: complementarity by active set ------------------------------
    def solve_row(self, balls, gaps_m, max_sweeps=None):
        """
        Eqs. (9)-(10) for balls ordered rear (index 0) to front along +z.

        A pair (j, j+1) is in contact iff its gap is closed and, with the contact, the B2B
        force is >= 0; without it, ball j must not be faster than ball j+1.  Solved exactly
        by an active-set loop over groups (each group by Newton).
        """
        n = len(balls)
        gaps = np.asarray(gaps_m, dtype=float)
        closed = gaps <= self.cfg.b2b_gap_tolerance_m
        free = [self.solve_ball(b) for b in balls]
        v0 = np.array([s.balls[0].v_b_m_s for s in free])
        active = closed & (v0[:-1] > v0[1:])
        tol_v = 1e-12 * self.cfg.groove_velocity_m_s
        max_sweeps = max_sweeps or 2 * n + 2
        groups, sols = None, None
        for _ in range(max_sweeps):
            groups = _split_groups(active)
            sols = []
            for grp in groups:
                if len(grp) == 1:
                    sols.append(free[grp[0]])
                    continue
                z0 = np.concatenate([[np.mean([free[i].z[0] for i in grp])],
                                     np.concatenate([free[i].z[1:3] for i in grp]),
                                     np.zeros(len(grp) - 1)])
                sols.append(self.solve_group([balls[i] for i in grp], z0))
            changed = False
            # release the most tensile contact first
            worst, worst_f = None, 0.0
            for grp, sol in zip(groups, sols):
                for k, f in enumerate(sol.b2b_force_n):
                    if f < worst_f:
                        worst, worst_f = grp[k], f
            if worst is not None:
                active[worst] = False
                changed = True
            else:
                vel = np.empty(n)
                for grp, sol in zip(groups, sols):
                    vel[grp] = sol.balls[0].v_b_m_s
                for j in range(n - 1):
                    if closed[j] and not active[j] and vel[j] > vel[j + 1] + tol_v:
                        active[j] = True
                        changed = True
            if not changed:
                return RowSolution(groups, sols, free, True)
        return RowSolution(groups, sols, free, False)


@dataclass
class RowSolution:
    """Balls in a row: contact groups (ball indices rear first) with their solutions."""

    groups: list
    solutions: list
    free: list                  # each ball alone, before contact
    complementarity_ok: bool

    @property
    def converged(self):
        """Return True if the active set settled and every group's Newton converged."""
        return self.complementarity_ok and all(s.converged for s in self.solutions)


def _split_groups(active):
    """Consecutive runs of balls joined by active contacts: [[0, 1], [2], ...]."""
    groups, cur = [], [0]
    for j, on in enumerate(active):
        if on:
            cur.append(j + 1)
        else:
            groups.append(cur)
            cur = [j + 1]
    groups.append(cur)
    return groups
