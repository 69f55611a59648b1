"""
Two-ball module of the ball screw (paper Sec. 3.3, Fig. 12(b), Table 5).

Two balls in adjacent positions of the same groove, each with its own screw contact-angle
deviation theta; the axial load is applied to the screw, which may only translate axially, so
both balls share it through the nut's axial displacement.  The balls touch (their helix
separation is the B2B contact separation); contact closes if the rear ball orbits faster
(Eq. 60), and the rear ball is the faster one by construction, as in the paper's cases.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Sec. 3.3, Fig. 12(b), Table 5, Eqs. (54)-(60).

"""

import time
from dataclasses import dataclass

import numpy as np

from bb_friction_ros.ball_screw.screw_model import ScrewModel


@dataclass
class ModuleResult:
    """Table 5 quantities of one two-ball case (SI; losses at the configured omega_N)."""

    f_b2b_n: float
    friction_increase: float
    torque_nm: float
    torque_no_b2b_nm: float
    loss_w: float
    loss_no_b2b_w: float
    b2b_loss_w: float
    omega_ratio_free: tuple
    omega_ratio: float
    rear_ball: int
    loads_n: np.ndarray
    converged: bool
    solve_time_s: float
    power_balance_error: float


def solve_two_ball_module(model, theta1_rad, theta2_rad, axial_load_n, nut_velocity_rad_s=None):
    """
    Table 5: B2B force and friction increase of the two-ball module (Eqs. 54-60).

    Parameters
    ----------
    model : ScrewModel
        Contact model of the screw (its config gives mu, geometry and the default omega_N).
    theta1_rad, theta2_rad : float
        Screw-side contact-angle deviation theta of ball 1 and ball 2 (Fig. 17)  [rad].
    axial_load_n : float
        Axial load W shared by the two balls, force of the balls on the nut along +z  [N].
    nut_velocity_rad_s : float, optional
        Signed nut angular velocity omega_N  [rad/s]; default
        ``config.operation.nut_velocity_rad_s``.

    Returns
    -------
    ModuleResult
        F_B2B [N], friction increase (fraction), friction torques [N m], losses [W] at
        omega_N, free orbit ratios omega_B / omega_N, contact loads [N], convergence and the
        relative power balance error |omega_N T_f - losses| / losses.

    """
    t0 = time.perf_counter()
    cfg = model.config
    omega_n = cfg.operation.nut_velocity_rad_s if nut_velocity_rad_s is None \
        else nut_velocity_rad_s
    sign = 1.0 if omega_n >= 0.0 else -1.0
    b = model.ball
    if model.preload_load() <= 0.0 and abs(axial_load_n) <= cfg.solver.min_axial_load_n:
        # No preload and no load: no ball is loaded, so there is no friction (as in
        # WholeScrew.step), rather than a solve of a system with no stiffness.
        return _unloaded_result(model, sign, axial_load_n, t0)
    centres = b.arc_centres(np.array([theta1_rad, theta2_rad]), 0.0, 0.0)
    scale = model.force_scale(2, axial_load_n)
    free = model.cold_solve(np.array([theta1_rad, theta2_rad]), 0.0, 0.0, sign,
                            axial_load_n)
    if not free.converged or free.x.shape[0] != 2:
        # The free balls did not converge (a failed load continuation even returns a
        # one-ball state): there is no start for the contact solve, and its last iterate is
        # no result.  Flag it, with no numbers, the same on every run.
        return _failed_result(sign, t0)
    rates = free.x[:, 2] * sign
    rear = int(np.argmax(rates))
    front = 1 - rear
    pair_r, pair_f = np.array([rear]), np.array([front])
    # Ball order along the helix follows the motion: put the rear ball behind the front one.
    con = model.solver.solve(free.x.copy(), free.u, centres, sign, axial_load_n, scale,
                             pair_r, pair_f, np.array([True]))
    abs_w = abs(omega_n)

    def friction_torque(sol):
        return float(sol.terms["nut_torque"].sum() - axial_load_n * b.r_gear)

    loss_free = float(free.terms["loss"].sum()) * abs_w
    b2b_loss = float(b.mu * con.forces[0] * con.b2b_speed[0]) * abs_w
    loss = float(con.terms["loss"].sum()) * abs_w + b2b_loss
    torque = friction_torque(con)
    return ModuleResult(
        f_b2b_n=float(con.forces[0]), friction_increase=loss / loss_free - 1.0,
        torque_nm=torque, torque_no_b2b_nm=friction_torque(free), loss_w=loss,
        loss_no_b2b_w=loss_free, b2b_loss_w=b2b_loss,
        omega_ratio_free=tuple(float(r) for r in rates),
        omega_ratio=float(con.x[rear, 2] * sign), rear_ball=rear + 1,
        loads_n=con.terms["load"].copy(), converged=bool(free.converged and con.converged),
        solve_time_s=time.perf_counter() - t0,
        power_balance_error=abs(omega_n * torque - loss) / max(loss, 1e-300))


def _unloaded_result(model, sign, axial_load_n, t0):
    """Zero friction of two unloaded balls (|W| <= solver.min_axial_load_n, no preload)."""
    rate = float(model.ball.rolling_guess(1, sign)[0, 2] * sign)
    return ModuleResult(
        f_b2b_n=0.0, friction_increase=0.0, torque_nm=0.0, torque_no_b2b_nm=0.0, loss_w=0.0,
        loss_no_b2b_w=0.0, b2b_loss_w=0.0, omega_ratio_free=(rate, rate), omega_ratio=rate,
        rear_ball=1, loads_n=np.zeros((2, 4)), converged=True,
        solve_time_s=time.perf_counter() - t0, power_balance_error=0.0)


def _failed_result(sign, t0):
    """Return a non-converged module: NaN numbers (printed as null), ``converged = False``."""
    nan = float("nan")
    return ModuleResult(
        f_b2b_n=nan, friction_increase=nan, torque_nm=nan, torque_no_b2b_nm=nan, loss_w=nan,
        loss_no_b2b_w=nan, b2b_loss_w=nan, omega_ratio_free=(nan, nan), omega_ratio=nan,
        rear_ball=0, loads_n=np.full((2, 4), nan), converged=False,
        solve_time_s=time.perf_counter() - t0, power_balance_error=nan)


__all__ = ["ScrewModel", "ModuleResult", "solve_two_ball_module"]
