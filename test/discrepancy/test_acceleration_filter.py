"""
The acceleration filter: zero-phase for the analysis, causal (AccelerationFilter) in the node.

Tested against analytical limits: a constant acceleration is reproduced exactly (first-order
hold is exact for a velocity ramp) once the filter has settled; the causal filter lags a
slow sinusoid by sqrt(2)/(2 pi fc), the zero-phase one not at all; segments are filtered on
their own.
"""

import math

import numpy as np
import pytest

from bb_friction_ros.empirical_terms import (AccelerationFilter, filter_lag_s, LiveTerms,
                                             load_terms, segments, zero_phase_acceleration)


def causal(t, v, fc, gap):
    f = AccelerationFilter(fc, gap)
    return np.array([f.update(a, b) for a, b in zip(t, v)])


def test_constant_acceleration_is_exact_after_settling():
    t = np.arange(0, 2.0, 1e-3)
    v = 3.0 + 40.0 * t
    a = causal(t, v, 10.0, 0.01)
    assert np.allclose(a[t > 0.5], 40.0, rtol=1e-6)
    z = zero_phase_acceleration(t, v, 10.0, 0.01)
    mid = (t > 0.5) & (t < 1.5)
    assert np.allclose(z[mid], 40.0, rtol=1e-6)


def test_causal_lag_and_zero_phase():
    """A slow sine (0.5 Hz << fc 10 Hz): causal lag = sqrt(2)/(2 pi fc), zero-phase none."""
    fc, f0 = 10.0, 0.5
    t = np.arange(0, 6.0, 1e-3)
    v = np.sin(2 * math.pi * f0 * t)
    true = 2 * math.pi * f0 * np.cos(2 * math.pi * f0 * t)
    mid = (t > 2.0) & (t < 4.0)
    z = zero_phase_acceleration(t, v, fc, 0.01)
    assert np.max(np.abs(z[mid] - true[mid])) < 0.01 * np.max(true)
    a = causal(t, v, fc, 0.01)
    lag = filter_lag_s(fc)
    shifted = 2 * math.pi * f0 * np.cos(2 * math.pi * f0 * (t - lag))
    assert np.max(np.abs(a[mid] - shifted[mid])) < 0.01 * np.max(true)
    assert lag == pytest.approx(0.0225, rel=0.01)


def test_segments_split_at_gaps_and_resets():
    t = np.array([0.0, 0.01, 0.02, 0.5, 0.51, 0.52, 0.0, 0.01])
    assert segments(t, 0.05) == [(0, 3), (3, 6), (6, 8)]
    v = np.array([0.0, 1.0, 2.0, 50.0, 50.0, 50.0, 0.0, 0.0])
    z = zero_phase_acceleration(t, v, 5.0, 0.05, min_segment_samples=3)
    assert np.all(np.isfinite(z[:6])) and np.all(np.isnan(z[6:]))   # last segment too short
    assert np.allclose(z[3:6], 0.0)          # the jump to 50 rad/s across the gap is no alpha


def test_live_terms_use_the_causal_filter_and_reset():
    terms = load_terms([{"name": "inertia", "params": {"j_kg_m2": 0.01, "accel_cutoff_hz":
                                                       10.0, "max_gap_s": 0.01}}])
    t = np.arange(0, 1.0, 1e-3)
    v = 20.0 * t
    live = LiveTerms(terms)
    out = np.array([live.torque_nm(a, a, 0.0, b, 1.0) for a, b in zip(t, v)])
    assert np.allclose(out, 0.01 * causal(t, v, 10.0, 0.01))
    live.reset()
    assert live.torque_nm(5.0, 0.0, 0.0, 3.0, 1.0) == 0.0      # a new segment starts at rest


def test_feedforward_and_look_ahead_carry_the_inertia_term(tmp_path):
    """
    The runner's held feedforward and look-ahead profile include J alpha of the same causal
    filter as the prediction (the terms are evaluated once per sample; alpha is held ahead).
    """
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.empirical_terms import make_term, TermSet
    from bb_friction_ros.model_file import read_model_file, write_model_file
    from bb_friction_ros.runner import build_runner, InputSample, look_ahead_profile
    j = 3e-4
    cfg = tmp_path / "aug.yaml"
    inertia = make_term("inertia", {"j_kg_m2": j, "accel_cutoff_hz": 10.0, "max_gap_s": 0.1})
    write_model_file(cfg, read_model_file(bundled_config("ball_screw.yaml"))[0],
                     TermSet([inertia]))
    runner = build_runner(cfg, 100.0, step_after_answer_fraction=0.0)   # steps first
    f = AccelerationFilter(10.0, 0.1)
    seed = None
    for k in range(40):                     # a ramp of 50 rad/s^2 from 1 rad/s, at 1 kHz
        t = k * 1e-3
        w = 1.0 + 50.0 * t
        p = runner.process(InputSample(t, w * t, w, 1500.0))
        alpha = f.update(t, w)
        assert p.torque_empirical_nm == pytest.approx(j * alpha, rel=1e-9, abs=1e-12)
        if p.stepped and p.converged:
            assert p.feedforward_nm == pytest.approx(p.torque_total_nm)
            seed = runner.profile_seed(InputSample(t, w * t, w, 1500.0))
            first = p.torque_total_nm
    assert seed is not None and abs(seed.nut_accel_rad_s2) > 10.0
    angles, torques, _ = look_ahead_profile(seed, 2.0, 3)
    assert torques[0] == pytest.approx(first)            # psi_0: the prediction itself
    assert len(torques) == 3 and all(math.isfinite(x) for x in torques)
