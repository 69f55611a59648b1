"""
The feedforward modes and their sign gate, the baselines' fits, the metrics a servo
engineer reads, and the references generated.
"""

import math

import numpy as np
import pytest

from bb_friction_ros.servo import baselines, metrics
from bb_friction_ros.servo.modes import CoulombViscousMode, Mode
from bb_friction_ros.servo.reference import generate, ReferenceSpec
from bb_friction_ros.servo.run import AxisRun


class Fixed(Mode):
    """A feedforward that always answers +0.1 N m (wrong after a reversal)."""

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        return 0.1


def test_safety_gate_zeroes_and_counts_wrong_signs():
    m = Fixed("model")
    assert m.value(0, 0, 1.0, 0, 1.0, 0, 1.0) == 0.1
    assert m.value(0, 0, -1.0, 0, 1.0, 0, -1.0) == 0.0      # against its own motion
    assert m.value(0, 0, 0.0, 0, 1.0, 0, 0.0) == 0.0        # at its own standstill
    assert m.wrong_sign == 2
    c = Fixed("model_commanded")        # answers the reference's motion
    assert c.value(0, 0, -1.0, 0, 1.0, 0, -1.0) == 0.1
    assert c.wrong_sign == 0 and c.against_motion == 1      # leads the plant's reversal


def _calibration(c, tc, j=2e-4, n=4000):
    t = np.arange(n) * 1e-3
    w = 10.0 * np.sin(2 * math.pi * t)
    a = np.gradient(w, t)
    u = j * a + c * w + tc * np.sign(w) + 0.01
    return baselines.Calibration(t, np.cumsum(w) * 1e-3, w, a, u, "test")


def test_coulomb_viscous_fit_recovers_a_rigid_body_drive():
    fit = baselines.CoulombViscous.fit(_calibration(3e-3, 0.2), 2e-4)
    assert fit.c_nm_s_per_rad == pytest.approx(3e-3, rel=1e-6)
    assert fit.coulomb_nm == pytest.approx(0.2, rel=1e-6)
    assert fit.offset_nm == pytest.approx(0.01, rel=1e-6)
    mode = CoulombViscousMode("coulomb_viscous", fit)
    assert mode.raw(0, 0, 0.0, 0) == 0.0                  # nothing at standstill


def test_lugre_says_when_it_cannot_see_pre_sliding():
    """A sign-switch drive (no pre-sliding): the bristle stiffness is not identifiable."""
    fit = baselines.fit_lugre(_calibration(3e-3, 0.2), 2e-4)
    assert fit.steady(10.0) == pytest.approx(0.2 + 3e-3 * 10.0, rel=1e-3)
    assert not fit.identified and "not identifiable" in fit.note


def _run(t, ref, angle):
    z = np.zeros_like(t)
    return AxisRun(t, ref, angle, z, angle, z, z, z, z, {})


def test_metrics_of_a_known_error():
    t = np.arange(0.0, 2.0, 1e-3)
    ref = np.where(t < 1.0, 10.0 * t, 20.0 - 10.0 * t)      # one reversal at 1 s
    err = 1e-4 * np.sin(2 * math.pi * 50 * t)
    m = metrics.axis_metrics(t, ref, ref - err, 0.02)
    um = 1e-4 * 0.02 / (2 * math.pi) * 1e6
    assert m["following_error_max_um"] == pytest.approx(um, rel=1e-3)
    assert m["following_error_rms_um"] == pytest.approx(um / math.sqrt(2), rel=1e-2)
    assert len(m["reversal_glitch_um"]) == 1
    assert m["cruise_rms_um"] == pytest.approx(um / math.sqrt(2), rel=2e-2)


def test_circle_reference_and_ballbar_figures():
    spec = ReferenceSpec(kind="circle", radius_mm=10.0, feed_m_min=2.0, directions="ccw")
    ref = generate(spec, [1.0], 1000.0, [0.02], "test")
    t = ref.t_s
    x = ref.axes[0].ref_rad * 0.02 / (2 * math.pi)
    y = ref.axes[1].ref_rad * 0.02 / (2 * math.pi)
    assert np.allclose(np.hypot(x, y), 0.01, rtol=0, atol=1e-12)
    feed = metrics.feed_mask(t, x, y)
    v = np.hypot(np.gradient(x, t), np.gradient(y, t))[feed]
    assert v == pytest.approx(2.0 / 60.0, rel=1e-3)
    # a path 1 um outside on X only: the radial deviation follows cos^2 of the angle
    scale = 1.0 + 1e-4
    runs = [_run(t, ref.axes[0].ref_rad, ref.axes[0].ref_rad * scale),
            _run(t, ref.axes[1].ref_rad, ref.axes[1].ref_rad)]
    c = metrics.circle_metrics(t, runs, 0.01, (0.02, 0.02))
    assert c["radial_deviation_range_um"] == pytest.approx(1.0, rel=1e-2)
    assert {s["axis"] for s in c["quadrant_spikes"]} == {"x", "y"}
    perfect = [_run(t, a.ref_rad, a.ref_rad) for a in ref.axes]
    assert metrics.circle_metrics(t, perfect, 0.01, (0.02, 0.02))[
        "radial_deviation_range_um"] < 1e-6


def test_reversal_moves_reach_their_speed_and_stroke():
    spec = ReferenceSpec(kind="reversal", stroke_rev=2.0, accel_rev_s2=20.0)
    ref = generate(spec, [0.5, 2.0], 1000.0, [0.02], "test")
    phi = ref.axes[0].ref_rad
    w = ref.axes[0].ref_velocity(ref.t_s)
    assert np.max(w) == pytest.approx(2 * math.pi * 2.0, rel=1e-3)
    assert np.max(phi) - np.min(phi) == pytest.approx(2 * math.pi * 2.0, rel=1e-6)
    assert len(metrics.reversal_indices(w)) == 3     # forward-back, twice


def test_truth_of_a_presliding_plant_builds_up_after_a_reversal():
    """The truth carries the plant's Dahl state: after a reversal it is gated, then builds."""
    from bb_friction_ros.servo.modes import TruthMode
    from bb_friction_ros.servo.plant import RigidBodyFriction
    truth = TruthMode("truth", RigidBodyFriction(0.0, 0.2, 0.0), presliding_rad=1e-3)
    for k in range(20):                       # forward: s -> 1
        truth.value(0, k * 1e-3, 1.0, 0, 1.0, 0, 1.0)
    back = [truth.value(0, 19e-3 - k * 1e-4, -1.0, 0, -1.0, 0, -1.0) for k in range(1, 80)]
    assert back[0] == 0.0 and truth.wrong_sign > 0      # the old sign is never fed forward
    assert back[-1] == pytest.approx(-0.2, rel=1e-3)     # 7.9 travels later: fully built
    assert all(b >= a for a, b in zip(back[5:], back[4:-1]))   # monotonic build-up


def test_planned_mode_plays_the_planned_feedforward_back_gated_by_the_plan():
    """A breakaway row before a planned start passes the gate; friction against the plan not."""
    import numpy as np
    from bb_friction_ros.servo.modes import PlannedMode
    t = np.arange(6) * 1e-3
    w = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    ff = np.array([0.0, 0.0, 0.2, 0.21, -0.1, 0.3])
    breakaway = np.array([False, False, True, False, False, False])
    m = PlannedMode("planned", t, ff, w, breakaway)
    got = [m.value(t[k], 0.0, 0.0, 0.0, w[k], 1000.0, 0.0) for k in range(6)]
    assert got == [0.0, 0.0, 0.2, 0.21, 0.0, 0.0]
    assert m.wrong_sign == 2 and m.timing == "commanded"


def test_without_the_safety_gate_a_wrong_sign_passes_and_is_still_counted():
    """The study switch: the gate's decision is counted either way; only the gate zeroes."""
    from bb_friction_ros.servo.modes import Mode
    gated, study = Mode("x"), Mode("x")
    study.gate = False
    assert gated._gated(-0.1, 1.0, 1.0) == 0.0
    assert study._gated(-0.1, 1.0, 1.0) == -0.1
    assert gated.wrong_sign == study.wrong_sign == 1
    assert study._gated(0.1, 1.0, 1.0) == 0.1 and study.wrong_sign == 1


def test_a_stop_whose_rounding_has_the_other_sign_is_not_a_reversal():
    """Central differences of a constant angle are rounding of either sign, not motion."""
    from bb_friction_ros.servo.metrics import reversal_indices
    v = np.concatenate([np.full(50, 2.0), np.full(20, -6.6e-14), np.full(50, -2.0),
                        np.full(10, 2.2e-14)])
    assert list(reversal_indices(v)) == [70]
