"""Single ball (Eqs. 34-55): Jacobian, power balance, contact state, symmetry."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.ball_screw import geometry as geo
from invariants import check_screw_balls, paper_approx


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
    check_screw_balls(_solve(model, theta_deg, sign), sign, 25.0, model.ball.r_gear)


def test_mirror_symmetry(model):
    # Rotation by pi about x_3 maps the screw onto itself: (theta, W, omega_N) ->
    # (-theta, -W, -omega_N), SL <-> SR, NL <-> NR, omega_B -> -omega_B.
    a = _solve(model, 2.0, 1.0, 25.0)
    m = _solve(model, -2.0, -1.0, -25.0)
    assert m.terms["load"][0] == pytest.approx(a.terms["load"][0][[1, 0, 3, 2]], rel=1e-6)
    assert m.x[0, 2] == pytest.approx(-a.x[0, 2], rel=1e-8)
    assert m.terms["loss"].sum() == pytest.approx(a.terms["loss"].sum(), rel=1e-7)
    check_screw_balls(m, -1.0, -25.0, model.ball.r_gear)


def test_b2b_separation_exact_helix():
    t4 = paper.TABLE4
    r_b, lead, r_p = t4["ball_radius_m"], t4["lead_m"], t4["pitch_radius_m"]
    sep = geo.b2b_contact_separation(r_b, lead, r_p)
    chord = np.linalg.norm(geo.nominal_ball_centre(sep, r_p, lead)
                           - geo.nominal_ball_centre(0.0, r_p, lead))
    assert chord == pytest.approx(2 * r_b, rel=1e-12)
    # Eq. (56) (circle of radius L/2pi) differs by ~0.02 %.
    assert 2 * geo.b2b_contact_angle(r_b, lead, r_p) == pytest.approx(sep, rel=1e-3)
    # Sec. 3.4: 37 balls in two loaded turns occupy 97.8 % of the track
    occupation = 100 * math.degrees(sep) * t4["n_balls"] / 720
    assert occupation == paper_approx(paper.OCCUPATION_RATIO)
