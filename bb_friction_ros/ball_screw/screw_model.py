"""
Ball screw model objects and the robust cold start of the ball equilibrium.

With zero preload the balls are in three-point contact (docs/assumptions_ball_screw.md): the
spin about the loaded diagonal is only weakly determined and Newton from a two-point guess can
run away.  A cold start therefore solves one ball with theta = 0 at a reference load per
ball, continues in the load (displacements scale as W^(2/3)) to the actual load, copies the
state to every ball and continues theta (and the lead errors) from zero to their actual
values with all balls coupled.  Every continuation step is a converged Newton solve.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (53)-(55), Table 4.

"""

import math

import numpy as np

from bb_friction_ros.ball_screw.b2b import B2BContactModel
from bb_friction_ros.ball_screw.single_ball import BallGrooveModel, LENGTH_SCALE_M
from bb_friction_ros.ball_screw.solver import EquilibriumSolver, Solution


class ScrewModel:
    """Ball-groove, B2B and solver objects built once from a BallScrewConfig."""

    def __init__(self, config):
        """Build the Hertz constants, friction maps and B2B frames."""
        self.config = config
        self.ball = BallGrooveModel(config)
        self.b2b = B2BContactModel(config, self.ball)
        self.solver = EquilibriumSolver(self.ball, self.b2b, config.solver)

    def preload_load(self):
        """Contact load [N] of a centred ball from the oversize alone (0 without preload)."""
        b = self.ball
        delta = max(b.r_groove - b.r_b - b.free_distance, 0.0)
        return float(b.k_load[0] * delta ** 1.5)

    def max_contact_load_n(self):
        """
        Largest contact load [N] inside the model's range (``config.validity``).

        Per contact type (screw, nut), the load at which the Hertz semi-major axis reaches
        ``max_contact_semi_axis_ratio`` R_B, a = k_a Q^(1/3), and the one at which the peak
        pressure p0 = 3 Q / (2 pi a b) = 3 Q^(1/3) / (2 pi kappa k_a^2) reaches
        ``max_hertz_pressure_pa``; the smallest of the four.
        """
        v = self.config.validity
        r_b = self.ball.r_b
        limits = []
        for h in self.ball.hertz:
            k_a = h.coef_a_m_per_n13
            limits.append((v.max_contact_semi_axis_ratio * r_b / k_a) ** 3)
            limits.append((v.max_hertz_pressure_pa * 2.0 * math.pi * h.ellipticity
                           * k_a * k_a / 3.0) ** 3)
        return float(min(limits))

    def max_axial_load_n(self, n_balls):
        """
        Axial load [N] at which the MEAN contact load of ``n_balls`` reaches the limit.

        Mean contact load of the loaded diagonal: |W| / (N cos(alpha) sin(beta_0)).  With
        geometric errors some balls carry more, so solutions are also checked ball by ball.
        """
        b = self.ball
        return self.max_contact_load_n() * n_balls * b.cos_a * math.sin(b.beta0)

    def force_scale(self, n_balls, axial_load_n):
        """Residual force scale [N]: the larger of the mean axial load per ball and preload."""
        return max(abs(axial_load_n) / n_balls, self.preload_load())

    def cold_start(self, n_balls, sign, axial_load_n):
        """
        Start state: rolling on the diagonal that carries W, with its Hertz approach.

        W > 0 (balls push the nut to +z) loads SL and NR; W < 0 loads SR and NL.
        """
        b = self.ball
        x = b.rolling_guess(n_balls, sign)
        sb, cb = math.sin(b.beta0), math.cos(b.beta0)
        q0 = abs(axial_load_n) / (n_balls * b.cos_a * sb)
        delta = (q0 / b.k_load[0]) ** (2.0 / 3.0)
        side = 1.0 if axial_load_n >= 0.0 else -1.0
        x[:, 0] = -delta * cb / LENGTH_SCALE_M
        x[:, 1] = -side * delta * sb / LENGTH_SCALE_M
        u = -side * 2.0 * delta / (b.cos_a * sb) / LENGTH_SCALE_M
        return x, u

    def cold_solve(self, theta, screw_shift_m, nut_shift_m, sign, axial_load_n):
        """
        Free balls (no B2B) for per-ball theta and profile shifts, from scratch.

        Returns a ``Solution``; ``converged`` is False if any continuation step failed
        (the last converged state is returned then).
        """
        st = self.config.solver
        theta = np.atleast_1d(np.asarray(theta, dtype=float))
        n = theta.size
        none = np.zeros(0, dtype=int)
        zero_set = np.zeros(0, dtype=bool)
        w_ref = math.copysign(st.cold_start_ball_load_n, axial_load_n)
        centres0 = self.ball.arc_centres(np.zeros(1), 0.0, 0.0)
        x, u = self.cold_start(1, sign, w_ref)
        sol = self.solver.solve(x, u, centres0, sign, w_ref, self.force_scale(1, w_ref),
                                none, none, zero_set)
        if not sol.converged:
            sol = self.solver.cold_solve(x, u, centres0, sign, w_ref,
                                         self.force_scale(1, w_ref))
        target = axial_load_n / n
        current = w_ref
        while sol.converged and current != target:
            ratio = target / current
            factor = st.continuation_load_factor
            # A zero load is never reached by geometric steps (they halve towards it without
            # end: a preloaded screw, which converges at every one of them, hung the cold start
            # at 0 N); it is taken in one step from the reference load.
            step = target if 1.0 / factor <= ratio <= factor or ratio <= 0.0 else \
                current * (factor if ratio > 1.0 else 1.0 / factor)
            grow = (step / current) ** (2.0 / 3.0)
            x, u = sol.x.copy(), sol.u * grow
            x[:, :2] *= grow
            current = step
            sol = self.solver.solve(x, u, centres0, sign, current,
                                    self.force_scale(1, current), none, none, zero_set)
        if not sol.converged:
            # Still one ball's state: give each of the n balls a copy, so that a caller's
            # next solve gets arrays of its own size (the compiled kernel does not check
            # bounds; a one-row state read as n rows was undefined memory).
            sol.x = np.repeat(sol.x, n, axis=0)
            return sol
        x, u = np.repeat(sol.x, n, axis=0), sol.u
        screw_shift = np.broadcast_to(np.asarray(screw_shift_m, dtype=float), (n,))
        nut_shift = np.broadcast_to(np.asarray(nut_shift_m, dtype=float), (n,))
        steps = max(1, int(math.ceil(np.abs(theta).max() / st.continuation_theta_step_rad)))
        scale = self.force_scale(n, axial_load_n)
        for k in range(1, steps + 1):
            lam = k / steps
            centres = self.ball.arc_centres(lam * theta, lam * screw_shift, lam * nut_shift)
            sol = self.solver.solve(x, u, centres, sign, axial_load_n, scale, none, none, zero_set)
            if not sol.converged:
                break
            x, u = sol.x, sol.u
        return sol


__all__ = ["ScrewModel", "Solution", "LENGTH_SCALE_M"]
