"""
The default model-step schedule converged at servo speeds (its acceptance criterion).

With the defaults, the prediction at every 1 kHz input of steady rotation at 10 and 20 rev/s
is within 0.2 of the B2B torque variation of a fine-step reference at the same nut angles
(bench/bench_convergence.py is the full study; docs/model_schedule.md).  The reference here
steps every 0.36 deg, which differs from a 0.18 deg one by 0.015-0.022 of the B2B variation
(measured by the bench), well inside the margin.  The old 100 Hz time schedule is run too:
it must fail the same bound, or the test could not tell the schedules apart.
"""

import dataclasses
import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import bundled_config
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.runner import InputSample, ModelRunner

REF_DEG = 0.36
REVS, SETTLE_REVS = 6.0, 1.0
LOAD_N = 1500.0
TARGET = 0.2        # required: error <= 0.2 of the B2B variation at 10 and 20 rev/s


def _runner(step_deg, rate_hz=None, after=None, cfg=None):
    cfg = cfg or load_model_file(bundled_config("ball_screw.yaml"))[0]
    p = NodeParameters()
    return ModelRunner(WholeScrew(cfg), rate_hz or p.model_rate_hz, None,
                       model_step_deg=step_deg, max_model_step_deg=max(step_deg, 36.0),
                       step_after_answer_fraction=after)


@pytest.mark.parametrize("rev_s", [10.0, 20.0])
def test_default_schedule_is_within_0_2_of_the_b2b_variation(rev_s):
    w = 2 * math.pi * rev_s
    m = int(round(rev_s * 360.0 / 1000.0 / REF_DEG))        # reference steps per input
    d = math.radians(REF_DEG)
    n_ref = int(round(REVS * 360.0 / REF_DEG)) + 1
    ref_in = [InputSample(5.0 + i / (1000.0 * m), i * d, w, LOAD_N) for i in range(n_ref)]
    inputs = ref_in[::m]
    ref = _runner(REF_DEG, after=0.0)     # every sample answered from its own step
    ref_out = [ref.process(s) for s in ref_in][::m]
    keep = np.array([s.nut_angle_rad >= 2 * math.pi * SETTLE_REVS for s in inputs])
    truth = np.array([p.torque_total_nm for p in ref_out])[keep]
    variation = np.std(np.array([p.torque_b2b_nm for p in ref_out])[keep])
    assert all(p.converged for p in ref_out) and variation > 0

    def share(runner):
        est = np.array([runner.process(s).torque_total_nm for s in inputs])[keep]
        return np.sqrt(np.mean((est - truth) ** 2)) / variation

    assert share(_runner(NodeParameters().model_step_deg)) <= TARGET
    assert share(_runner(1e9, rate_hz=100.0)) > 2 * TARGET       # the old time schedule


@pytest.mark.parametrize("rev_s", [10.0, 20.0])
def test_loose_substeps_move_the_answers_by_little(rev_s):
    """
    The sub-steps between two inputs are solved to ``solver.substep_tolerance`` (1e-5), not
    ``solver.tolerance`` (1e-8).  Against the same schedule with every step solved to 1e-8,
    over 3 s after the first revolution: RMS at most 0.005 of the B2B variation, largest
    0.5.  Measured 0.0000 / 0.0009 RMS and 0.000 / 0.037 largest at 10 / 20 rev/s (with
    1e-4: 0.0027 / 0.0032 and 0.05 / 0.07; with 1e-3, which accepts the unsolved secant
    guess and which this test refuses: 0.15 / 0.18 and 5.0 / 7.0).  A sub-step's state
    error moves a B2B contact's closing by a sub-step now and then (the ring's touching test
    resolves 1e-9 rad), so the largest difference depends on the run: up to 0.71 with RMS
    0.01 in 10 s of another start (docs/model_schedule.md, "Sub-steps"), where the error
    against the fine-step reference stays 0.15 / 0.16 either way.
    """
    cfg, _ = load_model_file(bundled_config("ball_screw.yaml"))
    strict_cfg = dataclasses.replace(cfg, solver=dataclasses.replace(
        cfg.solver, substep_tolerance=cfg.solver.tolerance))
    w = 2 * math.pi * rev_s
    inputs = [InputSample(5.0 + k / 1000.0, w * k / 1000.0, w, LOAD_N) for k in range(3000)]
    keep = np.array([s.nut_angle_rad >= 2 * math.pi * SETTLE_REVS for s in inputs])
    step = NodeParameters().model_step_deg
    r_strict, r_loose = _runner(step, cfg=strict_cfg), _runner(step, cfg=cfg)
    a = [r_strict.process(s) for s in inputs]
    b = [r_loose.process(s) for s in inputs]
    assert r_loose.stats.substeps > 0 and all(p.converged for p in b)
    variation = np.std(np.array([p.torque_b2b_nm for p in a])[keep])
    diff = (np.array([p.torque_total_nm for p in b])
            - np.array([p.torque_total_nm for p in a]))[keep] / variation
    assert np.sqrt(np.mean(diff ** 2)) <= 0.005
    assert np.max(np.abs(diff)) <= 0.5
