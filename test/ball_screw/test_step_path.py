"""
``WholeScrew.step_path`` (an input's steps in one compiled call) is ``step`` called per step.

The runner reaches each input through sub-steps then an answered step; ``step_path`` takes
them all in one call (``kernel.warm_steps``) while they are warm steps, and hands the rest
(a cold start, a reversal, a load of the other sign, no load, a failed warm solve) to
``step``.  Both run the same compiled arithmetic from one numba cache, so the answered
steps agree bit for bit, Newton iterations included; the sub-steps' convergence and
iterations are counted.
"""

import copy
import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw
from invariants import check_step

pytestmark = pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")

STEP_RAD = math.radians(1.8)
DT_S = 0.001


def _paths(inputs=70):
    """
    Per input: the (angle, velocity, load) of its steps, the last one answered.

    Four steps per input at 20 rev/s-like spacing; a reversal, a load change inside a path,
    a load of the other sign, a standing nut and a path with a stop inside on the way.
    """
    angle, out = 0.0, []
    for k in range(inputs):
        sign = 1.0 if k < 30 or k >= 45 else -1.0
        steps = []
        for j in range(4):
            angle += sign * STEP_RAD
            load = 1500.0 if k < 20 else 900.0 + 100.0 * j
            if k >= 55:
                load = -1200.0
            w = 0.0 if k == 50 or (k == 40 and j == 2) else sign * 2.0 * math.pi * 20.0
            steps.append((angle, w, load))
        out.append(steps)
    return out


def _step_by_step(screw, paths):
    """``step`` per step: the answered step's result and the sub-steps' counts per input."""
    out = []
    for steps in paths:
        missed = its = 0
        for j, (a, w, f) in enumerate(steps):
            r = screw.step(a, w, f, DT_S, substep=j < len(steps) - 1)
            if j < len(steps) - 1:
                missed += not r.converged
                its += r.iterations
        out.append((r, missed, its))
    return out


def _by_path(screw, paths):
    return [screw.step_path(*zip(*steps), DT_S) for steps in paths]


def _same(r, q):
    for name in ("torque_total_nm", "torque_b2g_nm", "torque_b2b_nm", "loss_w",
                 "drive_power_w", "converged", "in_load_range", "iterations", "t_s",
                 "nut_angle_rad"):
        assert getattr(r, name) == getattr(q, name), name
    for name in ("azimuth_rad", "theta_rad", "omega_b_rad_s", "loads_n", "b2b_forces_n",
                 "ball_axial_loads_n"):
        np.testing.assert_array_equal(getattr(r, name), getattr(q, name), err_msg=name)
    assert r.groups == q.groups


@pytest.mark.parametrize("distribution, budget", [("rigid", 0), ("elastic", 0), ("rigid", 2),
                                                  ("elastic", 2)])
def test_step_path_is_step_per_step_bit_for_bit(model, distribution, budget):
    cfg = load_ball_screw(overrides={"load_distribution": distribution,
                                     "solver": {"realtime_max_iterations": budget}})
    paths = _paths()
    ref = _step_by_step(WholeScrew(cfg, model), paths)
    got = _by_path(WholeScrew(cfg, model), paths)
    for (r, missed, its), q in zip(ref, got):
        _same(r, q)
        assert (q.substeps_not_converged, q.substep_iterations) == (missed, its)
        if q.converged and q.nut_velocity_rad_s != 0.0:
            check_step(q)
    assert max(q.n_groups for q in got) >= 2
    if budget:
        assert any(q.substeps_not_converged for q in got)   # the budget cut some sub-steps


def test_step_path_takes_its_warm_steps_in_one_compiled_call(model, config, monkeypatch):
    screw = WholeScrew(config, model)
    paths = _paths(20)
    screw.step_path(*zip(*paths[0]), DT_S)                   # cold start, then warm steps
    calls = []
    real = kernel.warm_steps

    def counted(*args):
        calls.append(len(args[2]) // 3)        # path: angles, velocities, loads
        return real(*args)
    monkeypatch.setattr(kernel, "warm_steps", counted)
    monkeypatch.setattr(kernel, "warm_step", None)           # would raise if called
    monkeypatch.setattr(type(model.solver), "solve", None)
    for steps in paths[1:]:
        assert screw.step_path(*zip(*steps), DT_S).converged
    assert calls == [4] * (len(paths) - 1)


def test_step_path_hands_the_rest_of_a_path_to_step(model, config, monkeypatch):
    """
    A path the compiled call stops in goes on step by step.

    Here it stops after the first step, as after a failed warm solve: the compiled call is
    given that step alone, as the sub-step it is (the sub-step tolerance, its convergence
    counted).
    """
    paths = _paths(25)
    ref = _step_by_step(WholeScrew(config, model), paths)
    real = kernel.warm_steps

    def first_only(state, active, path, aux, *rest):
        k = len(path) // 3
        settings, result = kernel.aux_parts(aux)[:2]
        answered_tol = settings[11]
        settings[11] = settings[12]
        out = real(state, active, path[::k].copy(), aux, *rest)
        settings[11] = answered_tol
        if result[0] == 1 and result[1] == 0.0:
            result[9] += 1
        return out
    monkeypatch.setattr(kernel, "warm_steps", first_only)
    for (r, missed, its), q in zip(ref, _by_path(WholeScrew(config, model), paths)):
        _same(r, q)
        assert (q.substeps_not_converged, q.substep_iterations) == (missed, its)


def test_a_copy_steps_on_its_own_after_a_path(model, config):
    """The look-ahead steps a copy in another thread: the model's next path must not move it."""
    paths = _paths(20)
    screw, twin = WholeScrew(config, model), WholeScrew(config, model)
    for steps in paths[:10]:
        screw.step_path(*zip(*steps), DT_S)
        twin.step_path(*zip(*steps), DT_S)
    ahead = copy.copy(screw)
    for steps in paths[10:]:
        screw.step_path(*zip(*steps), DT_S)
    for steps in paths[10:]:
        _same(ahead.step_path(*zip(*steps), DT_S), twin.step_path(*zip(*steps), DT_S))


def test_step_path_refuses_points_that_do_not_match():
    screw = WholeScrew(load_ball_screw())
    with pytest.raises(ValueError, match="step_path"):
        screw.step_path([0.1, 0.2], [1.0], [1500.0, 1500.0], DT_S)
    with pytest.raises(ValueError, match="step_path"):
        screw.step_path([], [], [], DT_S)


def test_step_path_returns_python_numbers(model, config):
    """Its scalars are floats, as ``step``'s (a numpy scalar prints as np.float64(...))."""
    screw = WholeScrew(config, model)
    for steps in _paths(3):
        r = screw.step_path(*zip(*steps), DT_S)
    for name in ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                 "torque_total_nm", "torque_b2g_nm", "torque_b2b_nm", "drive_power_w",
                 "loss_w", "power_balance_error"):
        assert type(getattr(r, name)) is float, name
    assert type(r.iterations) is int and type(r.converged) is bool


@pytest.mark.parametrize("by_path", [False, True])
def test_each_answer_field_holds_what_its_name_says(model, config, by_path):
    """StepResult is built positionally: each field read back against its own quantity."""
    screw = WholeScrew(config, model)
    for steps in _paths(20):
        if by_path:
            r = screw.step_path(*zip(*steps), DT_S)
        else:
            for j, (a, w, f) in enumerate(steps):
                r = screw.step(a, w, f, DT_S, substep=j < len(steps) - 1)
        if r.n_groups:
            break       # the first answer with a B2B group: every field has a value to show
    a, w, f = steps[-1]
    assert (r.t_s, r.nut_angle_rad, r.nut_velocity_rad_s, r.axial_load_n) == (
        screw.time, a, w, f)
    assert r.converged is True and r.in_load_range is True and r.iterations >= 1
    assert r.torque_b2g_nm * w + r.torque_b2b_nm * w == pytest.approx(r.loss_w, rel=1e-12)
    assert r.drive_power_w == w * r.torque_total_nm
    assert r.power_balance_error == abs(r.drive_power_w - r.loss_w) / r.loss_w
    assert r.n_groups >= 1 and r.torque_b2b_nm > 0.0
    assert [len(ids) for ids, _ in r.groups] == [len(forces) + 1 for _, forces in r.groups]
    n = screw.n
    np.testing.assert_array_equal(r.b2b_forces_n, screw._forces)
    np.testing.assert_array_equal(r.omega_b_rad_s, screw.ratio * w)
    assert np.all(np.abs(np.diff(np.sort(r.azimuth_rad))) > 0.0)   # track azimuths
    assert np.all(np.abs(r.theta_rad) < 1.0)                        # contact angle deviations
    assert r.azimuth_rad.shape == r.theta_rad.shape == r.ball_axial_loads_n.shape == (n,)
    assert r.loads_n.shape == (n, 4) and np.all(r.loads_n >= 0.0)
    assert r.ball_axial_loads_n.sum() == pytest.approx(f, rel=1e-6)
    assert 0.0 < r.solve_time_s < 10.0


def test_an_answer_keeps_its_arrays_when_the_model_steps_on(model, config):
    """A path's state lives in the model's buffer, stepped in place: no answer shares it."""
    screw = WholeScrew(config, model)
    paths = _paths(12)
    for steps in paths[:10]:
        r = screw.step_path(*zip(*steps), DT_S)
    kept = {name: np.copy(getattr(r, name)) for name in (
        "azimuth_rad", "theta_rad", "omega_b_rad_s", "loads_n", "b2b_forces_n",
        "ball_axial_loads_n")}
    for steps in paths[10:]:
        screw.step_path(*zip(*steps), DT_S)
    for name, values in kept.items():
        np.testing.assert_array_equal(getattr(r, name), values, err_msg=name)
    assert not np.array_equal(screw._forces, kept["b2b_forces_n"])


def test_the_answer_builder_puts_each_value_in_its_field(model, config):
    """``_result`` passes StepResult's fields by position: each lands under its name."""
    screw = WholeScrew(config, model)
    b = model.ball
    arrays = [np.full(3, float(i)) for i in range(6)]
    groups = [((1, 2), (0.5,))]
    r = screw._result(2.0, 3.0, 5.0, 7.0, 11.0, 0.0, True, 13, *arrays, groups, 0.0)
    torque = 7.0 - 3.0 * b.r_gear
    loss = 5.0 * 2.0 + b.mu * 11.0 * 2.0
    expected = dict(
        t_s=screw.time, nut_angle_rad=screw.nut_angle, nut_velocity_rad_s=2.0, axial_load_n=3.0,
        torque_total_nm=torque, torque_b2g_nm=5.0, torque_b2b_nm=b.mu * 11.0,
        drive_power_w=2.0 * torque, loss_w=loss, converged=True,
        power_balance_error=abs(2.0 * torque - loss) / loss, in_load_range=True,
        iterations=13)
    for name, value in expected.items():
        assert getattr(r, name) == value, name
    for name, value in zip(("azimuth_rad", "theta_rad", "omega_b_rad_s", "loads_n",
                            "ball_axial_loads_n", "b2b_forces_n"), arrays):
        assert getattr(r, name) is value, name
    assert r.groups is groups and r.solve_time_s > 0.0
    assert (r.substeps_not_converged, r.substep_iterations) == (0, 0)


@pytest.mark.parametrize("form", [list, tuple, np.array, lambda c: np.array(c)[:, None], iter])
def test_step_path_reads_its_points_in_any_form(model, config, form):
    """Lists (the runner's), tuples, arrays, nested columns and iterators: the same answers."""
    paths = _paths(8)
    ref = _by_path(WholeScrew(config, model), paths)
    screw = WholeScrew(config, model)
    for steps, r in zip(paths, ref):
        q = screw.step_path(*(form(c) for c in zip(*steps)), DT_S)
        _same(r, q)
    one = WholeScrew(config, model)
    for steps, r in zip(paths, ref):      # a path of one point may be given as numbers
        for j, (a, w, f) in enumerate(steps):
            q = one.step_path(a, w, f, DT_S) if j == len(steps) - 1 else one.step(
                a, w, f, DT_S, substep=True)
        _same(r, q)
