"""
Whole ball screw with B2B contact, stepped in time (paper Sec. 3.4, Figs. 19-21).

API (a stepping object, for the simulation, a ROS node or bag replay)::

    screw = WholeScrew(config)                 # builds Hertz constants and friction maps
    screw.reset(nut_angle_rad=0.0)             # balls evenly spaced over the loaded track
    r = screw.step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)   # StepResult
    r = screw.step_path(angles, velocities, loads, dt_s)   # sub-steps, then the last one

``step`` takes the MEASURED nut angle: each ball's azimuth advances by its orbit ratio
omega_B / omega_N (from the previous step) times the nut-angle increment, so the nut may
reverse or change speed.  The nut velocity sets the direction of friction (its magnitude
only scales losses: quasi-static Coulomb friction is rate independent); the axial load W is
the force of the balls on the nut along +z (W > 0 opposes omega_N > 0) and may change sign.
omega_N = 0 gives zero friction torque and keeps the state (static friction is
indeterminate in this model).  Load range (``config.validity``): a load whose mean contact
load exceeds the model's limit (contact ellipse a / R_B, Hertz pressure; about 10 kN for
Table 4) is not solved: the step returns ``converged = False``, ``in_load_range = False``
and zero torques, and keeps the state.  A solution with any single contact above the limit
keeps its numbers with ``in_load_range = False`` (an unconverged step inside the range keeps
``in_load_range = True``: its iterate's contact loads mean nothing).  Each step returns the
friction torque on the nut T_f = T_nut - W p / 2pi split into ball-groove and B2B parts (by
their losses), the drive power omega_N T_f and the total loss (equal to solver precision),
every ball's azimuth, omega_B, contact loads, and the B2B contact groups (ball ids
rear-first with their forces).

Model: N balls on a closed loop of ``loaded_turns`` turns in the nut (the return tube has
zero length, so the first and last balls are neighbours).  The axial load W reaches the balls
either through a rigid nut and shaft (``load_distribution: rigid``: one nut displacement
shared by all balls) or through shaft and nut bars that deform axially between the balls
(``elastic``, ref. [19]; ``load_distribution.py``), so that each ball's load varies along the
nut.  Balls never overlap: after each advance, overlaps are removed by the L2
projection onto non-overlapping positions (pool-adjacent-violators on the ring).  Contacts
close and open by the exact complementarity of Eq. (61) (``solver``).

Warm start: each step starts from the secant prediction in nut angle: the last two solutions
(states and B2B forces) are extrapolated linearly.  The initial active set is the closed
pairs whose predicted force stays positive, plus the open pairs whose rear ball is predicted
to be faster.  If Newton fails from there, the step retries from the plain previous
solution.  If that fails too, it cold-starts (``ScrewModel.cold_solve``), as it also does on
the first step and after a change of sign of omega_N or W.  The answer does not depend on the
start: every path converges to the same tolerance.

Real-time mode (``solver.realtime_max_iterations`` > 0, default 0 = off) caps the Newton
iterations of a warm step.  When the cap stops the solve, the step returns its last iterate
with ``converged = False`` (never silently), keeps it as the state and continues from it at
the next step.  A cold start is never cut short.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Sec. 3.4, Eq. (61), Figs. 19-21.

"""

import math
import time
from dataclasses import dataclass, field

import numpy as np

from bb_friction_ros.ball_screw import geometry as geo
from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.load_distribution import elastic_load_path
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.solver import Solution, kernel_terms

_TINY = float(np.finfo(float).tiny)
# kernel.warm_solve's load path of a rigid nut and shaft: no axial order, no compliances.
_RIGID = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))


@dataclass
class StepResult:
    """Outputs of one time step (SI units)."""

    t_s: float
    nut_angle_rad: float
    nut_velocity_rad_s: float
    axial_load_n: float
    torque_total_nm: float
    torque_b2g_nm: float
    torque_b2b_nm: float
    drive_power_w: float
    loss_w: float
    converged: bool
    power_balance_error: float
    azimuth_rad: np.ndarray
    theta_rad: np.ndarray
    omega_b_rad_s: np.ndarray
    loads_n: np.ndarray
    b2b_forces_n: np.ndarray          # per ring pair (ball j, ball j+1), 0 if open
    groups: list = field(default_factory=list)   # [(ball ids rear-first, forces)]
    ball_axial_loads_n: np.ndarray = None   # per ball: its axial force on the nut (sum = W)
    in_load_range: bool = True       # False: outside config.validity (see docs); see step()
    iterations: int = 0
    solve_time_s: float = 0.0
    substeps_not_converged: int = 0   # step_path: sub-steps before this one not converged
    substep_iterations: int = 0       # step_path: Newton iterations of those sub-steps

    @property
    def n_groups(self):
        """Return the number of B2B contact groups (chains of touching balls)."""
        return len(self.groups)


def _as_displacements(u, shape):
    """
    Nut displacement(s) u as a writable contiguous float array of ``shape``.

    (1,) rigid, (N,) elastic.  Never a read-only view: numba compiles another specialisation
    of the kernel for read-only arrays (the look-ahead's first step once compiled it in the
    live node's model thread, seconds after the node said ready).  An array that already
    fits is passed as it is (the kernel copies it): np.broadcast_to costs 2-3 us a call.
    """
    if (isinstance(u, np.ndarray) and u.shape == shape and u.dtype == np.float64
            and u.flags.c_contiguous and u.flags.writeable):
        return u
    if isinstance(u, float):
        # np.array([u]) costs a fifth of np.full((1,), u), twice per rigid step.
        return np.array([u]) if shape == (1,) else np.full(shape, u)
    return np.array(np.broadcast_to(u, shape), dtype=float)


def isotonic_ring_projection(azimuth, separation, loop_length):
    """
    Move balls the least (L2) so that neighbours on the loop are >= ``separation`` apart.

    Pool-adjacent-violators on y_i = phi_i - i * separation, with the ring cut at its
    largest gap (occupancy < 1 guarantees one positive gap).
    """
    return kernel.ring_projection(np.ascontiguousarray(azimuth, dtype=float),
                                  float(separation), float(loop_length))


class _PathSteps:
    """
    Take ``WholeScrew.step_path``: the warm steps between two inputs in one compiled call.

    The model's state is kept in a buffer of its own (``_path_buffers``) that
    ``kernel.warm_steps`` updates in place; ``step`` takes whatever the call could not.
    """

    def step_path(self, nut_angles_rad, nut_velocities_rad_s, axial_loads_n, dt_s):
        """
        Step through the given points in turn: sub-steps, then an answered last step.

        The same steps as ``step(angle, velocity, load, dt_s, substep=True)`` for every point
        but the last and ``step(..., substep=False)`` for the last, with the same results
        (iterations included), taken in one compiled call while they are warm steps of the
        same direction and load sign (``kernel.warm_steps``); a step that is not (a cold
        start, a reversal, no load, a failed warm solve, a lead error) and the steps after
        it are taken by ``step``.  Measured need: the Python around each step and its call
        was a fifth to a third of a sub-step at 20 rev/s and N = 37 (bench_warm_step.py).

        Parameters
        ----------
        nut_angles_rad, nut_velocities_rad_s, axial_loads_n : sequence of float
            The points, one per step (as ``step``'s arguments) [rad], [rad/s], [N].
        dt_s : float
            Time of each step [s].

        Returns
        -------
        StepResult
            The last step's; its ``substeps_not_converged`` counts the sub-steps before it
            that did not converge, its ``substep_iterations`` their Newton iterations (a
            sub-step's own result is not returned).

        """
        t0 = time.perf_counter()
        path = _path_points(nut_angles_rad, nut_velocities_rad_s, axial_loads_n)
        k = len(path) // 3
        dt_s = float(dt_s)
        # The leading warm steps in one compiled call, in this frame (a method of its own
        # for them, and the answer timed there too, cost 0.2 us a step more at 20 rev/s).
        res, done, missed, sub_it = None, 0, 0, 0
        solver = self.model.solver
        if (self._state is not None and self._geo is not None and solver.use_kernel
                and getattr(self._warm_solve, "__func__", None) is _COMPILED_WARM_SOLVE):
            sign, load_sign = self._state[2], self._state[3]
            buf = self._path_buf
            if buf is None:
                buf = self._path_buffers(self.config.load_distribution == "elastic")
            v = buf.views
            if not (self._state is buf.last_state and self._prev is buf.last_prev
                    and self._forces is v[2] and self.azimuth is v[4] and self.ratio is v[5]
                    and self._active is v[6]):
                self._path_state_in(buf)
            key = (sign, load_sign, solver, solver.settings, self.config.solver,
                   solver.disp_limit, solver.extra_oversize_m)
            if key != buf.key:
                # Packed again only when the direction, the load sign or a setting changed:
                # the same values as every call would write (measured: a fifth of the Python
                # around the call).
                self._path_settings(buf, key)
            buf.settings[6] = self.nut_angle
            blk = buf.blk
            if blk is None:
                # The answer's arrays are views of blk: a new one for each answer given.
                blk = buf.blk = np.empty((kernel.STEP_ROWS, self.n))
            kernel.warm_steps(buf.state, v[6], path, buf.aux, buf.coef_s, buf.coef_n,
                              *self._work, blk, buf.groups)
            r = buf.result.tolist()
            done = int(r[0])
            if done:
                # ``step``'s bookkeeping of the steps done: the state is the buffer's (views
                # into it; a copy of this model copies them, see __copy__).
                self.nut_angle = path.item(done - 1)
                t = self.time
                for _ in range(done):
                    t += dt_s       # as ``step`` sums it, step by step
                self.time = t
                if buf.elastic:
                    dp, u, up = buf.tail.item(0), v[7], v[8]
                else:
                    dp, u, up = buf.tail.tolist()   # state[16 N:16 N + 3]: one call, not three
                self._prev = buf.last_prev = (v[1], up, v[3], dp)
                self._state = buf.last_state = (v[0], u, sign, load_sign)
                self._forces, self.azimuth, self.ratio, self._active = v[2], v[4], v[5], v[6]
            missed = int(r[9])
            if done == k:
                buf.blk = None
                pairs = int(r[11])
                if pairs > 1:
                    g = buf.groups
                    grp = _groups(g[0, :pairs].tolist(), g[1, :pairs].tolist(),
                                  blk[7, :pairs].tolist())
                elif pairs:     # the one pair closed (most answers): no chains to find
                    grp = [((buf.groups.item(0, 0), buf.groups.item(1, 0)),
                            (blk.item(7, 0),))]
                else:
                    grp = []
                # blk[6]: the B2B forces the kernel also left in the state (v[2]), in an
                # array of this answer's own (a copy of v[2] cost more).
                res = self._result(path.item(2 * k - 1), path.item(3 * k - 1), r[5], r[6], r[7],
                                   r[8], bool(r[1]), int(r[3]), blk[1], blk[2], blk[4],
                                   blk[8:12].T, blk[5], blk[6], grp, None)
                sub_it = int(r[10] - r[3])
            else:
                sub_it = int(r[10])
        if done < k:
            # A step the compiled call could not take, and those after it.
            for j in range(done, k):
                if res is not None:
                    missed += not res.converged
                    sub_it += res.iterations
                res = self.step(path.item(j), path.item(k + j), path.item(2 * k + j), dt_s,
                                substep=j < k - 1)
        res.substeps_not_converged = missed
        res.substep_iterations = sub_it
        res.solve_time_s = time.perf_counter() - t0
        return res

    def _path_state_in(self, buf):
        """
        Copy the state as ``step`` keeps it into the path buffer (``step_path``).

        Not needed when the last step was a path's: then the kernel left every value of it
        in place, and the state tuples, never changed in place, say so.  The previous step's
        first, since it may be the buffer's current x.
        """
        v = buf.views
        x, u = self._state[0], self._state[1]
        if self._prev is not None:
            xp, up, fp, dp = self._prev
        else:
            xp, up, fp, dp = x, u, self._forces, 0.0
        v[1][:] = xp
        v[3][:] = fp
        v[8][:] = up
        v[0][:] = x
        v[2][:] = self._forces
        v[4][:] = self.azimuth
        v[5][:] = self.ratio
        v[6][:] = self._active
        v[7][:] = u
        buf.state[16 * self.n] = dp

    def _path_settings(self, buf, key):
        """Write ``kernel.warm_steps``' settings and constants of ``key`` (``step_path``)."""
        sign, load_sign, solver, st, cfg, disp_limit = key[:6]
        consts, buf.par[:] = self._step_constants(solver, sign)
        buf.coef_s, buf.coef_n = consts[4], consts[5]
        settings = buf.settings
        settings[0] = sign
        settings[1] = load_sign
        settings[2] = st.max_iterations
        settings[3] = st.max_active_set_changes
        settings[4] = cfg.realtime_max_iterations or -1
        settings[5] = st.max_step_rate
        settings[11] = cfg.tolerance
        settings[12] = cfg.substep_tolerance
        settings[13] = disp_limit
        buf.key = key

    def _path_buffers(self, elastic):
        """Make ``kernel.warm_steps``' buffers of this model and views into its state."""
        n = self.n
        m = n if elastic else 1
        state = np.zeros(kernel.state_size(n, elastic))
        o = 16 * n + 1
        # x, previous x, forces, previous forces, azimuth, ratio, active, u, previous u
        views = (state[2 * n:8 * n].reshape(n, 6), state[8 * n:14 * n].reshape(n, 6),
                 state[14 * n:15 * n], state[15 * n:16 * n], state[0:n], state[n:2 * n],
                 np.zeros(n, dtype=bool), state[o:o + m], state[o + m:o + 2 * m])
        # settings, result, packed constants, elastic constants: one array (kernel.aux_parts)
        aux = np.zeros(kernel.aux_size(elastic))
        settings, result, par, epar = kernel.aux_parts(aux)
        settings[7] = self.config.track.track_start_rad
        settings[8] = self.model.preload_load()
        settings[9] = -1.0 if self._preload else self.config.solver.min_axial_load_n
        settings[10] = self.max_axial_load_n
        settings[14] = self.model.ball.hertz[0].coef_delta_m_per_n23
        buf = self._path_buf = _PathBuffers()
        buf.state, buf.views, buf.settings, buf.elastic = state, views, settings, elastic
        buf.tail = state[16 * n:16 * n + (1 if elastic else 3)]
        buf.aux, buf.result, buf.par = aux, result, par
        if elastic:
            epar[:] = kernel.pack_elastic_constants(self.config.geometry.lead_m,
                                                    self.config.elastic)
        buf.groups = np.zeros((2, n), dtype=np.int64)
        return buf


class _PathBuffers:
    """
    ``kernel.warm_steps``' arrays of one model, and what ``step_path`` keeps between calls.

    ``key``: what the settings and packed constants were written for; ``last_state``,
    ``last_prev``: the model's state tuples as the last path call left them (views into
    ``state``).
    """

    __slots__ = ("state", "views", "settings", "result", "aux", "elastic", "key", "par",
                 "coef_s", "coef_n", "last_state", "last_prev", "tail", "blk", "groups")

    def __init__(self):
        """Nothing written yet: the first call writes the settings and the state."""
        self.key = self.last_state = self.last_prev = self.blk = None


class _WarmStep:
    """
    Take ``WholeScrew.step``'s warm solve, compiled or on the numpy reference path.

    The compiled step in one call (``_fused_step``), or the solver's Newton on the numpy
    reference path (``_warm_solve_numpy``), from its guesses.
    """

    def _step_constants(self, solver, sign):
        """
        Return (the solver's kernel constants, the compiled step's packed constants of ``sign``).

        Packed once per direction and per set of kernel constants (a cold start's
        continuation makes others), for ``kernel.warm_step`` and ``kernel.warm_steps`` alike.
        """
        consts = solver.kernel_constants()
        key = (sign, id(consts[0]))
        par = self._step_par.get(key)
        if par is None:
            par = kernel.pack_step_constants(self._geo, *consts[:4], consts[6],
                                             *solver.b2b.linear_terms(sign))
            self._step_par = {key: par, "cst": consts[0]}     # keeps consts[0] alive (its id)
        return consts, par

    def _fused_step(self, d_psi, sign, load_sign, omega_n, axial_load_n, budget, t0, tol):
        """
        Take a warm step of a rigid nut without lead errors in one compiled call.

        ``kernel.warm_step``: ``advance``, ``_warm_solve`` and ``_finish``'s sums with the same
        arithmetic.  Returns (StepResult, iterations), or (None, iterations) when the solve
        failed from every guess (state untouched: the caller cold-starts).
        """
        solver = self.model.solver
        st = solver.settings
        x, u = self._state[0], self._state[1]
        if self._prev is not None:
            xp, up, fp, dp = self._prev
        else:
            xp, up, fp, dp = x, u, self._forces, 0.0
        if x.shape != (self.n, 6) or xp.shape != x.shape or fp.shape != (self.n,):
            # The kernel does not check bounds (see solver._solve_active_kernel).
            raise ValueError(f"warm solve: state {x.shape}, previous {xp.shape}, forces "
                             f"{fp.shape} for {self.n} balls")
        scale = self.model.force_scale(self.n, axial_load_n)
        consts, par = self._step_constants(solver, sign)
        ok, exhausted, iterations, _, u, loss_sum, torque_sum, b2b_sum, load_max, blk, x, \
            active, groups = kernel.warm_step(
                self.azimuth, self.ratio, x, xp, fp, self._forces, self._active, par,
                consts[4], consts[5], *self._work, d_psi,
                self.nut_angle + self.config.track.track_start_rad, sign, float(u), float(up),
                float(dp), scale, axial_load_n, tol, st.max_iterations, st.max_step_rate,
                solver.displacement_limit(scale), st.max_active_set_changes,
                budget if budget else -1, omega_n)
        iterations = int(iterations)
        if not (ok or exhausted):
            return None, iterations
        # Real-time mode: an unfinished iterate is kept too, converged = False.
        self._prev = (self._state[0], self._state[1], self._forces, d_psi)
        self._state = (x, u, sign, load_sign)
        self.azimuth, self.ratio, self._forces = blk[0], blk[3], blk[6]
        self._active = active
        rear, front = groups[0].tolist(), groups[1].tolist()
        return self._result(omega_n, axial_load_n, loss_sum, torque_sum, b2b_sum, load_max,
                            bool(ok), iterations, blk[1], blk[2], blk[4], blk[8:12].T, blk[5],
                            blk[6].copy(), _groups(rear, front, blk[7, :len(rear)].tolist()),
                            t0), iterations

    def _warm_solve_numpy(self, d_psi, centres, sign, axial_load_n, scale, pair_idx, rear, front,
                          budget, elastic, tol):
        """
        Solve a warm step from the guesses in turn: the readable reference of ``_warm_solve``.

        Returns (the first ``Solution`` that converged or used up the budget, else the last;
        the iterations of all).  Runs the solver's own path (numpy, or the compiled Newton
        per active set).
        """
        sol = None
        iterations = 0
        guesses = self._guesses(d_psi)
        for gx, gu, gf in guesses[:1] if budget else guesses:
            # Closed pairs keep their predicted force > 0; open ones close if the rear ball
            # is predicted faster (the active-set loop corrects either guess).
            faster = gx[rear, 2] * sign > gx[front, 2] * sign
            active = (self._active[pair_idx] & (gf[pair_idx] > 0.0)) | faster
            sol = self.model.solver.solve(gx, gu, centres, sign, axial_load_n, scale, rear,
                                          front, active, gf[pair_idx], budget, elastic, tol)
            iterations += sol.iterations
            if sol.converged or sol.budget_exhausted:
                break
        return sol, iterations

    def _warm_solve(self, d_psi, centres, sign, axial_load_n, scale, pair_idx, rear, front,
                    budget, elastic, tol):
        """
        ``_warm_solve_numpy`` in one compiled call (``kernel.warm_solve``), same arithmetic.

        Measured need: the Python around the compiled Newton (guesses, active
        set, argument packing) cost about 90 us of a 320 us step at N = 37.  Bit for bit
        the reference when both run from one numba cache (test_compiled_step says why
        not always).
        """
        solver = self.model.solver
        st = solver.settings
        x, u = self._state[0], self._state[1]
        shape = (self.n,) if elastic is not None else (1,)
        u = _as_displacements(u, shape)
        if self._prev is not None:
            xp, up, fp, dp = self._prev
            up = _as_displacements(up, shape)
        else:
            xp, up, fp, dp = x, u, self._forces, 0.0
        path = elastic if elastic is not None else _RIGID
        if x.shape != (self.n, 6) or xp.shape != x.shape or fp.shape != (self.n,):
            # The kernel does not check bounds (see solver._solve_active_kernel).
            raise ValueError(f"warm solve: state {x.shape}, previous {xp.shape}, forces "
                             f"{fp.shape} for {self.n} balls")
        out, iterations, speed = kernel.warm_solve(
            x, u, xp, up, fp, float(dp), self._forces, self._active, d_psi, pair_idx, centres,
            sign, *solver.kernel_constants(), scale, axial_load_n, rear, front,
            *solver.b2b.linear_terms(sign), *path, tol, st.max_iterations,
            st.max_step_rate, solver.displacement_limit(scale), st.max_active_set_changes,
            budget if budget else -1, *self._work)
        x, u, f_all, active, ok, exhausted, it, norm, terms, per_contact = out
        sol = Solution(x=x, u=u if elastic is not None else float(u[0]), forces=f_all * scale,
                       active=active, converged=bool(ok), iterations=int(it),
                       residual=float(norm), terms=kernel_terms(terms, per_contact),
                       b2b_speed=speed, budget_exhausted=bool(exhausted))
        return sol, int(iterations)

    def _guesses(self, d_psi):
        """
        Warm starts: the secant prediction in nut angle, then the previous solution.

        The states (and B2B forces) of the last two steps are extrapolated linearly in the
        nut angle; the plain previous solution is the fallback if Newton fails from there.
        (Tried and not kept: a quadratic prediction, and not extrapolating balls whose
        contacts changed; neither reduced the iterations.)
        """
        x, u = self._state[0], self._state[1]
        out = []
        if self._prev is not None and self._prev[3] != 0.0:
            r = d_psi / self._prev[3]
            if 0.0 < r <= 4.0:
                xp, up, fp = self._prev[:3]
                out.append((x + r * (x - xp), u + r * (u - up),
                            self._forces + r * (self._forces - fp)))
        out.append((x.copy(), u, self._forces))
        return out


class WholeScrew(_WarmStep, _PathSteps):
    """N balls in a recirculating nut, stepped quasi-statically (see module docstring)."""

    def __init__(self, config, model=None):
        """Build the contact model (or reuse ``model``, a ScrewModel of the same config)."""
        self.config = config
        self.model = model if model is not None else ScrewModel(config)
        tr = config.track
        self.n = tr.n_balls
        self.loop = 2.0 * math.pi * tr.loaded_turns
        self.separation = self.model.b2b.separation
        self.max_contact_load_n = self.model.max_contact_load_n()
        self.max_axial_load_n = self.model.max_axial_load_n(self.n)
        # The compiled solve's work arrays, reused step after step (kernel.work_arrays).
        self._work = kernel.work_arrays(self.n)
        self._step_par = {}         # kernel.warm_step's packed constants per direction
        self._path_buf = None       # kernel.warm_steps' buffers (step_path)
        # Fixed by the config, read at every step.
        self._preload = self.model.preload_load() > 0.0
        e, b = config.errors, self.model.ball
        self._plain_theta = None if (e.screw_lead_error_amplitude_m or e.nut_lead_error_m) \
            else (e.theta_amplitude_rad, e.theta_cycles_per_rev, e.theta_phase_rad,
                  e.theta_offset_rad, b.r_groove - b.r_b, b.beta0)
        # kernel.warm_step's geometry (no lead errors): separation, loop, gap tolerance, theta.
        self._geo = None if self._plain_theta is None else np.array(
            (self.separation, self.loop, config.solver.gap_tolerance_rad) + self._plain_theta,
            dtype=float)
        if self.n * self.separation >= self.loop:
            raise ValueError(
                f"ball_screw.track.n_balls: {self.n} balls need "
                f"{math.degrees(self.n * self.separation):.1f} deg > loop "
                f"{math.degrees(self.loop):.1f} deg")
        self.reset()

    def __copy__(self):
        """Return a shallow copy with work arrays of its own (it may step in another thread)."""
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._work = kernel.work_arrays(self.n)
        new._path_buf = None
        if self._path_buf is not None:
            # The state may be views into this model's path buffer, which its next
            # step_path overwrites in place: the copy keeps its own.
            if self._state is not None:
                new._state = (self._state[0].copy(), np.copy(self._state[1])
                              if isinstance(self._state[1], np.ndarray) else self._state[1],
                              ) + tuple(self._state[2:])
            if self._prev is not None:
                new._prev = tuple(np.copy(a) if isinstance(a, np.ndarray) else a
                                  for a in self._prev)
            new._forces, new.azimuth = self._forces.copy(), self.azimuth.copy()
            new.ratio, new._active = self.ratio.copy(), self._active.copy()
        return new

    @property
    def occupancy(self):
        """Fraction of the loop occupied by balls (97.8 % in Sec. 3.4)."""
        return self.n * self.separation / self.loop

    def reset(self, nut_angle_rad=0.0):
        """Balls evenly spaced over the loop, no solved state (next step cold-starts)."""
        tr = self.config.track
        self.nut_angle = float(nut_angle_rad)
        self.time = 0.0
        self.azimuth = self.nut_angle + tr.track_start_rad \
            + (np.arange(self.n) + 0.5) * (self.loop / self.n)
        self.ratio = np.full(self.n, self.model.ball.rolling_guess(1, 1.0)[0, 2])
        self._state = None          # (x, u, sign, load sign)
        self._prev = None           # (x, u, forces, nut-angle increment) one step before
        self._active = np.zeros(self.n, dtype=bool)   # per ring pair (j, j+1)
        self._forces = np.zeros(self.n)

    def track_azimuth(self):
        """Screw-frame azimuth of each ball inside the loaded track (Eq. 35's phi)."""
        start = self.nut_angle + self.config.track.track_start_rad
        return start + np.mod(self.azimuth - start, self.loop)

    def _centres(self, phi):
        """Arc centres of every ball from theta(phi) and the lead errors (Figs. 15, 17, 19)."""
        e = self.config.errors
        b = self.model.ball
        if self._plain_theta is not None:
            theta, centres = kernel.theta_centres(np.ascontiguousarray(phi, dtype=float),
                                                  *self._plain_theta)
            return theta, centres, (theta, 0.0, 0.0)
        theta = geo.theta_deviation(phi, e.theta_amplitude_rad, e.theta_cycles_per_rev,
                                    e.theta_phase_rad, e.theta_offset_rad)
        screw_z = nut_z = 0.0
        if e.screw_lead_error_amplitude_m:
            screw_z = e.screw_lead_error_amplitude_m * np.sin(
                e.screw_lead_error_cycles_per_rev * phi)
        if e.nut_lead_error_m:
            chi = phi - self.nut_angle - self.config.track.track_start_rad
            nut_z = e.nut_lead_error_m * (chi - 0.5 * self.loop) / (2.0 * math.pi)
        return theta, b.arc_centres(theta, screw_z * b.cos_a, nut_z * b.cos_a), \
            (theta, screw_z * b.cos_a, nut_z * b.cos_a)

    def _pairs(self, sign):
        """Touching ring pairs as (pair index, rear ball, front ball) in chain order."""
        return kernel.ring_pairs(self.azimuth, self.separation, self.loop,
                                 self.config.solver.gap_tolerance_rad, float(sign))

    def _zero_result(self, omega_n, axial_load_n, dt_s, in_range=True):
        """
        Return zero friction with the state kept: no motion or no load.

        With ``in_range`` False: a load beyond the model's range, not solved (converged =
        False, zero torques, state kept).
        """
        return StepResult(
            t_s=self.time, nut_angle_rad=self.nut_angle, nut_velocity_rad_s=omega_n,
            axial_load_n=axial_load_n, torque_total_nm=0.0, torque_b2g_nm=0.0, torque_b2b_nm=0.0,
            drive_power_w=0.0, loss_w=0.0, power_balance_error=0.0,
            azimuth_rad=self.track_azimuth(), theta_rad=self._centres(
                self.track_azimuth())[0], omega_b_rad_s=self.ratio * omega_n,
            loads_n=np.zeros((self.n, 4)), b2b_forces_n=np.zeros(self.n),
            ball_axial_loads_n=np.zeros(self.n), converged=in_range, in_load_range=in_range)

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        """
        Advance the balls to the measured nut angle and solve the equilibrium there.

        Parameters
        ----------
        nut_angle_rad : float
            Measured nut angle  [rad]; the balls advance by their orbit ratio times its
            increment, so the nut may reverse or change speed.
        nut_velocity_rad_s : float
            Signed nut angular velocity omega_N  [rad/s]; its sign sets the direction of
            friction, 0 gives zero friction and keeps the state.
        axial_load_n : float
            Axial load W, force of the balls on the nut along +z (W > 0 opposes
            omega_N > 0)  [N].
        dt_s : float
            Time since the previous step  [s].
        substep : bool
            A step between two inputs, whose state is never answered: it only carries the
            balls along.  Solved to ``solver.substep_tolerance`` instead of
            ``solver.tolerance`` (docs/model_schedule.md, "Sub-steps").

        Returns
        -------
        StepResult
            Friction torque T_f = T_nut - W p / 2pi and its ball-groove and B2B parts
            [N m], drive power omega_N T_f and total loss [W], ball azimuths [rad], orbit
            rates [rad/s], contact loads [N], B2B contact groups, convergence.

        """
        t0 = time.perf_counter()
        d_psi = float(nut_angle_rad) - self.nut_angle
        self.nut_angle = float(nut_angle_rad)
        self.time += float(dt_s)
        omega_n = float(nut_velocity_rad_s)
        axial_load_n = float(axial_load_n)
        unloaded = not self._preload and abs(axial_load_n) <= self.config.solver.min_axial_load_n
        if omega_n == 0.0 or unloaded or abs(axial_load_n) > self.max_axial_load_n:
            self.azimuth = isotonic_ring_projection(self.azimuth + self.ratio * d_psi,
                                                    self.separation, self.loop)
            self._prev = None
            # Beyond the model's range even on average (config.validity): not solved.
            return self._zero_result(omega_n, axial_load_n, dt_s,
                                     in_range=omega_n == 0.0 or unloaded)
        sign = 1.0 if omega_n > 0.0 else -1.0
        load_sign = 1.0 if axial_load_n >= 0.0 else -1.0
        budget = self.config.solver.realtime_max_iterations or None
        tol = self.config.solver.substep_tolerance if substep else self.config.solver.tolerance
        warm_ok = (self._state is not None and self._state[2] == sign
                   and self._state[3] == load_sign)
        iterations = 0
        if (warm_ok and self._geo is not None and self.model.solver.use_kernel
                and self.config.load_distribution == "rigid"
                and getattr(self._warm_solve, "__func__", None) is _COMPILED_WARM_SOLVE):
            # The whole warm step in one compiled call (kernel.warm_step).  Not when
            # _warm_solve was replaced (the numpy reference, in tests): that takes the path
            # below, of which this is the compiled form.
            result, iterations = self._fused_step(d_psi, sign, load_sign, omega_n, axial_load_n,
                                                  budget, t0, tol)
            if result is not None:
                return result
            warm_ok = False     # failed from every guess: the path below cold-starts
        if self._plain_theta is not None:
            # No lead errors: the geometry of the step in one compiled call.
            self.azimuth, phi, theta, centres, pair_idx, rear, front = kernel.advance(
                self.azimuth, self.ratio, d_psi, self.separation, self.loop,
                self.nut_angle + self.config.track.track_start_rad,
                self.config.solver.gap_tolerance_rad, sign, *self._plain_theta)
            shifts = (theta, 0.0, 0.0)
        else:
            self.azimuth = isotonic_ring_projection(self.azimuth + self.ratio * d_psi,
                                                    self.separation, self.loop)
            phi = self.track_azimuth()
            theta, centres, shifts = self._centres(phi)
            pair_idx, rear, front = self._pairs(sign)
        scale = self.model.force_scale(self.n, axial_load_n)
        elastic = None
        if self.config.load_distribution == "elastic":
            elastic = elastic_load_path(phi, self.config.geometry.lead_m,
                                        self.config.elastic, axial_load_n, scale)
        sol = None
        prev = None
        if warm_ok:
            warm = self._warm_solve if self.model.solver.use_kernel else self._warm_solve_numpy
            sol, iterations = warm(d_psi, centres, sign, axial_load_n, scale, pair_idx, rear,
                                   front, budget, elastic, tol)
            if sol.converged or sol.budget_exhausted:
                # Real-time mode: an unfinished iterate is returned, converged = False.
                prev = (self._state[0], self._state[1], self._forces, d_psi)
        if sol is None or not (sol.converged or sol.budget_exhausted):
            free = self.model.cold_solve(*shifts, sign, axial_load_n)
            ratio = free.x[:, 2] * sign
            sol = self.model.solver.solve(free.x, free.u, centres, sign, axial_load_n, scale, rear,
                                          front, ratio[rear] > ratio[front],
                                          elastic=elastic, tolerance=tol)
            sol.converged = sol.converged and free.converged
            iterations += sol.iterations
        sol.iterations = iterations
        self._prev = prev
        return self._finish(sol, sign, omega_n, axial_load_n, theta, phi, pair_idx, rear, front,
                            t0)

    def _finish(self, sol, sign, omega_n, axial_load_n, theta, phi, pair_idx, rear, front, t0):
        """Store the state and build the StepResult."""
        self._state = (sol.x, sol.u, sign, 1.0 if axial_load_n >= 0.0 else -1.0)
        t = sol.terms
        loss_sum, torque_sum, b2b_sum, load_max, self.ratio, self._active, self._forces, act \
            = kernel.step_totals(t["loss"], t["nut_torque"], t["load"], sol.forces,
                                 sol.b2b_speed, sol.active, pair_idx, sol.x, float(sign))
        return self._result(omega_n, axial_load_n, loss_sum, torque_sum, b2b_sum, load_max,
                            bool(sol.converged), sol.iterations, phi, theta,
                            self.ratio * omega_n, t["load"].copy(), -t["axial"],
                            self._forces.copy(),
                            _groups(rear[act].tolist(), front[act].tolist(),
                                    sol.forces[act].tolist()), t0)

    def _result(self, omega_n, axial_load_n, loss_sum, torque_sum, b2b_sum, load_max,
                converged, iterations, phi, theta, omega_b, loads, ball_axial, forces, groups,
                t0):
        """Build the StepResult from a step's sums and arrays (owned); t0 None: untimed."""
        b = self.model.ball
        abs_w = abs(omega_n)
        groove_loss = loss_sum * abs_w
        b2b_loss = b.mu * b2b_sum * abs_w
        torque = torque_sum - axial_load_n * b.r_gear
        loss = groove_loss + b2b_loss
        drive = omega_n * torque
        # Positional, in the order of StepResult's fields: keywords cost 0.7 us more a call.
        return StepResult(
            self.time, self.nut_angle, omega_n, axial_load_n, torque, groove_loss / omega_n,
            b2b_loss / omega_n, drive, loss, converged, abs(drive - loss) / max(loss, _TINY),
            phi, theta, omega_b, loads, forces, groups, ball_axial,
            # Per contact only for a solution: an unconverged iterate's loads mean nothing,
            # and its load |W| already passed the range check in ``step``.
            bool(not converged or load_max <= self.max_contact_load_n), iterations,
            0.0 if t0 is None else time.perf_counter() - t0)


def _path_points(nut_angles_rad, nut_velocities_rad_s, axial_loads_n):
    """``step_path``'s points as one array (angles, velocities, loads), each flattened."""
    try:
        # Lists (as the runner and the look-ahead pass give them) read by one np.fromiter:
        # 0.3 us a call less than one per list, and one array argument less than three.
        k = len(nut_angles_rad)
        if k > 0 and len(nut_velocities_rad_s) == k and len(axial_loads_n) == k:
            path = np.fromiter((*nut_angles_rad, *nut_velocities_rad_s, *axial_loads_n),
                               float)
            if len(path) == 3 * k:
                return path
    except (TypeError, ValueError):     # a number, an iterator, nested sequences
        pass
    cols = []
    for points in (nut_angles_rad, nut_velocities_rad_s, axial_loads_n):
        try:
            cols.append(np.fromiter(points, float))
        except (TypeError, ValueError):     # a number, or nested sequences: flattened
            cols.append(np.asarray(points, dtype=float).ravel())
    k = len(cols[0])
    if k == 0 or len(cols[1]) != k or len(cols[2]) != k:
        raise ValueError(f"step_path: {k} angles, {len(cols[1])} velocities and "
                         f"{len(cols[2])} loads (one of each per step, at least one)")
    return np.concatenate(cols)


def _groups(rear, front, forces):
    """B2B contact groups [(ball ids rear-first, forces)] of the active pairs in chain order."""
    groups = []
    chain_ids, chain_f = [], []
    for r, f, force in zip(rear, front, forces):
        if chain_ids and chain_ids[-1] == r:
            chain_ids.append(f)
            chain_f.append(force)
        else:
            if chain_ids:
                groups.append((tuple(chain_ids), tuple(chain_f)))
            chain_ids, chain_f = [r, f], [force]
    if chain_ids:
        groups.append((tuple(chain_ids), tuple(chain_f)))
    return groups


_COMPILED_WARM_SOLVE = WholeScrew._warm_solve
