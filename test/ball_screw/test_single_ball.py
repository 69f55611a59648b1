"""Single ball (Eqs. 34-55): Jacobian, power balance, contact state, symmetry."""

import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import geometry as geo


def _solve(model, theta_deg, sign=1.0, load=25.0):
    sol = model.cold_solve(np.radians([theta_deg]), 0.0, 0.0, sign, load)
    assert sol.converged
    return sol


def test_jacobian_matches_finite_differences(model):
    b = model.ball
    rng = np.random.default_rng(0)
    sol = model.cold_solve(np.radians([0.0, 2.0, -3.0]), 0.0, 0.0, 1.0, 75.0)
    x = sol.x + rng.normal(0.0, 0.05, sol.x.shape)
    centres = b.arc_centres(np.radians([0.0, 2.0, -3.0]), 0.0, 0.0)
    t = b.evaluate(x, sol.u, centres, 1.0)
    jac = np.concatenate([t["d_force"], t["d_moment"]], axis=1)
    h = 1e-6
    for k in range(7):
        xp, xm, up, um = x.copy(), x.copy(), sol.u, sol.u
        if k < 6:
            xp[:, k] += h
            xm[:, k] -= h
        else:
            up, um = sol.u + h, sol.u - h
        fp = b.evaluate(xp, up, centres, 1.0, False)
        fm = b.evaluate(xm, um, centres, 1.0, False)
        num = (np.concatenate([fp["force"], fp["moment"]], axis=1)
               - np.concatenate([fm["force"], fm["moment"]], axis=1)) / (2 * h)
        scale = np.abs(jac).max(axis=2)
        # Tolerance: central differences of a bicubic map, ~1e-7 relative.
        assert np.all(np.abs(jac[:, :, k] - num) <= 1e-5 * scale + 1e-12)


@pytest.mark.parametrize("theta_deg, ratio", [(0.0, 0.55465), (2.0, 0.56387),
                                              (3.0, 0.56823)])
def test_free_orbit_ratio_matches_independent_reimplementation(model, theta_deg, ratio):
    # Reference: an independent re-implementation of Sec. 3 (25 N per ball, two-ball module).
    sol = model.cold_solve(np.radians([0.0, theta_deg]), 0.0, 0.0, 1.0, 50.0)
    assert sol.converged
    assert sol.x[1, 2] == pytest.approx(ratio, abs=2e-4)


def test_three_point_contact_at_50n(model):
    # That re-implementation: SL ~ NR ~ 38-41 N, NL ~ 5-7 N, SR unloaded (zero preload,
    # Coulomb friction).
    load = _solve(model, 0.0).terms["load"][0]
    assert load[1] == 0.0
    assert 35.0 < load[0] < 42.0 and 35.0 < load[2] < 42.0
    assert 3.0 < load[3] < 8.0


@pytest.mark.parametrize("theta_deg", [0.0, 2.0, -3.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_power_balance_single_ball(model, theta_deg, sign):
    b = model.ball
    sol = _solve(model, theta_deg, sign)
    torque = sol.terms["nut_torque"].sum() - 25.0 * b.r_gear
    loss = sol.terms["loss"].sum()
    assert sign * torque == pytest.approx(loss, rel=1e-7)
    assert loss > 0.0


def test_mirror_symmetry(model):
    # Rotation by pi about x_3 maps the screw onto itself: (theta, W, omega_N) ->
    # (-theta, -W, -omega_N), SL <-> SR, NL <-> NR, omega_B -> -omega_B.
    a = _solve(model, 2.0, 1.0, 25.0)
    m = _solve(model, -2.0, -1.0, -25.0)
    assert m.terms["load"][0] == pytest.approx(a.terms["load"][0][[1, 0, 3, 2]], rel=1e-6)
    assert m.x[0, 2] == pytest.approx(-a.x[0, 2], rel=1e-8)
    assert m.terms["loss"].sum() == pytest.approx(a.terms["loss"].sum(), rel=1e-7)


def test_b2b_separation_exact_helix():
    sep = geo.b2b_contact_separation(2.778e-3, 20e-3, 16.5e-3)
    chord = np.linalg.norm(geo.nominal_ball_centre(sep, 16.5e-3, 20e-3)
                           - geo.nominal_ball_centre(0.0, 16.5e-3, 20e-3))
    assert chord == pytest.approx(2 * 2.778e-3, rel=1e-12)
    # Eq. (56) (circle of radius L/2pi) differs by ~0.02 %.
    assert 2 * geo.b2b_contact_angle(2.778e-3, 20e-3, 16.5e-3) == pytest.approx(sep, rel=1e-3)
    assert math.degrees(sep) * 37 / 720 == pytest.approx(0.978, abs=1e-3)
