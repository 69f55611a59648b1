"""Whole screw (Sec. 3.4): invariants every step, groups, reversal, zero speed/load."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.simulation import run_whole_screw, summarize
from bb_friction_ros.ball_screw.whole_screw import isotonic_ring_projection, WholeScrew
from invariants import assert_paper, check_step

SHORT = 45    # steps of 3.6 deg: 162 deg of nut rotation, past the first B2B peak


@pytest.fixture(scope="module")
def short_run(config, model):
    screw = WholeScrew(config, model)
    results, _ = run_whole_screw(config, n_steps=SHORT, screw=screw)
    return results, screw


def test_invariants_every_step(short_run):
    """Power balance, sum of parts, signs and finiteness at every step."""
    for r in short_run[0]:
        check_step(r)


def test_fig20_groups_form(short_run):
    results, screw = short_run
    assert_paper(paper.B2B_GROUPS, max(r.n_groups for r in results))
    last = results[-1]
    for ids, forces in last.groups:
        assert len(ids) == len(forces) + 1
        assert all(f > 0.0 for f in forces)
        # Rear-first, consecutive along the loop (omega_N > 0: rear has the lower index).
        assert all((b - a) % screw.n == 1 for a, b in zip(ids[:-1], ids[1:]))
        assert np.ptp(last.omega_b_rad_s[list(ids)]) < 1e-6


def test_fig21_b2b_share_peak(short_run):
    # Ours (3.44 deg amplitude, calibrated): ~47.5 % near 97 deg.  The bands and their
    # reasons are in paper.B2B_PEAK_SHARE / B2B_PEAK_NUT_ANGLE.
    s = summarize(short_run[0], short_run[1].separation)
    assert_paper(paper.B2B_PEAK_SHARE, 100 * s["peak_b2b_share"])
    assert_paper(paper.B2B_PEAK_NUT_ANGLE, s["peak_b2b_nut_angle_deg"])


def test_fig21_peak_share_at_the_calibrated_amplitude(short_run, config):
    # The theta amplitude (not in the paper) is calibrated to this number, 49.6 %, by the
    # bundled sweep (docs/assumptions_ball_screw.md).  Tolerance 3 pt: the calibration
    # resolves the amplitude to ~0.05 deg (1.2 pt), and the peak share scatters by ~1 pt
    # between amplitudes 0.01 deg apart (3.6 deg time steps); rigid and elastic differ by ~3.
    assert math.degrees(config.errors.theta_amplitude_rad) == pytest.approx(3.44)
    s = summarize(short_run[0], short_run[1].separation)
    assert 100 * s["peak_b2b_share"] == pytest.approx(paper.B2B_PEAK_SHARE.value, abs=3.0)


def test_theta_zero_gives_no_b2b(model):
    cfg = load_ball_screw(overrides={"errors": {"theta_amplitude_deg": 0.0}})
    screw = WholeScrew(cfg, model)
    results, _ = run_whole_screw(cfg, n_steps=10, screw=screw)
    assert all(r.converged and r.torque_b2b_nm == 0.0 and r.n_groups == 0 for r in results)
    for r in results:
        check_step(r)


def test_zero_speed_keeps_state(config, model):
    screw = WholeScrew(config, model)
    screw.step(0.1, 2 * math.pi, 1500.0, 0.01)
    az = screw.azimuth.copy()
    r = screw.step(0.1, 0.0, 1500.0, 0.01)
    assert r.converged and r.torque_total_nm == 0.0 and r.loss_w == 0.0
    check_step(r)
    assert np.array_equal(screw.azimuth, az)


def test_reversal_and_load_sign(config, model):
    screw = WholeScrew(config, model)
    fwd = screw.step(0.1, 2 * math.pi, 1500.0, 0.01)
    back = screw.step(0.05, -2 * math.pi, 1500.0, 0.01)
    check_step(fwd)
    check_step(back)
    assert fwd.torque_total_nm > 0.0 > back.torque_total_nm
    neg = screw.step(0.0, -2 * math.pi, -1500.0, 0.01)
    check_step(neg)
    # Mirror of the first step: same |T_f| for (-theta, -W, -omega_N) is not available
    # on the fixed screw, but both directions must dissipate.
    assert neg.loss_w > 0.0


def test_zero_load_zero_friction(config, model):
    screw = WholeScrew(config, model)
    r = screw.step(0.1, 2 * math.pi, 0.0, 0.01)
    check_step(r)
    assert r.torque_total_nm == 0.0


def test_isotonic_ring_projection():
    loop, sep = 10.0, 1.0
    az = np.array([0.0, 0.5, 3.0, 3.2, 9.5])
    out = isotonic_ring_projection(az, sep, loop)
    gaps = np.diff(np.append(out, out[0] + loop))
    assert gaps.min() >= sep - 1e-12
    # Wrapped pair (9.5, 0.0 + 10) overlaps too: the 3-ball block keeps its mean.
    assert out.sum() == pytest.approx(az.sum())


def test_preloaded_screw_starts_at_zero_load():
    """
    A preloaded screw started cold at 0 N converges in a bounded number of solves, to the
    state reached warm by lowering the load to 0 N.

    The cold start's load continuation halved towards a zero target without end (each step
    converges on a preloaded screw): the first step at 0 N never returned (seen in the
    physical search's preload trials).  The solve count bounds it here so that a regression
    fails, not hangs.
    """
    cfg = load_ball_screw(None, {"errors": {"theta_amplitude_deg": 0.0},
                                 "geometry": {"ball_oversize_um": 1.0}})
    w = 2 * math.pi
    warm = WholeScrew(cfg)
    warm.reset(0.0)
    warm.step(0.01, w, 10.0, 0.01)
    warm.step(0.01, w, 1.0, 0.0)
    ref = warm.step(0.01, w, 0.0, 0.0)
    cold = WholeScrew(cfg)
    solver = cold.model.solver
    calls = []
    solve = solver.solve

    def counted(*args, **kwargs):
        calls.append(1)
        if len(calls) > 100:
            raise RuntimeError("the cold start does not end at 0 N")
        return solve(*args, **kwargs)

    solver.solve = counted
    cold.reset(0.0)
    res = cold.step(0.01, w, 0.0, 0.0)
    assert res.converged and ref.converged
    # preload alone: a friction torque at zero axial load, the same either way
    assert res.torque_total_nm > 0.0
    assert res.torque_total_nm == pytest.approx(ref.torque_total_nm, rel=1e-6)


def test_a_substep_is_solved_to_its_own_tolerance_and_an_answered_step_fully(config, model):
    """
    ``step(..., substep=True)`` solves to ``solver.substep_tolerance`` (1e-5), which the
    secant guess's single Newton iteration meets; the step after it, answered, is solved to
    ``solver.tolerance`` and passes every invariant.  Steady 20 rev/s, 1.8 deg steps, every
    fourth answered (1 kHz inputs), from a cold start.  Tolerance of the answered torque:
    0.1 % of the torque; the runner's answers moved by at most 6.7e-5 N m of 0.2 N m
    (0.03 %) over the first 3 s at 20 rev/s (1.3e-4 N m with a sub-step tolerance of 1e-4;
    docs/model_schedule.md, "Sub-steps"), here 40 steps from the cold start.
    """
    assert config.solver.substep_tolerance > config.solver.tolerance
    w, d = 2 * math.pi * 20.0, math.radians(1.8)
    strict, loose = WholeScrew(config, model), WholeScrew(config, model)
    it_strict = it_loose = n_sub = 0
    for k in range(1, 41):
        answered = k % 4 == 0
        a = strict.step(k * d, w, 1500.0, 2.5e-4)
        b = loose.step(k * d, w, 1500.0, 2.5e-4, substep=not answered)
        assert a.converged and b.converged
        if k <= 4:
            continue            # the cold start and the secant's first step
        if answered:
            check_step(b)
            assert b.torque_total_nm == pytest.approx(a.torque_total_nm, rel=1e-3)
        else:
            it_strict += a.iterations
            it_loose += b.iterations
            n_sub += 1
    # about one Newton iteration fewer per sub-step (measured 0.85 here, 52 against 75 over
    # 27, where the first steps after the cold start need more; 1.0 with 1e-4)
    assert it_strict - it_loose >= 0.7 * n_sub
