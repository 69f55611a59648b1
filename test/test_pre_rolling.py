"""
The pre-rolling term: a Dahl state of the nut travel, the same live and offline, and never a
friction that opposes the motion in what the runner answers.
"""

import math

import numpy as np
import pytest

from bb_friction_ros.empirical_terms import dahl_state, make_term, TermSet
from bb_friction_ros.model_file import NoPhysics
from bb_friction_ros.runner import InputSample, ModelRunner

TRAVEL = 0.003


def _reversal(n=400, rate_hz=1000.0, amplitude_rad=0.3):
    t = np.arange(n) / rate_hz
    phi = amplitude_rad * np.sin(2.0 * np.pi * t)
    w = amplitude_rad * 2.0 * np.pi * np.cos(2.0 * np.pi * t)
    return t, phi, w


def test_dahl_state_is_the_exact_exponential_build_up_after_a_reversal():
    phi = np.concatenate([np.linspace(0.0, 0.1, 50), 0.1 - np.linspace(0.0, 0.02, 200)[1:]])
    t = np.arange(phi.size) * 1e-3
    w = np.sign(np.gradient(phi))
    z = dahl_state(phi, t, TRAVEL, w)
    back = 0.1 - phi[50:]                       # travel since the reversal
    expected = -1.0 + 2.0 * np.exp(-back / TRAVEL)
    assert z[:50] == pytest.approx(1.0)
    assert z[50:] == pytest.approx(expected, abs=1e-12)
    # half the way from +1 to -1 after ln 2 travels, at 3 travels within 10 %
    assert np.interp(math.log(2.0) * TRAVEL, back, z[50:]) == pytest.approx(0.0, abs=1e-3)


def test_live_evaluation_equals_the_array_evaluation_bit_for_bit():
    terms = TermSet([make_term("pre_rolling", {"torque_nm": 0.1, "travel_rad": TRAVEL}),
                     make_term("seal_drag", {"torque_nm": 0.05})])
    t, phi, w = _reversal()
    offline = terms.torque_nm(t, phi, w, 1000.0)
    live = terms.live()
    online = np.array([live.torque_nm(a, a, b, c, 1000.0) for a, b, c in zip(t, phi, w)])
    assert np.array_equal(offline, online)
    live.reset()                                # a reset starts the state again
    assert live.torque_nm(0.0, 0.0, phi[0], w[0], 1000.0) == online[0]


def test_state_restarts_where_the_run_restarts():
    t, phi, w = _reversal()
    z = dahl_state(np.concatenate([phi, phi]), np.concatenate([t, t]), TRAVEL,
                   np.concatenate([w, w]))
    assert np.array_equal(z[:t.size], z[t.size:])


def test_answered_friction_never_opposes_the_motion_and_builds_up_from_zero():
    """Dahl on the whole drag: right after a reversal the state's friction has the old sign."""
    terms = TermSet([make_term("seal_drag", {"torque_nm": 0.05}),
                     make_term("pre_rolling", {"torque_nm": 0.05, "travel_rad": TRAVEL})])
    runner = ModelRunner(NoPhysics(), 100.0, terms)
    t, phi, w = _reversal()
    preds = [runner.process(InputSample(a, b, c, 1000.0)) for a, b, c in zip(t, phi, w)]
    assert runner.stats.friction_cut > 0
    assert not [p for p in preds if p.torque_total_nm * p.nut_velocity_rad_s < 0.0]
    assert not [p for p in preds if p.feedforward_nm * p.nut_velocity_rad_s < 0.0]
    k = int(np.argmax(w < 0))                   # the first sample moving back
    after = np.array([abs(p.torque_total_nm) for p in preds[k:k + 100]])
    assert after[0] == 0.0 and after[-1] == pytest.approx(0.05, rel=0.05)
    assert np.all(np.diff(after) >= -1e-12)     # builds up, never overshoots the drag
    assert all(p.torque_total_nm == pytest.approx(p.torque_b2g_nm + p.torque_b2b_nm
                                                  + p.torque_empirical_nm) for p in preds)


def test_inertia_is_not_friction_and_is_not_cut():
    """The torque that decelerates the axis may oppose the motion; only friction is cut."""
    terms = TermSet([make_term("inertia", {"j_kg_m2": 0.01, "accel_cutoff_hz": 50.0,
                                           "max_gap_s": 0.05})])
    runner = ModelRunner(NoPhysics(), 100.0, terms)
    t, phi, w = _reversal()
    preds = [runner.process(InputSample(a, b, c, 1000.0)) for a, b, c in zip(t, phi, w)]
    assert runner.stats.friction_cut == 0
    assert any(p.torque_total_nm * p.nut_velocity_rad_s < 0.0 for p in preds)
