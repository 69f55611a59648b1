"""Low-order numerical model (Eqs. 1-10): paper values and physical invariants."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.linear_bearing import kernel
from bb_friction_ros.linear_bearing.case_study import LinearPairCase
from bb_friction_ros.linear_bearing.geometry import (contact_forces_diagonal,
                                                     contact_forces_rigid,
                                                     deviated_contact_angles)
from bb_friction_ros.linear_bearing.numerical import LinearBearingModel
from invariants import check_linear_group, paper_approx

THETA = paper.TABLE1["theta_rad"]


@pytest.fixture(scope="module")
def cfg():
    return load_linear_bearing()


@pytest.fixture(scope="module")
def model(cfg):
    return LinearBearingModel(cfg)


def make_ball(model, cfg, theta, rho, tr=0.0, tl=0.0):
    beta = deviated_contact_angles(cfg.nominal_contact_angle_rad, -theta, theta, tr, tl)
    return model.ball(beta, contact_forces_rigid(beta, rho * cfg.vertical_load_n,
                                                 cfg.vertical_load_n))


def eps_of(sol, cfg):
    return sol.balls[0].v_b_m_s / (0.5 * cfg.groove_velocity_m_s) - 1.0


def test_rigid_statics_balance_and_diagonal_limit(cfg):
    """Loads balance the ball and the top groove; without deviation they are the diagonal loads."""
    beta = deviated_contact_angles(cfg.nominal_contact_angle_rad, -THETA, THETA, 0.0, 0.0)
    q = contact_forces_rigid(beta, -60.0, 100.0)
    from bb_friction_ros.linear_bearing.geometry import outward_normals
    n = outward_normals(beta)
    assert np.allclose((q[:, None] * n).sum(axis=0), 0.0, atol=1e-12)
    assert np.allclose(-(q[2:, None] * n[2:]).sum(axis=0), [-60.0, -100.0], atol=1e-12)
    beta0 = np.full(4, cfg.nominal_contact_angle_rad)
    assert np.allclose(contact_forces_rigid(beta0, -60.0, 100.0),
                       contact_forces_diagonal(cfg.nominal_contact_angle_rad, -60.0, 100.0))


def test_table2_numerical_eps(model, cfg):
    """Table 2 (a): numerical eps_1 (tolerance and reason: ``paper.EPS1_NUM``)."""
    sol = model.solve_ball(make_ball(model, cfg, THETA, -0.6))
    check_linear_group(sol, cfg.groove_velocity_m_s)
    assert eps_of(sol, cfg) * 100 == paper_approx(paper.EPS1_NUM)


def test_table3_b2b_force_numerical(model, cfg):
    """Table 3 (a): numerical F_B2B (tolerance and reason: ``paper.F_B2B_NUM``)."""
    balls = [make_ball(model, cfg, THETA, -0.6), make_ball(model, cfg, THETA, 0.6)]
    sol = model.solve_group(balls)
    check_linear_group(sol, cfg.groove_velocity_m_s, forced=True)
    assert sol.b2b_force_n[0] == paper_approx(paper.F_B2B_NUM)


def test_table2_case_b_no_contact(model, cfg):
    """Table 2/3 (b): matched top deviations give eps = 0 and no B2B force."""
    balls = [make_ball(model, cfg, THETA, r, -THETA, THETA) for r in (-0.6, 0.6)]
    row = model.solve_row(balls, [0.0])
    assert row.converged
    assert [len(g) for g in row.groups] == [1, 1]
    for s in row.free:
        assert abs(eps_of(s, cfg)) < 1e-12


@pytest.mark.parametrize("theta_deg,rho", [(2.0, -0.6), (-3.0, 0.6), (1.0, 0.3), (0.5, -0.1)])
def test_power_balance(model, cfg, theta_deg, rho):
    """Drive power v x F = sum of ball-groove losses + B2B loss, to 1e-9 relative."""
    th = math.radians(theta_deg)
    for balls in ([make_ball(model, cfg, th, rho)],
                  [make_ball(model, cfg, th, rho), make_ball(model, cfg, th, -rho)]):
        check_linear_group(model.solve_group(balls), cfg.groove_velocity_m_s, forced=True)


def test_mirror_symmetry(model, cfg):
    """Mirroring x maps (theta, rho) to (-theta, -rho): the ball speed is unchanged."""
    for th, rho in ((THETA, -0.6), (math.radians(1.3), 0.2)):
        a = model.solve_ball(make_ball(model, cfg, th, rho))
        b = model.solve_ball(make_ball(model, cfg, -th, -rho))
        assert eps_of(a, cfg) == pytest.approx(eps_of(b, cfg), abs=1e-12)


@pytest.mark.parametrize("rho", [-0.6, 0.0, 0.45])
def test_no_deviation_means_nominal_speed(model, cfg, rho):
    """Insight (2) of Sec. 2.3.2: without contact-angle deviation, v_B = v/2 for any load."""
    assert abs(eps_of(model.solve_ball(make_ball(model, cfg, 0.0, rho)), cfg)) < 1e-12


def test_jacobian_matches_finite_differences(model, cfg):
    """The analytic Newton Jacobian (including B2B friction terms) is the true derivative."""
    balls = [make_ball(model, cfg, THETA, -0.6), make_ball(model, cfg, THETA, 0.2),
             make_ball(model, cfg, THETA, 0.6)]
    z = model.solve_group(balls).z
    z = z + 0.01 * np.random.default_rng(0).normal(size=z.size)
    v = cfg.groove_velocity_m_s
    _, jac = model._residual(balls, z, v)
    fd = np.zeros_like(jac)
    for i in range(z.size):
        e = np.zeros(z.size)
        e[i] = 1e-7
        fd[:, i] = (model._residual(balls, z + e, v, False)[0]
                    - model._residual(balls, z - e, v, False)[0]) / 2e-7
    assert np.abs(jac - fd).max() < 1e-6


def test_row_complementarity(model, cfg):
    """N balls in a row: forces >= 0, touching free pairs separate, groups share one speed."""
    rhos = [-0.6, 0.4, -0.3, 0.6, -0.5, 0.1]
    balls = [make_ball(model, cfg, THETA, r) for r in rhos]
    gaps = [0.0, 0.0, 0.0, 1e-4, 0.0]
    row = model.solve_row(balls, gaps)
    assert row.converged
    speed = np.empty(len(balls))
    for grp, sol in zip(row.groups, row.solutions):
        check_linear_group(sol, cfg.groove_velocity_m_s)
        speed[grp] = sol.balls[0].v_b_m_s
        assert all(b.v_b_m_s == sol.balls[0].v_b_m_s for b in sol.balls)
    joined = {j for grp in row.groups for j in grp[:-1]}
    for j in range(len(balls) - 1):
        if j not in joined and gaps[j] == 0.0:
            assert speed[j] <= speed[j + 1] + 1e-15
    assert 3 not in joined            # the open gap never transmits force
    assert any(len(g) > 1 for g in row.groups)


def test_two_point_contact_is_flagged(cfg):
    """A contact below the load threshold makes the result say so instead of a silent number."""
    case = LinearPairCase(load_linear_bearing(overrides={"min_contact_load_n": 30.0}))
    res = case.numerical(THETA, -0.6)
    assert not res.valid
    assert any("two-point" in n for n in res.notes)


def test_nonconvergence_is_flagged(model, cfg):
    """A solve stopped early reports converged = False."""
    balls = [make_ball(model, cfg, THETA, -0.6), make_ball(model, cfg, THETA, 0.6)]
    assert not model.solve_group(balls, max_iter=1).converged


@pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")
@pytest.mark.parametrize("theta_deg, rhos", [(2.0, (-0.6, 0.6)), (-1.0, (0.3, -0.2, 0.5)),
                                             (2.5, (-0.6,))])
def test_compiled_kernel_equals_numpy_path(cfg, theta_deg, rhos):
    """The compiled Newton (default) gives the numpy reference's solution and outputs."""
    fast, ref = LinearBearingModel(cfg), LinearBearingModel(cfg)
    ref.use_kernel = False
    balls = [make_ball(fast, cfg, math.radians(theta_deg), r) for r in rhos]
    z0 = np.concatenate([[0.5], np.tile([0.7, 0.0], len(balls)), np.full(len(balls) - 1, 0.1)])
    a, b = fast.solve_group(balls, z0), ref.solve_group(balls, z0)
    assert a.converged and b.converged
    np.testing.assert_allclose(a.z, b.z, rtol=1e-9, atol=1e-12)
    for ma, mb in zip(a.balls, b.balls):
        np.testing.assert_allclose(ma.friction_n, mb.friction_n, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(ma.moment_nm, mb.moment_nm, rtol=1e-9, atol=1e-18)
        np.testing.assert_allclose(ma.loss_w, mb.loss_w, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(a.b2b_force_n, b.b2b_force_n, rtol=1e-9, atol=1e-12)
    # and the kernel's own residual is the numpy residual
    v = cfg.groove_velocity_m_s
    z = a.z + 0.01
    res_k, jac_k = np.empty(z.size), np.empty((z.size, z.size))
    prep = fast._prepare(balls)
    kernel.group_residual(z, prep["nx"], prep["ny"], prep["q"], prep["a"], fast._vg, v,
                          cfg.ball_radius_m, cfg.friction_coefficient, prep["q_ref"],
                          *fast.fmap.hermite_tables, True, res_k, jac_k)
    res_n, jac_n = ref._residual(balls, z, v)
    np.testing.assert_allclose(res_k, res_n, rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(jac_k, jac_n, rtol=1e-10, atol=1e-12)
