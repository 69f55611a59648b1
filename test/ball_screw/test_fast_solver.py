"""Compiled kernel, secant warm start and real-time mode: same answers as the numpy path."""

import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import geometry as geo
from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.simulation import run_whole_screw
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from invariants import check_module, check_step

pytestmark = pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")

STEPS = 40    # 144 deg of nut rotation: chains form, grow and start to decay
# These tests compare two implementations, each converged to the solver tolerance, so
# their answers differ by about that tolerance.  Their bounds (1e-8 relative and finer) were
# set with the tolerance at 1e-10 and test the kernel sharply there; the default is 1e-8
# since 2026-11 (docs/model_schedule.md), so this file pins 1e-10 rather than widening them.
COMPARE_TOLERANCE = 1e-10


@pytest.fixture(scope="module")
def config():
    """The default configuration at the comparison tolerance."""
    return load_ball_screw(overrides={"solver": {"tolerance": COMPARE_TOLERANCE}})


@pytest.fixture(scope="module")
def model(config):
    """ScrewModel (compiled kernel) at the comparison tolerance."""
    return ScrewModel(config)


@pytest.fixture(scope="module")
def numpy_model(config):
    """A second model that solves with the numpy path (lagged B2B Jacobian)."""
    model = ScrewModel(config)
    model.solver.use_kernel = False
    return model


def _kernel_evaluate(model, x, u, centres, sign, scale):
    b, sv = model.ball, model.solver
    n = x.shape[0]
    res, jac, dax = np.empty((n, 6)), np.empty((n, 6, 7)), np.empty((n, 7))
    terms, per_contact = np.empty((n, 10)), np.empty((n, 4, 3))
    cst = kernel.pack_constants(b)
    axial = kernel.evaluate_balls(x, u, np.zeros(n), centres, sign, cst, sv._k_load,
                                  sv._k_axis, sv._on_nut, sv._coef[0], sv._coef[1], sv._grid,
                                  scale, True, res, jac, dax, terms, per_contact)
    kernel.contact_angles(x, u, np.zeros(n), centres, cst, sv._on_nut, per_contact)
    return axial, res, jac, dax, terms, per_contact


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_kernel_evaluation_equals_numpy(model, sign):
    b = model.ball
    theta = np.radians([0.0, 2.0, -3.0])
    sol = model.cold_solve(theta, 0.0, 0.0, sign, 75.0)
    x = sol.x + np.random.default_rng(1).normal(0.0, 0.05, sol.x.shape)
    centres = b.arc_centres(theta, 0.0, 0.0)
    scale = 25.0
    t = b.evaluate(x, sol.u, centres, sign)
    axial, res, jac, dax, terms, per_contact = _kernel_evaluate(model, x, sol.u, centres,
                                                                sign, scale)
    ref_res = np.concatenate([t["force"], t["moment"] / b.r_b], axis=1) / scale
    ref_jac = np.concatenate([t["d_force"], t["d_moment"] / b.r_b], axis=1) / scale
    assert np.abs(res - ref_res).max() <= 1e-13 * np.abs(ref_res).max()
    assert np.abs(jac - ref_jac).max() <= 1e-13 * np.abs(ref_jac).max()
    assert np.abs(dax - t["d_axial"] / scale).max() <= 1e-13 * np.abs(dax).max()
    assert axial == pytest.approx(t["axial"].sum(), rel=1e-13)
    for col, key in ((6, "loss"), (7, "nut_torque"), (8, "axial")):
        assert terms[:, col] == pytest.approx(t[key], rel=1e-12, abs=1e-15)
    assert np.array_equal(per_contact[..., 0], t["load"])
    assert per_contact[..., 2] == pytest.approx(t["angle"], abs=1e-14)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_kernel_b2b_terms_and_exact_direction_jacobian(model, sign):
    b2b = model.b2b
    rng = np.random.default_rng(2)
    x = model.ball.rolling_guess(3, sign) + rng.normal(0.0, 0.1, (3, 6))
    rear, front = np.array([0, 1]), np.array([1, 2])
    lin = b2b.linear_terms(sign)

    def terms(xx):
        out = [np.empty((2, 6)), np.empty((2, 6)), np.empty(2)] \
            + [np.empty((2, 6, 6)) for _ in range(4)]
        kernel.b2b_terms(xx, rear, front, *lin, True, *out)
        return out

    g_r, g_f, speed, dgr_r, dgr_f, dgf_r, dgf_f = terms(x)
    ref = b2b.unit_terms(x[rear], x[front], sign)
    for got, want in zip((g_r, g_f, speed), ref):
        assert got == pytest.approx(want, abs=1e-14)
    h = 1e-6
    for j in range(6):
        for ball, d_rear, d_front in ((0, dgr_r[0], dgf_r[0]), (1, dgr_f[0], dgf_f[0])):
            xp, xm = x.copy(), x.copy()
            xp[ball, j] += h
            xm[ball, j] -= h
            tp, tm = terms(xp), terms(xm)
            assert (tp[0][0] - tm[0][0]) / (2 * h) == pytest.approx(d_rear[:, j], abs=1e-8)
            assert (tp[1][0] - tm[1][0]) / (2 * h) == pytest.approx(d_front[:, j], abs=1e-8)


@pytest.mark.parametrize("theta2_deg", [2.0, 3.0])
def test_two_ball_module_kernel_equals_numpy(model, numpy_model, theta2_deg):
    fast = solve_two_ball_module(model, 0.0, math.radians(theta2_deg), 50.0)
    ref = solve_two_ball_module(numpy_model, 0.0, math.radians(theta2_deg), 50.0)
    check_module(fast)
    check_module(ref)
    assert fast.f_b2b_n == pytest.approx(ref.f_b2b_n, rel=1e-8)
    assert fast.friction_increase == pytest.approx(ref.friction_increase, rel=1e-8)
    assert fast.loads_n == pytest.approx(ref.loads_n, rel=1e-8, abs=1e-9)


@pytest.fixture(scope="module")
def numpy_run(config, numpy_model):
    return run_whole_screw(config, n_steps=STEPS, screw=WholeScrew(config, numpy_model))[0]


def _assert_same_run(results, ref):
    scale = max(abs(r.torque_total_nm) for r in ref)
    for r, q in zip(results, ref):
        check_step(r)
        check_step(q)
        assert r.torque_total_nm == pytest.approx(q.torque_total_nm, abs=1e-8 * scale)
        assert r.torque_b2b_nm == pytest.approx(q.torque_b2b_nm, abs=1e-8 * scale)
        assert r.azimuth_rad == pytest.approx(q.azimuth_rad, abs=1e-10)
        assert r.b2b_forces_n == pytest.approx(q.b2b_forces_n, abs=1e-6)
        assert [g[0] for g in r.groups] == [g[0] for g in q.groups]


def test_whole_screw_kernel_equals_numpy(config, model, numpy_run):
    results = run_whole_screw(config, n_steps=STEPS, screw=WholeScrew(config, model))[0]
    assert max(r.n_groups for r in results) >= 2
    _assert_same_run(results, numpy_run)


def test_secant_warm_start_changes_nothing(config, model, numpy_run, monkeypatch):
    # Without the secant prediction (previous solution only) the answers are the same.
    # (The readable warm solve, whose guesses can be replaced; the compiled one is the same
    # bit for bit, test_compiled_step.)
    monkeypatch.setattr(WholeScrew, "_warm_solve", WholeScrew._warm_solve_numpy)
    monkeypatch.setattr(WholeScrew, "_guesses", lambda self, d_psi: [
        (self._state[0].copy(), self._state[1], self._forces)])
    results = run_whole_screw(config, n_steps=STEPS, screw=WholeScrew(config, model))[0]
    _assert_same_run(results, numpy_run)


def test_realtime_budget_is_never_silent(model, numpy_run):
    cfg = load_ball_screw(overrides={"solver": {"realtime_max_iterations": 2,
                                                "tolerance": COMPARE_TOLERANCE}})
    results = run_whole_screw(cfg, n_steps=STEPS, screw=WholeScrew(cfg, model))[0]
    assert all(r.iterations <= 2 for r in results[1:])
    short = [r for r in results if not r.converged]
    assert short, "a 2-iteration budget cannot converge every step to 1e-10"
    for r in results:
        if r.converged:
            # A step that says converged is as accurate as without the budget.
            ref = numpy_run[int(round(r.t_s / 0.01)) - 1]
            assert r.torque_total_nm == pytest.approx(ref.torque_total_nm, rel=1e-7)


def test_realtime_large_budget_is_the_default(config, model, numpy_run):
    assert config.solver.realtime_max_iterations == 0       # off by default
    cfg = load_ball_screw(overrides={"solver": {"realtime_max_iterations": 1000,
                                                "tolerance": COMPARE_TOLERANCE}})
    results = run_whole_screw(cfg, n_steps=STEPS, screw=WholeScrew(cfg, model))[0]
    _assert_same_run(results, numpy_run)


def test_centres_fast_path_equals_geometry(config, model):
    screw = WholeScrew(config, model)
    phi = screw.track_azimuth()
    theta, centres, shifts = screw._centres(phi)
    e = config.errors
    ref = geo.theta_deviation(phi, e.theta_amplitude_rad, e.theta_cycles_per_rev,
                              e.theta_phase_rad, e.theta_offset_rad)
    assert theta == pytest.approx(ref, abs=1e-15)
    assert centres == pytest.approx(model.ball.arc_centres(ref, 0.0, 0.0), abs=1e-18)
    assert shifts[1] == shifts[2] == 0.0


def test_lead_errors_kernel_equals_numpy(model, numpy_model):
    cfg = load_ball_screw(overrides={"errors": {"nut_lead_error_um": 2.0,
                                                "screw_lead_error_amplitude_um": 1.0},
                                     "solver": {"tolerance": COMPARE_TOLERANCE}})
    fast = run_whole_screw(cfg, n_steps=12, screw=WholeScrew(cfg, model))[0]
    ref = run_whole_screw(cfg, n_steps=12, screw=WholeScrew(cfg, numpy_model))[0]
    _assert_same_run(fast, ref)      # which checks the invariants of every step


def test_more_balls_than_one_chunk_of_lanes_equal_numpy():
    # The kernel takes the balls 64 lanes at a time; past one chunk the Newton direction
    # reads the Jacobian copied out of the lanes, not the lanes themselves.
    cfg = load_ball_screw(overrides={"solver": {"tolerance": COMPARE_TOLERANCE},
                                     "track": {"n_balls": 90, "loaded_turns": 4.9}})
    fast = WholeScrew(cfg, ScrewModel(cfg))
    ref_model = ScrewModel(cfg)
    ref_model.solver.use_kernel = False
    ref = WholeScrew(cfg, ref_model)
    assert fast.n == ref.n == 90 > kernel._CHUNK
    _assert_same_run(run_whole_screw(cfg, n_steps=12, screw=fast)[0],
                     run_whole_screw(cfg, n_steps=12, screw=ref)[0])
