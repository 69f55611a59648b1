"""
The compiled warm step (``kernel.warm_solve``) is its Python reference.

``WholeScrew._warm_solve_numpy`` is the readable reference: guesses, active-set loop
(``EquilibriumSolver.solve``), Newton per active set.  The compiled call runs the same
arithmetic (compiled without fastmath around the shared Newton kernel), for rigid and
elastic load paths, with and without a real-time iteration budget, across a reversal and a
load change (where the step cold-starts and the secant restarts).

Tolerance: with the kernels loaded from one numba cache the two agree bit for bit (the demo
replay too).  Freshly compiled code can differ in the last bits (1e-12 relative, measured):
the kernels' FMA contraction depends on what the compiler inlines where, and a function
compiled inside ``warm_solve`` is not the same machine code as the one the reference calls.
So the torques agree to 1e-9 (the Newton tolerance is 1e-10 of the force scale) and the
contact groups exactly.
"""

import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw
from invariants import check_step

pytestmark = pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")

STEP_RAD = math.radians(3.6)


def _motion(steps):
    """(nut angle, velocity, load) per step: forward, reversal, back, load change."""
    angle, out = 0.0, []
    for k in range(steps):
        sign = 1.0 if k < 0.6 * steps else -1.0
        angle += sign * STEP_RAD
        load = 1500.0 if k < 0.8 * steps else 900.0
        out.append((angle, sign * 2.0 * math.pi, load))
    return out


def _run(screw, motion, substep=False):
    return [screw.step(a, w, f, 0.01, substep) for a, w, f in motion]


@pytest.mark.parametrize("distribution, budget", [("rigid", 0), ("elastic", 0), ("rigid", 3),
                                                  ("elastic", 3)])
def test_compiled_warm_step_is_the_reference_bit_for_bit(model, distribution, budget):
    cfg = load_ball_screw(overrides={"load_distribution": distribution,
                                     "solver": {"realtime_max_iterations": budget}})
    fast, ref = WholeScrew(cfg, model), WholeScrew(cfg, model)
    ref._warm_solve = ref._warm_solve_numpy
    motion = _motion(40)
    for r, q in zip(_run(fast, motion), _run(ref, motion)):
        for name in ("torque_total_nm", "torque_b2b_nm", "loss_w", "drive_power_w"):
            assert getattr(r, name) == pytest.approx(getattr(q, name), rel=1e-9, abs=1e-12), \
                name
        assert (r.converged, r.in_load_range) == (q.converged, q.in_load_range)
        for name in ("azimuth_rad", "omega_b_rad_s", "loads_n", "ball_axial_loads_n"):
            np.testing.assert_allclose(getattr(r, name), getattr(q, name), rtol=1e-9,
                                       atol=1e-9, err_msg=name)
        np.testing.assert_allclose(r.b2b_forces_n, q.b2b_forces_n, rtol=0, atol=1e-6)
        assert [g[0] for g in r.groups] == [g[0] for g in q.groups]
        if r.converged:
            check_step(r)
    assert max(r.n_groups for r in _run(WholeScrew(cfg, model), motion)) >= 2


@pytest.mark.parametrize("distribution", ["rigid", "elastic"])
def test_compiled_substep_is_the_reference(model, distribution):
    """Sub-steps (``step(..., substep=True)``) pass the looser tolerance to either path."""
    cfg = load_ball_screw(overrides={"load_distribution": distribution})
    fast, ref = WholeScrew(cfg, model), WholeScrew(cfg, model)
    ref._warm_solve = ref._warm_solve_numpy
    motion = _motion(40)
    for r, q in zip(_run(fast, motion, True), _run(ref, motion, True)):
        assert r.torque_total_nm == pytest.approx(q.torque_total_nm, rel=1e-9, abs=1e-12)
        assert (r.converged, r.iterations) == (q.converged, q.iterations)
        assert [g[0] for g in r.groups] == [g[0] for g in q.groups]


def test_compiled_warm_step_is_used_and_does_the_work(model, config, monkeypatch):
    """The default step solves through one compiled call, not the Python active-set loop."""
    screw = WholeScrew(config, model)
    screw.step(STEP_RAD, 2.0 * math.pi, 1500.0, 0.01)         # cold start
    monkeypatch.setattr(type(model.solver), "solve", None)     # would raise if called
    for k in range(2, 6):
        assert screw.step(k * STEP_RAD, 2.0 * math.pi, 1500.0, 0.01).converged


def test_fused_warm_step_falls_back_to_the_cold_start(model, config, monkeypatch):
    """
    A rigid warm step runs as one call (kernel.warm_step); when it fails from every guess
    the step cold-starts from the same geometry, counts both solves' iterations, and lands
    on the same equilibrium (both converge to the solver's tolerance).
    """
    motion = [(k * STEP_RAD, 2.0 * math.pi, 1500.0) for k in range(1, 12)]
    plain = _run(WholeScrew(config, model), motion)
    calls = []
    real = kernel.warm_step

    def failing(*args):
        out = real(*args)
        calls.append(out[2])
        return (False, False) + out[2:]
    monkeypatch.setattr(kernel, "warm_step", failing)
    failed = _run(WholeScrew(config, model), motion)
    assert len(calls) == len(motion) - 1          # every step after the first cold start
    for r, q, it in zip(failed[1:], plain[1:], calls):
        assert r.converged and q.converged
        assert r.iterations >= it                  # the warm attempt's plus the cold start's
        assert r.torque_total_nm == pytest.approx(q.torque_total_nm, rel=1e-6)
        assert [g[0] for g in r.groups] == [g[0] for g in q.groups]
        np.testing.assert_allclose(r.azimuth_rad, q.azimuth_rad, rtol=0, atol=1e-9)
