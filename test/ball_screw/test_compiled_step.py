"""
The compiled warm step (``kernel.warm_solve``) is its Python reference, bit for bit.

``WholeScrew._warm_solve_numpy`` is the readable reference: guesses, active-set loop
(``EquilibriumSolver.solve``), Newton per active set.  The compiled call must give exactly
the same numbers (it is compiled without fastmath around the shared Newton kernel), for
rigid and elastic load paths, with and without a real-time iteration budget, across a
reversal and a load change (where the step cold-starts and the secant restarts).
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


def _run(screw, motion):
    return [screw.step(a, w, f, 0.01) for a, w, f in motion]


@pytest.mark.parametrize("distribution, budget", [("rigid", 0), ("elastic", 0), ("rigid", 3),
                                                  ("elastic", 3)])
def test_compiled_warm_step_is_the_reference_bit_for_bit(model, distribution, budget):
    cfg = load_ball_screw(overrides={"load_distribution": distribution,
                                     "solver": {"realtime_max_iterations": budget}})
    fast, ref = WholeScrew(cfg, model), WholeScrew(cfg, model)
    ref._warm_solve = ref._warm_solve_numpy
    motion = _motion(40)
    for r, q in zip(_run(fast, motion), _run(ref, motion)):
        for name in ("torque_total_nm", "torque_b2b_nm", "loss_w", "drive_power_w",
                     "converged", "iterations", "in_load_range"):
            assert getattr(r, name) == getattr(q, name), name
        for name in ("azimuth_rad", "omega_b_rad_s", "loads_n", "b2b_forces_n",
                     "ball_axial_loads_n"):
            assert np.array_equal(getattr(r, name), getattr(q, name)), name
        assert r.groups == q.groups
        if r.converged:
            check_step(r)
    assert max(r.n_groups for r in _run(WholeScrew(cfg, model), motion)) >= 2


def test_compiled_warm_step_is_used_and_does_the_work(model, config, monkeypatch):
    """The default step solves through one compiled call, not the Python active-set loop."""
    screw = WholeScrew(config, model)
    screw.step(STEP_RAD, 2.0 * math.pi, 1500.0, 0.01)         # cold start
    monkeypatch.setattr(type(model.solver), "solve", None)     # would raise if called
    for k in range(2, 6):
        assert screw.step(k * STEP_RAD, 2.0 * math.pi, 1500.0, 0.01).converged
