"""
Quasi-static equilibrium of a set of balls with B2B contact: Newton + active set (Eqs. 54-61).

Unknowns: the six states of every ball, the nut axial displacement u (shared: the axial load
is carried by all balls) and the normal force of every active B2B contact.  Equations: six
equilibrium equations per ball (Eq. 54 plus the B2B terms of Eq. 59), the axial balance of
the nut, and equal orbit rates across each active contact (Eq. 60).

Block structure: a ball's equations involve only its own state, u and the forces of its (at
most two) B2B contacts.  Two implementations of the Newton iteration for one active set:

- ``kernel.newton`` (numba, the default; one iteration for the rigid and the elastic load
  path, ``kernel.solve_active`` / ``solve_active_elastic`` call it): exact Jacobian, including
  the derivatives of the B2B friction direction, which couple touching balls.  The system is
  block tridiagonal along each chain (blocks of a ball's six states and the force of the
  contact behind it), bordered by u.  A block Thomas sweep per chain and a Schur complement
  for u solve it, so the cost per iteration is linear in the number of balls, and convergence
  stays quadratic along long chains.
- The numpy path (when numba is missing, or ``use_kernel = False``): all the 6x6 ball blocks
  are solved at once (batched LAPACK).  This leaves a tridiagonal system in the B2B forces,
  bordered by u, and u is eliminated by a Schur complement.  The direction of the B2B
  friction is held at its current value in the Jacobian (its residual is exact).  That keeps
  the blocks independent and costs contraction, not accuracy.

Both stop at the same residual tolerance and use the same trust region and line search.

Complementarity (Eq. 61) is solved exactly by an active set: a contact with a negative force
is released, a touching inactive pair whose rear ball orbits faster is closed, until neither
happens.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (54)-(61).

"""

from dataclasses import dataclass, field

import numpy as np

from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.single_ball import LENGTH_SCALE_M, N_STATE


def _solve_blocks(a, b):
    """Batched solve of a @ x = b; singular blocks get a Levenberg-Marquardt shift."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        eye = np.eye(a.shape[-1])
        shift = np.finfo(float).eps ** 0.5 * np.abs(a).max(axis=(-2, -1), keepdims=True)
        return np.linalg.solve(a + shift * eye, b)


def kernel_terms(terms, per_contact):
    """
    Return the kernels' (N, 10) ball and (N, 4, 3) contact terms as ``evaluate``'s dict.

    Without "angle": the compiled solve does not compute the contact angles, which no output
    reads (``kernel.contact_angles`` on demand).
    """
    return {"force": terms[:, 0:3], "moment": terms[:, 3:6], "loss": terms[:, 6],
            "nut_torque": terms[:, 7], "axial": terms[:, 8], "load": per_contact[..., 0],
            "contact_loss": per_contact[..., 1]}


@dataclass
class Solution:
    """Result of one equilibrium solve (states normalised as in ``single_ball``)."""

    x: np.ndarray
    u: float
    forces: np.ndarray          # B2B forces [N], per candidate pair (0 when inactive)
    active: np.ndarray          # bool per candidate pair
    converged: bool
    iterations: int
    residual: float
    terms: dict = field(default_factory=dict)     # last ``BallGrooveModel.evaluate`` output
    b2b_speed: np.ndarray = None                  # slip speed per candidate pair
    budget_exhausted: bool = False                # stopped by ``max_total_iterations``


class _ColdStart:
    """
    The cold start of ``EquilibriumSolver``: free balls brought to equilibrium in stages.

    Geometry first with the rates frozen, then the rates with the geometry frozen, then
    Newton on everything (``cold_solve``); the warm steps never come here.
    """

    def _stage_geometry(self, x, u, centres, sign, axial_load_n, scale):
        """
        Cold-start stage: move balls and nut to balance the cross-section forces.

        Rates frozen; unknowns (xi, zeta) per ball and u; equations F_x, F_z per ball and the
        axial balance.  Brings the ball into its (three-point) contact state before the
        weakly determined spin about the loaded diagonal is touched (geometry first with mu = 0
        and the rates frozen, then the rates, then everything: the order that converged for an
        independent re-implementation, docs/assumptions_ball_screw.md, Solver).
        """
        st = self.settings
        rows, cols = [0, 2], [0, 1]
        limit = max(self.disp_limit, self._approach_units(scale))
        for _ in range(st.max_iterations):
            t = self.ball.evaluate(x, u, centres, sign, True, self.extra_oversize_m)
            res = t["force"][:, rows] / scale
            axial = (t["axial"].sum() + axial_load_n) / scale
            if max(np.abs(res).max(), abs(axial)) <= st.tolerance:
                break
            jac = t["d_force"][:, rows, :] / scale
            blk = jac[:, :, cols]
            y = _solve_blocks(blk, res[..., None])[..., 0]
            z = _solve_blocks(blk, jac[:, :, N_STATE:N_STATE + 1])[..., 0]
            a_row = t["d_axial"][:, cols] / scale
            c_u = t["d_axial"][:, N_STATE].sum() / scale
            schur = np.einsum("ij,ij->", a_row, z) - c_u
            du = (axial - np.einsum("ij,ij->", a_row, y)) / schur
            dx = -(y + z * du)
            big = max(np.abs(dx).max(), abs(du)) / limit
            step = 1.0 / big if big > 1.0 else 1.0
            x = x.copy()
            x[:, cols] += step * dx
            u = u + step * du
        return x, u

    def _stage_rates(self, x, u, centres, sign, scale):
        """Cold-start stage: orbit and spin rates with the geometry frozen (4 x 4 per ball)."""
        st = self.settings
        rows, cols = [1, 3, 4, 5], [2, 3, 4, 5]
        r_b = self.ball.r_b
        for _ in range(st.max_iterations):
            t = self.ball.evaluate(x, u, centres, sign, True, self.extra_oversize_m)
            res = np.concatenate([t["force"], t["moment"] / r_b], axis=1)[:, rows] / scale
            if np.abs(res).max() <= st.tolerance:
                break
            jac = np.concatenate([t["d_force"], t["d_moment"] / r_b], axis=1)[:, rows, :]
            dx = -_solve_blocks(jac[:, :, cols] / scale, res[..., None])[..., 0]
            big = np.abs(dx).max() / st.max_step_rate
            x = x.copy()
            x[:, cols] += dx / big if big > 1.0 else dx
        return x

    def cold_solve(self, x, u, centres, sign, axial_load_n, scale, sweeps=3):
        """Free balls (no B2B) from a rough start: alternate the two stages, then Newton."""
        for _ in range(sweeps):
            x, u = self._stage_geometry(x, u, centres, sign, axial_load_n, scale)
            x = self._stage_rates(x, u, centres, sign, scale)
        none = np.zeros(0, dtype=int)
        return self.solve(x, u, centres, sign, axial_load_n, scale, none, none,
                          np.zeros(0, dtype=bool))


class EquilibriumSolver(_ColdStart):
    """Solve ball equilibrium for given geometry, load and candidate B2B pairs."""

    def __init__(self, ball_model, b2b_model, settings):
        """Keep the models and the solver settings (a ``SolverSettings``)."""
        self.ball = ball_model
        self.b2b = b2b_model
        self.settings = settings
        self.disp_limit = settings.max_step_displacement_m / LENGTH_SCALE_M
        self.extra_oversize_m = 0.0     # > 0 only during a cold start's continuation
        # Compiled Newton kernel (exact B2B Jacobian); the numpy path below without numba.
        self.use_kernel = kernel.HAVE_NUMBA
        b = ball_model
        self._k_load = np.ascontiguousarray(b.k_load, dtype=float)
        self._k_axis = np.ascontiguousarray(b.k_axis, dtype=float)
        self._on_nut = np.ascontiguousarray(b.on_nut, dtype=float)
        self._coef = tuple(m.cell_coefficients for m in b.maps)
        m0 = b.maps[0]
        self._grid = np.array([m0.n_polar, m0.n_azimuth, m0.dt, m0.dh], dtype=float)
        self._cst = {}      # kernel constants per extra oversize (continuation)
        if self.use_kernel:
            self._warm_up()

    def _warm_up(self):
        """
        Load (or compile) the kernel now, not in the first step: one evaluation of two balls.

        numba loads the cached machine code at the first call (about 0.2 s; a first compile
        takes seconds), which would otherwise stall a live node's first input.  The warm
        step's calls are loaded by ``runner.warm_up``'s warm step, which takes the path the
        config uses (``kernel.warm_step`` for a rigid nut, else ``kernel.warm_solve``):
        loading ``warm_solve`` here as well cost 55 ms of every start (measured) for a call
        the default config never makes.
        """
        x = self.ball.rolling_guess(2, 1.0)
        centres = self.ball.arc_centres(np.zeros(2), 0.0, 0.0)
        pair = np.array([0]), np.array([1])
        self._solve_active_kernel(x, 0.0, np.zeros(1), centres, 1.0, 1.0, 1.0, *pair, 0)
        kernel.ring_projection(np.array([0.0, 0.5]), 1.0, 10.0)
        kernel.ring_pairs(np.array([0.0, 0.5]), 1.0, 10.0, 0.0, 1.0)
        kernel.theta_centres(np.zeros(2), 0.0, 1.0, 0.0, 0.0, 1.0, 0.5)
        self.b2b.speed(x, *pair, 1.0)

    def _approach_units(self, load_n):
        """Hertz approach of a screw contact under ``load_n``, in LENGTH_SCALE_M units."""
        # HertzContact.approach for a scalar load, without numpy's per-call overhead.
        return self.ball.hertz[0].coef_delta_m_per_n23 * max(float(load_n), 0.0) \
            ** (2.0 / 3.0) / LENGTH_SCALE_M

    def _residual(self, x, u, f_hat, centres, sign, axial_load_n, scale, rear, front, jac):
        """Scaled residuals and the Jacobian pieces for a fixed active set."""
        t = self.ball.evaluate(x, u, centres, sign, jacobian=jac,
                               extra_oversize_m=self.extra_oversize_m)
        r_b = self.ball.r_b
        res = np.concatenate([t["force"], t["moment"] / r_b], axis=1) / scale
        g_rear = g_front = speed = None
        if rear.size:
            g_rear, g_front, speed = self.b2b.unit_terms(x[rear], x[front], sign)
            np.add.at(res, rear, g_rear * f_hat[:, None])
            np.add.at(res, front, g_front * f_hat[:, None])
        axial = (t["axial"].sum() + axial_load_n) / scale
        cons = x[rear, 2] - x[front, 2]
        return t, res, axial, cons, g_rear, g_front, speed

    def _newton_step(self, t, res, axial, cons, g_rear, g_front, scale, rear, front, n):
        """Solve the bordered block system for (dx, du, dF) as described in the docstring."""
        r_b = self.ball.r_b
        jac = np.concatenate([t["d_force"], t["d_moment"] / r_b], axis=1) / scale
        blocks = jac[:, :, :N_STATE]
        k = rear.size
        rhs = np.zeros((n, N_STATE, 4))
        rhs[:, :, 0] = res
        rhs[:, :, 1] = jac[:, :, N_STATE]
        if k:
            rhs[rear, :, 2] = g_rear
            rhs[front, :, 3] = g_front
        sol = _solve_blocks(blocks, rhs)
        y, z = sol[:, :, 0], sol[:, :, 1]
        a_row = t["d_axial"][:, :N_STATE] / scale
        c_u = t["d_axial"][:, N_STATE].sum() / scale
        schur_u = np.einsum("ij,ij->", a_row, z) - c_u
        rhs_u = axial - np.einsum("ij,ij->", a_row, y)
        if k == 0:
            du = rhs_u / schur_u
            df = np.zeros(0)
        else:
            wr = sol[rear, :, 2]                # J_r^-1 G_rear, per contact
            wf = sol[front, :, 3]
            diag = wr[:, 2] - wf[:, 2]
            # Neighbouring contacts of a chain share a ball: k-1's front is k's rear.
            shared_lo = np.zeros(k, dtype=bool)
            shared_lo[1:] = front[:-1] == rear[1:]
            # C[k, k-1] = +e.W_f[k-1] (ball r_k is the front of k-1); C[k, k+1] = -e.W_r[k+1].
            sub = np.where(shared_lo[1:], wf[:-1, 2], 0.0)
            sup = np.where(shared_lo[1:], -wr[1:, 2], 0.0)
            ab = np.zeros((3, k))
            ab[0, 1:] = sup
            ab[1, :] = diag
            ab[2, :-1] = sub
            col_u = z[rear, 2] - z[front, 2]
            rhs_f = cons - (y[rear, 2] - y[front, 2])
            # Imported here: only the numpy path needs scipy.linalg (not on the node's
            # start-up path, where its import cost 0.1 s).
            from scipy.linalg import solve_banded
            pq = solve_banded((1, 1), ab, np.stack([rhs_f, col_u], axis=1))
            row_f = np.einsum("ij,ij->i", a_row[rear], wr) + np.einsum("ij,ij->i",
                                                                       a_row[front], wf)
            du = (rhs_u - row_f @ pq[:, 0]) / (schur_u - row_f @ pq[:, 1])
            df = pq[:, 0] - pq[:, 1] * du
        dx = y + z * du
        if k:
            dx[rear] += sol[rear, :, 2] * df[:, None]
            dx[front] += sol[front, :, 3] * df[:, None]
        return -dx, du, df

    def _solve_active_kernel(self, x, u, f_hat, centres, sign, axial_load_n, scale, rear, front,
                             max_iterations, elastic=None, tolerance=None):
        """
        ``solve_active`` through the compiled kernel (``kernel.solve_active``).

        With ``elastic`` = (order, comp_a, comp_b) (``load_distribution.ElasticLoadPath``)
        u is the per-ball nut displacement (N,) and ``kernel.solve_active_elastic`` solves.
        """
        st = self.settings
        # The kernel does not check bounds: refuse mismatched arrays here rather than read
        # memory that is not theirs (which made results differ from run to run).
        n = np.shape(x)[0]
        if np.shape(centres)[0] != n or (np.size(rear) and max(np.max(rear), np.max(front))
                                         >= n) or np.size(f_hat) != np.size(rear):
            raise ValueError(f"solve_active: {n} ball states, {np.shape(centres)[0]} "
                             f"centres, {np.size(rear)} pairs, {np.size(f_hat)} forces")
        disp_limit = self.displacement_limit(scale)
        common = (np.ascontiguousarray(f_hat, dtype=float),
                  np.ascontiguousarray(centres, dtype=float), float(sign),
                  *self.kernel_constants(), float(scale), float(axial_load_n),
                  np.ascontiguousarray(rear, dtype=np.int64),
                  np.ascontiguousarray(front, dtype=np.int64), *self.b2b.linear_terms(sign))
        tol = st.tolerance if tolerance is None else tolerance
        limits = (float(tol), int(max_iterations), float(st.max_step_rate), float(disp_limit))
        x = np.ascontiguousarray(x, dtype=float)
        if elastic is None:
            out = kernel.solve_active(x, float(u), *common, *limits)
        else:
            u = np.ascontiguousarray(np.broadcast_to(u, (x.shape[0],)), dtype=float)
            out = kernel.solve_active_elastic(x, u, *common, *elastic, *limits)
        x, u, f_hat, ok, it, norm, terms, per_contact, speed = out
        return x, u, f_hat, bool(ok), int(it), float(norm), kernel_terms(terms, per_contact), \
            speed

    def kernel_constants(self):
        """
        Return the kernels' constants (cst, k_load, k_axis, on_nut, map coefficients, grid).

        ``cst`` depends on the current extra oversize (cold-start continuation).
        """
        cst = self._cst.get(self.extra_oversize_m)
        if cst is None:
            cst = kernel.pack_constants(self.ball, self.extra_oversize_m)
            if len(self._cst) < 64:
                self._cst[self.extra_oversize_m] = cst
        return (cst, self._k_load, self._k_axis, self._on_nut, self._coef[0], self._coef[1],
                self._grid)

    def displacement_limit(self, scale):
        """Trust-region limit of a Newton step in xi, zeta and u [LENGTH_SCALE_M]."""
        return max(self.disp_limit, self._approach_units(scale))

    def solve_active(self, x, u, f_hat, centres, sign, axial_load_n, scale, rear, front,
                     max_iterations=None, elastic=None, tolerance=None):
        """
        Newton iterations for one active set; returns (x, u, f_hat, ok, it, res, t, sp).

        ``elastic``: see ``_solve_active_kernel``; the elastic system always runs through
        the kernel functions (compiled, or as plain Python without numba).  ``tolerance``:
        the residual tolerance (default ``settings.tolerance``; a sub-step's is looser).
        """
        st = self.settings
        tol = st.tolerance if tolerance is None else tolerance
        max_it = st.max_iterations if max_iterations is None else max_iterations
        if self.use_kernel or elastic is not None:
            return self._solve_active_kernel(x, u, f_hat, centres, sign, axial_load_n, scale, rear,
                                             front, max_it, elastic, tol)
        n = x.shape[0]
        t, res, axial, cons, gr, gf, sp = self._residual(x, u, f_hat, centres, sign, axial_load_n,
                                                         scale, rear, front, True)
        norm = max(np.abs(res).max(), abs(axial), np.abs(cons).max() if cons.size else 0.0)
        it = 0
        while norm > tol and it < max_it:
            it += 1
            dx, du, df = self._newton_step(t, res, axial, cons, gr, gf, scale, rear, front, n)
            # Trust region: near two-point contact the spin about the loaded diagonal is
            # weakly determined and a full step can run away.
            disp_limit = self.displacement_limit(scale)
            big = max(np.abs(dx[:, 2:]).max() / st.max_step_rate,
                      max(np.abs(dx[:, :2]).max(), abs(du)) / disp_limit)
            step = 1.0 / big if big > 1.0 else 1.0
            for _ in range(12):
                xn, un, fn = x + step * dx, u + step * du, f_hat + step * df
                out = self._residual(xn, un, fn, centres, sign, axial_load_n, scale, rear, front,
                                     True)
                nn = max(np.abs(out[1]).max(), abs(out[2]),
                         np.abs(out[3]).max() if out[3].size else 0.0)
                if np.isfinite(nn) and (nn < norm or nn <= tol):
                    break
                step *= 0.5
            x, u, f_hat = xn, un, fn
            t, res, axial, cons, gr, gf, sp = out
            norm = nn
        return x, u, f_hat, bool(norm <= tol), it, norm, t, sp

    def solve(self, x, u, centres, sign, axial_load_n, scale, pair_rear, pair_front, active,
              f_guess=None, max_total_iterations=None, elastic=None, tolerance=None):
        """
        Equilibrium with exact B2B complementarity over the candidate (touching) pairs.

        pair_rear/pair_front: ball indices of candidate pairs, in chain order (a pair's
        front ball is the next pair's rear ball when they share it).  ``active``: initial
        active set (bool per pair).  Forces returned in newtons.  ``max_total_iterations``
        (real-time mode) caps the Newton iterations over all active sets; when it stops the
        solve, the result has ``converged = False`` and ``budget_exhausted = True``.
        ``elastic``: the elastic load path (order, comp_a, comp_b); u is then per ball.
        ``tolerance``: residual tolerance, also of the active-set tests (default
        ``settings.tolerance``; ``WholeScrew.step`` passes a sub-step's looser one).
        """
        st = self.settings
        tol = st.tolerance if tolerance is None else tolerance
        active = np.asarray(active, dtype=bool).copy()
        f_all = np.zeros(pair_rear.size) if f_guess is None else np.asarray(f_guess) / scale
        total_it = 0
        ok = False
        exhausted = False
        for _ in range(st.max_active_set_changes):
            idx = np.flatnonzero(active)
            rear, front = pair_rear[idx], pair_front[idx]
            f0 = np.maximum(f_all[idx], 0.0)
            left = None if max_total_iterations is None else \
                max(int(max_total_iterations) - total_it, 0)
            x, u, f_hat, ok, it, norm, t, sp = self.solve_active(
                x, u, f0, centres, sign, axial_load_n, scale, rear, front,
                st.max_iterations if left is None else min(st.max_iterations, left), elastic,
                tol)
            total_it += it
            f_all = np.zeros(pair_rear.size)
            f_all[idx] = f_hat
            if not ok:
                exhausted = left is not None and it >= left and bool(np.isfinite(norm))
                break
            if not pair_rear.size:
                break
            changed = False
            neg = idx[f_hat < -tol]
            if neg.size:
                active[neg] = False
                changed = True
            closing = (~active) & (x[pair_rear, 2] * sign > x[pair_front, 2] * sign
                                   + tol)
            if closing.any() and not neg.size:
                active |= closing
                changed = True
            if not changed or not pair_rear.size:
                break
        else:
            ok = False
        speed = np.zeros(pair_rear.size)
        if pair_rear.size:
            speed = self.b2b.speed(x, pair_rear, pair_front, sign)
        return Solution(x=x, u=u, forces=f_all * scale, active=active, converged=ok,
                        iterations=total_it, residual=norm, terms=t, b2b_speed=speed,
                        budget_exhausted=exhausted)
