"""
Standard output tests: the invariants that every model's outputs must satisfy.

As PyBaMM's standard output tests do for its battery models, one set of checks is reused by
the tests of every model here: the linear bearing's numerical and analytical models, the
ball screw's single balls, two-ball module and whole screw, and the runner's (and node's)
predictions.  Each ``check_*`` asserts, for one model output:

- finiteness of every number it reports;
- power balance: the drive power equals the sum of the friction losses (energy is neither
  made nor lost in a quasi-static solve);
- sum of parts: a prediction's total equals ball-to-groove + ball-to-ball + empirical terms
  (for a model step alone this is the power balance divided by omega_N, so not checked twice);
- sign: losses and contact forces are never negative, friction opposes the motion;
- symmetry (``assert_mirror``): mirrored inputs give equal or sign-reversed outputs.

Each tolerance is the one the tests held before this module existed, with its reason. Paper
numbers are checked with ``assert_paper`` against ``bb_friction_ros.paper``.
"""

import math

import numpy as np
import pytest

# Newton to 1e-12 on the linear bearing's scaled residual: the balance closes to ~1e-12.
LINEAR_POWER_REL = 1e-9
# A loss is an integral of |slip| x pressure >= 0; -1e-15 W allows the quadrature's rounding.
LOSS_FLOOR_W = -1e-15
# The ball screw solves to tolerance 1e-8 on a residual scaled by the per-ball load (1e-10
# until 2026-11, docs/model_schedule.md); the balance of one cold-solved ball closes to
# 1.2e-6 there (6e-8 at 1e-10, measured over test_single_ball's cases), hence 1e-5.
SCREW_BALL_POWER_REL = 1e-5
# Whole screw and module: the total torque comes from the nut's equilibrium, the parts from
# the losses; they agree to the solver's power balance (<= 4.4e-8 in the Sec. 3.4 run).
SCREW_POWER_REL = 1e-6


def paper_approx(value):
    """Return ``pytest.approx`` of a ``paper.PaperValue`` with its own tolerance."""
    assert value.target and value.band is None, f"{value.key}: not an approx target"
    return pytest.approx(value.value, rel=value.rel, abs=value.abs)


def assert_paper(value, ours):
    """Assert that ``ours`` meets the paper value ``value`` within its stated tolerance."""
    assert value.target, f"{value.key} is not a target: {value.reason}"
    if value.band is not None:
        lo, hi = value.band
        assert lo <= ours <= hi, (f"{value.key} = {ours} outside {value.band} {value.unit} "
                                  f"(paper {value.value}, {value.source}): {value.reason}")
    else:
        assert ours == paper_approx(value), (f"{value.key} ({value.source}): {value.reason}")


def assert_finite(**named):
    """Assert that every named number or array is finite, naming the first that is not."""
    for name, x in named.items():
        assert np.all(np.isfinite(np.asarray(x, dtype=float))), f"{name} is not finite: {x}"


def assert_power_balance(drive_w, losses_w, rel):
    """Drive power = sum of losses, to ``rel`` of the losses."""
    assert_finite(drive_w=drive_w, losses_w=losses_w)
    assert drive_w == pytest.approx(losses_w, rel=rel), "drive power != sum of losses"


def assert_sum_of_parts(total, parts, rel):
    """The total equals the sum of its parts, to ``rel`` of the total."""
    assert_finite(total=total, parts=list(parts))
    assert math.fsum(parts) == pytest.approx(total, rel=rel), "parts do not sum to the total"


def assert_mirror(a, b, even=(), odd=(), rel=1e-6):
    """
    Mirror symmetry: ``b`` is the output for the mirror image of ``a``'s inputs.

    Each attribute named in ``even`` is unchanged, each in ``odd`` changes sign, to ``rel``.
    """
    for name in even:
        assert getattr(b, name) == pytest.approx(getattr(a, name), rel=rel), name
    for name in odd:
        assert getattr(b, name) == pytest.approx(-getattr(a, name), rel=rel), name


# --- linear bearing -------------------------------------------------------------------------
def check_linear_group(sol, groove_velocity_m_s, forced=False, rel=LINEAR_POWER_REL):
    """
    Numerical model, one group of touching balls (``GroupSolution``, Eqs. 1-10).

    Drive power v x (z-friction the top groove exerts on the balls: contacts TR and TL) =
    sum of the ball-groove losses + the B2B loss; losses >= 0; B2B forces >= 0 unless the
    group was ``forced`` together by the caller (``solve_group``) rather than found by the
    complementarity of Eq. (9) (``solve_row``).
    """
    assert sol.converged
    for b in sol.balls:
        assert_finite(v_b_m_s=b.v_b_m_s, friction_n=b.friction_n, loss_w=b.loss_w)
        assert np.all(b.loss_w >= LOSS_FLOOR_W)
    assert_finite(b2b_force_n=sol.b2b_force_n, b2b_loss_w=sol.b2b_loss_w)
    # a forced pair that would rather separate pulls (F < 0) and its Eq. (7) loss is < 0
    assert forced or (np.all(sol.b2b_force_n >= 0.0) and np.all(sol.b2b_loss_w >= 0.0))
    drive = groove_velocity_m_s * sum(b.friction_n[2:].sum() for b in sol.balls)
    losses = sum(b.loss_w.sum() for b in sol.balls) + sol.b2b_loss_w.sum()
    assert_power_balance(drive, losses, rel)


def check_linear_pair(res):
    """
    Two-ball case of Sec. 2.4 (``PairResult`` or the analytical grid dict), either model.

    Finite; P_f > 0 and P_fB2B, F_B2B >= 0; contact only where ball 1 is faster (Eqs. 9, 30).
    Eq. (32) makes the B2B loss of the analytical model proportional to its force.
    """
    get = res.get if isinstance(res, dict) else (lambda k: getattr(res, k))
    if isinstance(res, dict):
        eps1, eps2 = res["eps1"], res["eps2"]
    else:
        eps1, eps2 = res.eps
    f, p_f, p_b2b = (np.asarray(get(k), dtype=float) for k in ("f_b2b_n", "p_f_w", "p_b2b_w"))
    assert_finite(eps1=eps1, eps2=eps2, f_b2b_n=f, p_f_w=p_f, p_b2b_w=p_b2b)
    assert np.all(p_f > 0.0) and np.all(p_b2b >= 0.0) and np.all(f >= 0.0)
    assert np.all((f > 0) <= (np.asarray(eps1) > np.asarray(eps2))), "contact with eps1 <= eps2"
    assert np.all((p_b2b > 0) == (f > 0)), "B2B loss without B2B force, or the reverse"


# --- ball screw -----------------------------------------------------------------------------
def check_screw_balls(sol, sign, axial_load_n, gear_ratio_m, rel=SCREW_BALL_POWER_REL):
    """
    Balls without B2B contact, solved together (``cold_solve``, Eqs. 34-55), per unit omega_N.

    sign(omega_N) x friction torque (nut torque - W p / 2pi) = sum of the contact losses > 0.
    """
    assert sol.converged
    torque = sol.terms["nut_torque"].sum() - axial_load_n * gear_ratio_m
    loss = sol.terms["loss"].sum()
    assert_finite(torque=torque, loss=loss, loads_n=sol.terms["load"])
    assert np.all(sol.terms["load"] >= 0.0)
    assert_power_balance(sign * torque, loss, rel)
    assert loss > 0.0


def check_module(res, tol=SCREW_POWER_REL):
    """
    Two-ball module of Sec. 3.3 (``ModuleResult``).

    |omega_N T_f - losses| / losses < tol; total loss = ball-groove + B2B; F_B2B >= 0;
    adding a B2B contact never lowers the loss below the free balls'.
    """
    assert res.converged
    assert_finite(f_b2b_n=res.f_b2b_n, torque_nm=res.torque_nm, loss_w=res.loss_w,
                  b2b_loss_w=res.b2b_loss_w, loads_n=res.loads_n)
    assert res.power_balance_error < tol
    assert res.f_b2b_n >= 0.0 and res.b2b_loss_w >= 0.0 and res.loss_no_b2b_w > 0.0
    assert res.loss_w >= res.b2b_loss_w


def check_step(r, rel=SCREW_POWER_REL):
    """
    One whole-screw step (``StepResult``, Sec. 3.4).

    omega_N T_f = sum of losses >= 0; B2B forces >= 0 and each contact group lists one force
    fewer than its balls; the B2B torque is zero without a group.  T_f = T_b2g + T_b2b is not
    asserted apart: the parts are the losses over omega_N, so it is the power balance again.
    """
    assert r.converged
    assert_finite(torque_total_nm=r.torque_total_nm, torque_b2g_nm=r.torque_b2g_nm,
                  torque_b2b_nm=r.torque_b2b_nm, drive_power_w=r.drive_power_w,
                  loss_w=r.loss_w, azimuth_rad=r.azimuth_rad, omega_b_rad_s=r.omega_b_rad_s,
                  loads_n=r.loads_n, b2b_forces_n=r.b2b_forces_n)
    assert r.loss_w >= 0.0
    if r.loss_w > 0.0:
        assert_power_balance(r.drive_power_w, r.loss_w, rel)
    else:
        assert r.torque_total_nm == 0.0 and r.drive_power_w == 0.0
    assert np.all(r.b2b_forces_n >= 0.0)
    for ids, forces in r.groups:
        assert len(ids) == len(forces) + 1
    if not r.groups:
        assert r.torque_b2b_nm == 0.0


def check_prediction(p, rel=SCREW_POWER_REL):
    """
    One runner prediction (``runner.Prediction``, or a published message as a dict).

    Total = ball-groove + B2B + empirical terms, finite; B2B forces >= 0.
    """
    get = p.get if isinstance(p, dict) else (lambda k: getattr(p, k))
    parts = [get(k) for k in ("torque_b2g_nm", "torque_b2b_nm", "torque_empirical_nm")]
    assert_sum_of_parts(get("torque_total_nm"), parts, rel)
    if not isinstance(p, dict):
        for _, forces in p.groups:
            assert all(f >= 0.0 for f in forces)
