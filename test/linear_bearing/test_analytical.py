"""Analytical model (Eqs. 16-33) against the paper and against the numerical model."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.contact.hertz import HertzContact
from bb_friction_ros.linear_bearing import analytical as an
from bb_friction_ros.linear_bearing.case_study import LinearPairCase
from bb_friction_ros.linear_bearing.geometry import contact_forces_diagonal
from bb_friction_ros.linear_bearing.mitigation import (matched_top_deviations,
                                                       two_ball_relative_motion)
from invariants import check_linear_pair, paper_approx

THETA = paper.TABLE1["theta_rad"]
B0 = paper.TABLE1["nominal_contact_angle_rad"]


@pytest.fixture(scope="module")
def case():
    return LinearPairCase(load_linear_bearing())


def test_table2_analytical_eps(case):
    """Table 2 (a): analytical eps_1 = -eps_2 (tolerances: ``paper.EPS1_AN``, ``EPS2_AN``)."""
    res = case.analytical(THETA, -0.6)
    check_linear_pair(res)
    assert res.eps[0] * 100 == paper_approx(paper.EPS1_AN)
    assert res.eps[1] * 100 == paper_approx(paper.EPS2_AN)
    assert res.eps[1] == pytest.approx(-res.eps[0], abs=1e-15)


def test_table3_b2b_force_analytical(case):
    """Table 3: analytical F_B2B, case (a) (``paper.F_B2B_AN``) and case (b): 0 N."""
    assert case.analytical(THETA, -0.6).f_b2b_n == paper_approx(paper.F_B2B_AN)
    res_b = case.analytical(THETA, -0.6, -THETA, THETA)
    check_linear_pair(res_b)
    assert res_b.f_b2b_n == paper_approx(paper.F_B2B_B)


def test_eq33_is_eq22_for_the_case_study():
    """Eq. (33) is Eq. (22) with the Sec. 2.4.1 loads."""
    th, rho = np.meshgrid(np.radians(np.linspace(-3, 3, 7)), np.linspace(-0.6, 0.6, 5))
    f = contact_forces_diagonal(B0, rho * 100.0, 100.0)
    dbeta = np.stack([-th, th, 0 * th, 0 * th], axis=-1)
    assert np.allclose(an.velocity_deviation_eq22(dbeta, f[0], f[1], B0),
                       an.velocity_deviation_eq33(th, rho)[0], atol=1e-15)


def test_eq16_19_21_reduce_to_eq22_with_diagonal_loads():
    """Eqs. (16)+(19)+(21) with F_BL = F_TR, F_BR = F_TL give Eq. (22) (its derivation)."""
    t1 = paper.TABLE1
    r_b = t1["ball_radius_m"]
    hz = HertzContact.ball_in_straight_groove(r_b, t1["conformity"], t1["youngs_modulus_pa"],
                                              t1["poisson_ratio"])
    rng = np.random.default_rng(1)
    for _ in range(5):
        dbeta = np.radians(rng.uniform(-2, 2, 4))
        fu, fd = rng.uniform(20, 150, 2)
        loads = np.array([fu, fd, fu, fd])
        d_eta = an.velocity_centre_deviation(dbeta, loads, np.full(4, B0), r_b,
                                             hz.psi(r_b), hz.ellipticity, paper.K_F.value)
        assert an.velocity_deviation_eq21(dbeta, d_eta, B0) == pytest.approx(
            an.velocity_deviation_eq22(dbeta, fu, fd, B0), abs=1e-12)


def test_design_rule_nulls_velocity_deviation():
    """Sec. 2.4.2: dbeta_TR = dbeta_BL, dbeta_TL = dbeta_BR gives eps = 0 for any loads."""
    rng = np.random.default_rng(2)
    bl, br = np.radians(rng.uniform(-3, 3, (2, 50)))
    tr, tl = matched_top_deviations(bl, br)
    dbeta = np.stack([bl, br, tr, tl], axis=-1)
    fu, fd = rng.uniform(1, 200, (2, 50))
    assert np.abs(an.velocity_deviation_eq22(dbeta, fu, fd, B0)).max() < 1e-15


def test_fig8_analytical_matches_numerical_at_small_deviation(case):
    """Fig. 8: the two models agree where the approximations hold (small |theta|, |rho|)."""
    for th, rho in ((0.5, -0.1), (1.0, 0.2), (-0.5, 0.15)):
        num = case.numerical(math.radians(th), rho)
        ana = case.analytical(math.radians(th), rho)
        assert ana.eps[0] - ana.eps[1] == pytest.approx(num.eps[0] - num.eps[1], rel=0.12)


def test_analytical_grid_is_vectorised(case):
    """A theta x rho grid evaluates in one call and equals the scalar calls."""
    th = np.radians(np.linspace(-3, 3, 100))
    rho = np.linspace(-0.6, 0.6, 100)
    grid = case.analytical(th[None, :], rho[:, None])
    assert grid["f_b2b_n"].shape == (100, 100)
    check_linear_pair(grid)
    s = case.analytical(th[7], rho[90])
    assert grid["f_b2b_n"][90, 7] == pytest.approx(s.f_b2b_n, rel=1e-12)
    assert np.all(grid["f_b2b_n"] >= 0)


def test_fig10_gap_closes_then_stays(case):
    """Fig. 10: the 0.1 R_B gap closes at gap/((eps1-eps2) v/2) in case (a), never in (b)."""
    cfg = case.cfg
    gap0 = 0.1 * cfg.ball_radius_m
    res_a = case.analytical(THETA, -0.6)
    t_hit = gap0 / ((res_a.eps[0] - res_a.eps[1]) * 0.5 * cfg.groove_velocity_m_s)
    t = np.array([0.0, 0.5 * t_hit, t_hit, 2 * t_hit])
    _, _, gap = two_ball_relative_motion(*res_a.eps, cfg.groove_velocity_m_s, gap0, t)
    assert gap == pytest.approx([gap0, 0.5 * gap0, 0.0, 0.0], abs=1e-15)
    res_b = case.analytical(THETA, -0.6, -THETA, THETA)
    _, _, gap_b = two_ball_relative_motion(*res_b.eps, cfg.groove_velocity_m_s, gap0, t)
    assert np.allclose(gap_b, gap0)
