"""
The compiled warm step works in the model's work arrays and hands out arrays of its own.

``kernel.warm_steps``, ``warm_step`` and ``warm_solve`` lay their arrays out in the work
arrays (``kernel.work_arrays``: newton's share, then ``kernel.step_work_size``'s), and newton
returns views of them to these compiled callers: a warm step allocates a few arrays only
(measured at 20 rev/s: 47 a rigid step before, 6 after).  What reaches Python is copied out
of them, and what a step computes does not depend on what the work arrays held before.
"""

import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw

pytestmark = pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")

STEP_RAD = math.radians(1.8)
OMEGA = 2.0 * math.pi * 20.0
LOAD_N = 1500.0
DT_S = STEP_RAD / OMEGA


def _inputs(count, first=0):
    """Per input: four steps of 1.8 deg at 20 rev/s (the last one answered), as the runner."""
    return [[(4 * k + j + 1) * STEP_RAD for j in range(4)] for k in range(first, first + count)]


def _path(screw, angles):
    return screw.step_path(angles, [OMEGA] * len(angles), [LOAD_N] * len(angles), DT_S)


def _screw(model_distribution):
    return WholeScrew(load_ball_screw(overrides={"load_distribution": model_distribution}))


def _allocations():
    from numba.core.runtime import rtsys
    return rtsys.get_allocation_stats().alloc


@pytest.mark.parametrize("distribution, most", [("rigid", 4.0), ("elastic", 9.0)])
def test_a_warm_step_allocates_a_few_arrays(distribution, most):
    """NRT allocations per warm step of ``step_path`` (once 47 rigid, 50 elastic; 2.5, 8.5)."""
    nrt = pytest.importorskip("numba.core.runtime._nrt_python")
    screw = _screw(distribution)
    for angles in _inputs(40):                 # cold start, the groups forming, compiled
        _path(screw, angles)
    was_on = nrt.memsys_stats_enabled()
    nrt.memsys_enable_stats()
    try:
        before = _allocations()
        steps = 0
        for angles in _inputs(20, first=40):
            res = _path(screw, angles)
            steps += len(angles)
        per_step = (_allocations() - before) / steps
    finally:
        if not was_on:
            nrt.memsys_disable_stats()
    assert res.converged and res.iterations > 0
    assert 0.0 < per_step <= most


@pytest.mark.parametrize("distribution", ["rigid", "elastic"])
def test_warm_steps_do_not_read_what_the_work_arrays_held(distribution):
    """The same path from work arrays full of NaN and full of zeros: bit for bit the same."""
    results = []
    for fill in (np.nan, 0.0):
        screw = _screw(distribution)
        screw._work[0][:] = fill
        out = []
        for angles in _inputs(30):
            r = _path(screw, angles)
            out.append((r.torque_total_nm, r.iterations, r.substep_iterations,
                        r.azimuth_rad.copy(), r.loads_n.copy(), r.b2b_forces_n.copy()))
        for k in range(60, 80):           # step by step too (kernel.warm_step / warm_solve)
            r = screw.step(k * 4 * STEP_RAD, OMEGA, LOAD_N, DT_S)
            out.append((r.torque_total_nm, r.iterations, 0, r.azimuth_rad.copy(),
                        r.loads_n.copy(), r.b2b_forces_n.copy()))
        results.append(out)
    assert all(np.isfinite(a[0]) for a in results[0])
    for a, b in zip(*results):
        assert a[:3] == b[:3]
        for u, v in zip(a[3:], b[3:]):
            assert np.array_equal(u, v)


def _arrays(screw, res, by_path):
    """
    What Python keeps of a step: the answer's arrays, and the state ``step`` leaves.

    (``step_path`` leaves its state in its own buffer, which the next path rewrites.)
    """
    out = [res.azimuth_rad, res.theta_rad, res.omega_b_rad_s, res.loads_n, res.b2b_forces_n,
           res.ball_axial_loads_n]
    if not by_path:
        out += [screw._state[0], screw._state[1], screw.azimuth, screw.ratio, screw._forces,
                screw._active, screw._prev[0], screw._prev[1], screw._prev[2]]
    return [a for a in out if isinstance(a, np.ndarray)]


@pytest.mark.parametrize("distribution", ["rigid", "elastic"])
@pytest.mark.parametrize("by_path", [False, True])
def test_what_a_step_hands_out_stays_as_it_was(distribution, by_path, monkeypatch):
    """
    The answer and the state a step leaves do not change with the next step.

    They would if a view of the work arrays reached Python: the next step writes them.
    The compiled calls' arrays do not share memory with the work arrays either.
    """
    screw = _screw(distribution)
    ws, wi = screw._work
    handed = []
    for name in ("warm_step", "warm_solve"):
        real = getattr(kernel, name)

        def spy(*args, _real=real):
            out = _real(*args)
            flat = [a for a in out if isinstance(a, np.ndarray)]
            flat += [a for part in out if isinstance(part, tuple) for a in part
                     if isinstance(a, np.ndarray)]
            handed.extend(flat)
            return out
        monkeypatch.setattr(kernel, name, spy)
    kept = []
    for k, angles in enumerate(_inputs(25)):
        res = _path(screw, angles) if by_path else screw.step(angles[-1], OMEGA, LOAD_N, DT_S)
        for was, now in kept:
            assert np.array_equal(was, now, equal_nan=True)
        if screw._prev is not None:                     # a warm step next
            kept = [(a.copy(), a) for a in _arrays(screw, res, by_path)]
    assert len(kept) >= 6
    if not by_path:
        assert handed                                  # through warm_step or warm_solve
    for a in handed:
        assert not (np.shares_memory(a, ws) or np.shares_memory(a, wi))


def test_work_arrays_hold_the_warm_step_after_newton():
    """work_arrays: newton's share, then the warm step's; a smaller pair is refused."""
    n = 37
    ws, wi = kernel.work_arrays(n)
    nf, ni = kernel.newton_work_size(n)
    sf, si = kernel.step_work_size(n)
    assert (ws.shape[0], wi.shape[0]) == (nf + sf, ni + si)
    assert sf >= 60 * n and si >= 12 * n
    screw = _screw("rigid")
    for angles in _inputs(3):
        _path(screw, angles)
    screw._work = (np.empty(nf), np.empty(ni, dtype=np.int64))    # newton's share only
    with pytest.raises(ValueError, match="work arrays"):
        _path(screw, _inputs(1, first=3)[0])
