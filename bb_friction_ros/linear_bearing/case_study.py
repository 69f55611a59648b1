"""
The two-ball case of Sec. 2.4 (Fig. 7), numerical and analytical, and its theta x rho maps.

Setup: the bottom groove deviates by theta (dbeta_BL = -theta, dbeta_BR = +theta); the top
groove by (dbeta_TR, dbeta_TL).  Ball 1 is behind and carries N_x = +rho N_y, ball 2 in
front carries -rho N_y, both N_y.  The balls are taken as touching, so B2B contact forms
exactly when ball 1 is faster (Eq. 9).

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Sec. 2.4.1, Fig. 7, Eq. (33), Tables 1-3, Figs. 8-9.

"""

from dataclasses import dataclass
import time

import numpy as np

from bb_friction_ros.linear_bearing import analytical as an
from bb_friction_ros.linear_bearing.geometry import (contact_forces_diagonal,
                                                     contact_forces_rigid,
                                                     deviated_contact_angles, outward_normals)
from bb_friction_ros.linear_bearing.numerical import LinearBearingModel


@dataclass
class PairResult:
    """Outputs of one two-ball case; the first six keys are the CLI's JSON contract."""

    eps: tuple                 # (eps_1, eps_2): each ball alone, fractions of v/2
    f_b2b_n: float
    p_f_w: float               # ball-groove loss of both balls without B2B
    p_b2b_w: float
    converged: bool
    solve_time_s: float
    p_f_with_b2b_w: float      # ball-groove loss of both balls once in contact
    valid: bool                # False: a contact unloaded, or the analytical model's range left
    notes: tuple               # why not valid, in words
    model: str

    def as_json(self):
        """
        Return the CLI's ``--json`` object: contract keys first, then extras.

        An unconverged solve's last iterate is no result: its numbers are null.
        """
        def num(x):
            return float(x) if self.converged else None

        return {"eps": [num(e) for e in self.eps], "f_b2b_n": num(self.f_b2b_n),
                "p_f_w": num(self.p_f_w), "p_b2b_w": num(self.p_b2b_w),
                "converged": bool(self.converged), "solve_time_s": float(self.solve_time_s),
                "p_f_with_b2b_w": num(self.p_f_with_b2b_w),
                "friction_increase": num(self.p_b2b_w / self.p_f_w) if self.p_f_w else None,
                "valid": bool(self.valid), "notes": list(self.notes), "model": self.model}


class LinearPairCase:
    """Sec. 2.4 case studies for one LinearBearingConfig; the numerical model is built once."""

    def __init__(self, cfg):
        """Keep the config; the friction map is built (or loaded) on first numerical use."""
        self.cfg = cfg
        self._model = None
        self._hertz = None

    @property
    def model(self):
        """Return the numerical LinearBearingModel (friction map built lazily)."""
        if self._model is None:
            self._model = LinearBearingModel(self.cfg)
        return self._model

    def loads(self, beta_rad, side_force_n):
        """Contact loads of one ball by the configured statics model  [N]."""
        cfg = self.cfg
        if cfg.contact_force_model == "diagonal":
            return contact_forces_diagonal(cfg.nominal_contact_angle_rad, side_force_n,
                                           cfg.vertical_load_n)
        return contact_forces_rigid(beta_rad, side_force_n, cfg.vertical_load_n)

    def numerical(self, theta_rad, rho, dbeta_tr_rad=0.0, dbeta_tl_rad=0.0, dbeta_bl_rad=None,
                  dbeta_br_rad=None):
        """
        Low-order numerical model (Eqs. 1-10) of the two-ball case.

        Parameters
        ----------
        theta_rad : float
            Bottom-groove deviation theta: dbeta_BL = -theta, dbeta_BR = +theta  [rad]
            (Sec. 2.4.1); must be 0 when ``dbeta_bl_rad`` / ``dbeta_br_rad`` are given.
        rho : float
            Side force ratio N_x / N_y of ball 1; ball 2 carries -rho N_y  [1].
        dbeta_tr_rad, dbeta_tl_rad : float, optional
            Top-groove deviations; (-theta, theta) is Table 2's matched case (b)  [rad].
        dbeta_bl_rad, dbeta_br_rad : float, optional
            The bottom groove's two sides set independently instead of by theta; an unset
            side is 0  [rad].

        Returns
        -------
        PairResult
            eps (fractions of v/2), f_b2b_n [N], p_f_w and p_b2b_w [W] at the configured v,
            converged, valid and the reasons when not valid.

        """
        t0 = time.perf_counter()
        cfg, m = self.cfg, self.model
        if dbeta_bl_rad is None and dbeta_br_rad is None:
            bottom = (-theta_rad, theta_rad)
        elif theta_rad:
            raise ValueError("theta_rad and dbeta_bl_rad/dbeta_br_rad both set the bottom "
                             "groove: give one")
        else:
            bottom = (dbeta_bl_rad or 0.0, dbeta_br_rad or 0.0)
        dbeta = np.array([*bottom, dbeta_tr_rad, dbeta_tl_rad], dtype=float)
        beta = deviated_contact_angles(cfg.nominal_contact_angle_rad, *dbeta)
        ny = cfg.vertical_load_n
        notes = []
        balls = []
        for name, nx in (("ball 1", rho * ny), ("ball 2", -rho * ny)):
            q = self.loads(beta, nx)
            if np.any(q <= cfg.min_contact_load_n):
                notes.append(f"{name}: contact(s) {_names(q <= cfg.min_contact_load_n)} "
                             "unloaded (two-point contact)")
            balls.append(m.ball(beta, q))
        row = m.solve_row(balls, [0.0])
        v_half = 0.5 * cfg.groove_velocity_m_s
        eps = tuple(s.balls[0].v_b_m_s / v_half - 1.0 for s in row.free)
        p_f = sum(float(s.balls[0].loss_w.sum()) for s in row.free)
        p_b2b = sum(float(s.b2b_loss_w.sum()) for s in row.solutions)
        f_b2b = sum(float(s.b2b_force_n.sum()) for s in row.solutions)
        p_f_c = sum(float(b.loss_w.sum()) for s in row.solutions for b in s.balls)
        converged = row.converged and all(s.converged for s in row.free)
        if not converged:
            notes.append("solver did not converge")
        return PairResult(eps, f_b2b, p_f, p_b2b, converged, time.perf_counter() - t0, p_f_c,
                          not notes, tuple(notes), "numerical")

    def analytical(self, theta_rad, rho, dbeta_tr_rad=0.0, dbeta_tl_rad=0.0):
        """
        Analytical model (Eqs. 22, 30, 32) with the paper's diagonal loads; vectorised.

        Parameters
        ----------
        theta_rad, rho, dbeta_tr_rad, dbeta_tl_rad : float or array_like
            As for ``numerical``  [rad], [1], [rad], [rad]; arrays broadcast together.

        Returns
        -------
        PairResult or dict
            A ``PairResult`` for scalar inputs; for arrays, a dict of arrays ``eps1``,
            ``eps2`` [1], ``f_b2b_n`` [N], ``p_f_w``, ``p_b2b_w`` [W] and ``valid``.

        """
        t0 = time.perf_counter()
        cfg = self.cfg
        theta, rho_, tr, tl = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (
            theta_rad, rho, dbeta_tr_rad, dbeta_tl_rad)))
        dbeta = np.stack([-theta, theta, tr, tl], axis=-1)
        b0, ny = cfg.nominal_contact_angle_rad, cfg.vertical_load_n
        hz = self.hertz()
        psi = hz.psi(cfg.ball_radius_m)
        f1 = np.moveaxis(contact_forces_diagonal(b0, rho_ * ny, ny), 0, -1)
        f2 = np.moveaxis(contact_forces_diagonal(b0, -rho_ * ny, ny), 0, -1)
        eps1 = an.velocity_deviation_eq22(dbeta, f1[..., 0], f1[..., 1], b0)
        eps2 = an.velocity_deviation_eq22(dbeta, f2[..., 0], f2[..., 1], b0)
        force = an.b2b_force_eq30(eps1, eps2, f1[..., :2], f2[..., :2], cfg.ball_radius_m, psi,
                                  b0, cfg.friction_coefficient, cfg.k_f)
        p_b2b = an.b2b_loss_eq32(force, cfg.groove_velocity_m_s, b0, cfg.friction_coefficient)
        p_f = sum(an.groove_loss_pure_spin(f, hz.semi_axes(f)[0], hz.ellipticity,
                                           cfg.groove_velocity_m_s, b0, cfg.ball_radius_m,
                                           cfg.friction_coefficient) for f in (f1, f2))
        # Validity (Sec. 2.3.2): four-point contact, checked with the deviated angles by the
        # configured statics, as the numerical model checks it.  The linear range |c/a| < 0.5
        # of Fig. 5 is not made a cutoff: the paper's own case (a) (Table 3, 6 % from FEA)
        # has |c/a| = 0.56 (analytical) to 0.67 (numerical) at its BR contact.
        beta = b0 + dbeta
        four_point = np.ones(theta.shape, dtype=bool)
        for nx in (rho_ * ny, -rho_ * ny):
            four_point &= np.all(_loads_grid(cfg, beta, nx) > cfg.min_contact_load_n, axis=-1)
        # Outside the range of floating point (e.g. N_y = 1e308 N) there is no result.
        finite = np.isfinite(eps1) & np.isfinite(eps2) & np.isfinite(force) \
            & np.isfinite(p_f) & np.isfinite(p_b2b)
        valid = four_point & finite
        elapsed = time.perf_counter() - t0
        if np.ndim(eps1) == 0:
            notes = (() if four_point else ("a contact unloads (two-point contact): outside "
                                            "the analytical model",)) \
                + (() if finite else ("not finite: the inputs overflow floating point",))
            return PairResult((float(eps1), float(eps2)), float(force), float(p_f),
                              float(p_b2b), bool(finite), elapsed, float(p_f), bool(valid),
                              notes, "analytical")
        return {"eps1": eps1, "eps2": eps2, "f_b2b_n": force, "p_f_w": p_f, "p_b2b_w": p_b2b,
                "valid": valid, "solve_time_s": elapsed}

    def hertz(self):
        """Return the Hertz contact of the configured ball and groove (solved once)."""
        if self._hertz is None:
            from bb_friction_ros.contact.hertz import HertzContact
            cfg = self.cfg
            self._hertz = HertzContact.ball_in_straight_groove(
                cfg.ball_radius_m, cfg.conformity, cfg.youngs_modulus_pa, cfg.poisson_ratio)
        return self._hertz

    def numerical_grid(self, theta_rad, rho):
        """
        Figs. 8(a), 9(a), 9(c): numerical model over a theta x rho grid.

        Parameters
        ----------
        theta_rad : array_like, shape (n,)
            Bottom-groove deviations  [rad].
        rho : array_like, shape (m,)
            Side force ratios  [1].

        Returns
        -------
        dict
            Arrays of shape (m, n): ``eps1``, ``eps2`` [1], ``f_b2b_n`` [N], ``p_f_w``,
            ``p_b2b_w`` [W], ``converged`` and ``valid``.

        """
        shape = (len(rho), len(theta_rad))
        out = {k: np.zeros(shape) for k in ("eps1", "eps2", "f_b2b_n", "p_f_w", "p_b2b_w")}
        out["converged"] = np.zeros(shape, dtype=bool)
        out["valid"] = np.zeros(shape, dtype=bool)
        for i, r in enumerate(rho):
            for j, t in enumerate(theta_rad):
                res = self.numerical(t, r)
                out["eps1"][i, j], out["eps2"][i, j] = res.eps
                out["f_b2b_n"][i, j] = res.f_b2b_n
                out["p_f_w"][i, j] = res.p_f_w
                out["p_b2b_w"][i, j] = res.p_b2b_w
                out["converged"][i, j] = res.converged
                out["valid"][i, j] = res.valid
        return out


def _loads_grid(cfg, beta_rad, side_force_n):
    """
    Contact loads (..., 4) of one ball by the configured statics, vectorised  [N].

    The rigid statics of ``geometry.contact_forces_rigid`` by Cramer's rule, so that a grid
    is one call; parallel contact normals (no statics) give non-finite loads.
    """
    ny = cfg.vertical_load_n
    if cfg.contact_force_model == "diagonal":
        return np.moveaxis(contact_forces_diagonal(cfg.nominal_contact_angle_rad,
                                                   side_force_n, ny), 0, -1)
    n = outward_normals(beta_rad)                       # (..., 4, 2)
    rx, ry = -np.asarray(side_force_n, dtype=float), ny

    def solve2(c1, c2, bx, by):     # x1 c1 + x2 c2 = (bx, by)
        det = c1[..., 0] * c2[..., 1] - c2[..., 0] * c1[..., 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            return ((bx * c2[..., 1] - c2[..., 0] * by) / det,
                    (c1[..., 0] * by - bx * c1[..., 1]) / det)

    f_tr, f_tl = solve2(n[..., 2, :], n[..., 3, :], rx, ry)
    f_bl, f_br = solve2(n[..., 0, :], n[..., 1, :], -rx, -ry)
    return np.stack([f_bl, f_br, f_tr, f_tl], axis=-1)


def _names(mask):
    from bb_friction_ros.linear_bearing.geometry import CONTACTS
    return ",".join(c for c, m in zip(CONTACTS, mask) if m)
