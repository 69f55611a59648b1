"""Two-ball module (Sec. 3.3, Table 5)."""

import math

import pytest

from bb_friction_ros.ball_screw.module import solve_two_ball_module


@pytest.fixture(scope="module")
def cases(model):
    return {th: solve_two_ball_module(model, 0.0, math.radians(th), 50.0) for th in (2, 3)}


def test_table5_b2b_force(cases):
    a, b = cases[2], cases[3]
    assert a.converged and b.converged
    # The ratio (b)/(a) is physics: paper 1.505 (FEA 1.506); 1 % tolerance.
    assert b.f_b2b_n / a.f_b2b_n == pytest.approx(2.89 / 1.92, rel=0.01)
    # KNOWN GAP, not a paper assertion: absolute F_B2B is ~0.54 x the paper's 1.92 / 2.89 N
    # (docs/assumptions_ball_screw.md).  Regression guard against the independent
    # re-implementation of Sec. 3 (Table 4, E = 210 GPa, 50 N shared, zero preload), which
    # found 1.04 / 1.56 N; 2 %.
    assert a.f_b2b_n == pytest.approx(1.04, rel=0.02)
    assert b.f_b2b_n == pytest.approx(1.56, rel=0.02)


def test_table5_friction_increase(cases):
    # Paper 39.2 % / 60.2 %; issue tolerance +-8 percentage points.
    assert 100 * cases[2].friction_increase == pytest.approx(39.2, abs=8.0)
    assert 100 * cases[3].friction_increase == pytest.approx(60.2, abs=8.0)


def test_table5_power_balance(cases):
    for c in cases.values():
        assert c.power_balance_error < 1e-6


def test_table5_faster_ball_is_rear(cases):
    # theta > 0 rotates beta_SL down and beta_SR up: that ball orbits faster (free orbit
    # ratios 0.55465 / 0.56387 / 0.56823 at 0 / 2 / 3 deg, docs/assumptions_ball_screw.md).
    for c in cases.values():
        assert c.rear_ball == 2
        assert c.omega_ratio_free[1] > c.omega_ratio_free[0]


def test_equal_theta_gives_no_b2b(model):
    r = solve_two_ball_module(model, 0.0, 0.0, 50.0)
    assert r.converged
    assert abs(r.f_b2b_n) < 1e-6
    assert abs(r.friction_increase) < 1e-6


def test_table5_mirror(model, cases):
    m = solve_two_ball_module(model, 0.0, -math.radians(2.0), -50.0, -2 * math.pi)
    assert m.f_b2b_n == pytest.approx(cases[2].f_b2b_n, rel=1e-6)
    assert m.torque_nm == pytest.approx(-cases[2].torque_nm, rel=1e-6)
