"""
Look-ahead feedforward: the profile (runner), the controller-side interpolator, and the safe
feedforward policy when a step does not converge (issue #11; issue #13 finding 2).
"""

import math
from types import SimpleNamespace

import pytest

from bb_friction_ros.config import bundled_config
from bb_friction_ros.feedforward import FeedforwardInterpolator
from bb_friction_ros.runner import build_runner, InputSample, look_ahead_profile, ModelRunner

W_LOAD_N = 1500.0


@pytest.fixture(scope="module")
def runner():
    return build_runner(bundled_config("ball_screw.yaml"), 100.0)


def _ramp(omega, n, rate_hz=1000.0, t0=50.0, angle0=0.0):
    return [InputSample(t0 + k / rate_hz, angle0 + omega * k / rate_hz, omega, W_LOAD_N)
            for k in range(n)]


# --- the profile ------------------------------------------------------------------------

@pytest.mark.parametrize("omega", [2 * math.pi, -2 * math.pi * 5])
def test_profile_starts_at_the_prediction_and_is_monotonic(runner, omega):
    """First point = the step's angle and torque; angles strictly monotonic ahead."""
    runner.reset()
    profiles = []
    for s in _ramp(omega, 60):
        pred = runner.process(s)
        if pred.stepped:
            prof = look_ahead_profile(runner.profile_seed(s), 2.0, 4)
            profiles.append((pred, prof))
    # 60 ms of 1 kHz input: a step every model_step_deg of rotation, at least every 10 ms
    every = min(10, round(runner.step_rad / (abs(omega) / 1000.0)))
    assert len(profiles) == len(range(0, 60, every))
    for pred, (angles, torques, converged) in profiles:
        assert converged and pred.converged
        assert angles[0] == pred.nut_angle_rad
        assert torques[0] == pred.torque_total_nm    # exactly the prediction at that angle
        steps = [(b - a) * math.copysign(1.0, omega) for a, b in zip(angles, angles[1:])]
        assert all(d > 0 for d in steps)
        # covers two model periods of motion at the current velocity
        assert abs(angles[-1] - angles[0]) == pytest.approx(2 * 0.01 * abs(omega), rel=1e-12)
        # friction opposes the motion all along the profile
        assert all(t * omega > 0 for t in torques)


def test_profile_at_standstill_is_one_point(runner):
    runner.reset()
    s = InputSample(10.0, 1.0, 0.0, W_LOAD_N)
    pred = runner.process(s)
    angles, torques, converged = look_ahead_profile(runner.profile_seed(s), 2.0, 5)
    assert angles == [1.0] and torques == [pred.torque_total_nm] == [0.0] and converged


def test_profile_leaves_the_model_untouched(runner):
    """Stepping the copy ahead never changes what the runner answers (live = replay)."""
    samples = _ramp(2 * math.pi * 5, 80)
    runner.reset()
    plain = [runner.process(s) for s in samples]
    runner.reset()
    with_profiles = []
    for s in samples:
        p = runner.process(s)
        if p.stepped:
            look_ahead_profile(runner.profile_seed(s), 3.0, 5)
        with_profiles.append(p)
    assert [p.torque_total_nm for p in with_profiles] == [p.torque_total_nm for p in plain]
    assert [p.groups for p in with_profiles] == [p.groups for p in plain]


def test_reversal_gives_a_new_direction_profile_at_once(runner):
    """At a reversal the runner steps at once; the new profile runs the other way."""
    runner.reset()
    fwd = _ramp(2 * math.pi, 25)
    back = [InputSample(fwd[-1].stamp_s + (k + 1) / 1000.0,
                        fwd[-1].nut_angle_rad - 2 * math.pi * (k + 1) / 1000.0,
                        -2 * math.pi, W_LOAD_N) for k in range(5)]
    seeds = []
    for s in fwd + back:
        if runner.process(s).stepped:
            seeds.append(runner.profile_seed(s))
    old = look_ahead_profile(seeds[-2], 2.0, 3)
    new = look_ahead_profile(seeds[-1], 2.0, 3)
    assert seeds[-1].sample is back[0]           # the first reversed sample stepped
    assert new[0][1] < new[0][0] and all(t < 0 for t in new[1])
    assert old[0][1] > old[0][0] and all(t > 0 for t in old[1])
    # a controller still holding the old profile gives no old-direction friction
    ff = FeedforwardInterpolator()
    ff.set_profile(old[0], old[1], 2 * math.pi, W_LOAD_N, True)
    assert ff.torque_at(back[0].nut_angle_rad, -2 * math.pi) == 0.0
    assert ff.status == "reversed"
    ff.set_profile(new[0], new[1], -2 * math.pi, W_LOAD_N, True)
    assert ff.torque_at(back[0].nut_angle_rad, -2 * math.pi) == new[1][0] < 0


# --- the interpolator -------------------------------------------------------------------

def test_interpolator_inside_beyond_and_empty():
    ff = FeedforwardInterpolator()
    assert ff.torque_at(0.3, 1.0) == 0.0 and ff.status == "empty"
    assert ff.set_profile([0.0, 0.1, 0.3], [1.0, 2.0, 0.0], 5.0, 1000.0, True)
    assert ff.torque_at(0.05, 5.0) == pytest.approx(1.5, rel=1e-15)
    assert ff.torque_at(0.2, 5.0) == pytest.approx(1.0, rel=1e-15)
    assert ff.torque_at(0.1, 5.0) == 2.0 and ff.status == "inside"
    assert ff.torque_at(0.5, 5.0) == 0.0 and ff.status == "beyond"
    # slightly behind the start while still moving forward (latency, noise): first point
    assert ff.torque_at(-0.01, 5.0) == 1.0 and ff.status == "inside"


def test_interpolator_negative_direction():
    ff = FeedforwardInterpolator()
    ff.set_profile([1.0, 0.8, 0.6], [-1.0, -3.0, -2.0], -4.0, 1000.0, True)
    assert ff.torque_at(0.9, -4.0) == pytest.approx(-2.0, rel=1e-15)
    assert ff.torque_at(0.7, -4.0) == pytest.approx(-2.5, rel=1e-15)
    assert ff.torque_at(0.2, -4.0) == -2.0 and ff.status == "beyond"
    assert ff.torque_at(0.9, 4.0) == 0.0 and ff.status == "reversed"


def test_interpolator_reversal_without_velocity_uses_the_tolerance():
    ff = FeedforwardInterpolator(reversal_tolerance_rad=0.02)
    ff.set_profile([0.0, 0.1], [1.0, 1.0], 5.0, 1000.0, True)
    assert ff.torque_at(-0.01) == 1.0
    assert ff.torque_at(-0.03) == 0.0 and ff.status == "reversed"


def test_interpolator_standstill():
    ff = FeedforwardInterpolator()
    ff.set_profile([0.5], [0.0], 0.0, 1000.0, True)
    assert ff.torque_at(0.7, 1.0) == 0.0 and ff.status == "standstill"
    ff.set_profile([0.0, 0.1], [1.0, 1.0], 5.0, 1000.0, True)
    assert ff.torque_at(0.05, 0.0) == 0.0 and ff.status == "standstill"


def test_interpolator_ignores_nonconverged_profiles():
    ff = FeedforwardInterpolator()
    ff.set_profile([0.0, 0.1], [1.0, 1.0], 5.0, 1000.0, True)
    assert not ff.set_profile([0.0, 0.1], [-60.0, 8.0], 5.0, 1000.0, False)
    assert ff.torque_at(0.05, 5.0) == 1.0 and ff.ignored_nonconverged == 1


@pytest.mark.parametrize("angles,torques,omega", [
    ([0.0, 0.0], [1.0, 1.0], 5.0),           # not strictly monotonic
    ([0.1, 0.0], [1.0, 1.0], 5.0),           # backwards for the direction of motion
    ([0.0, 0.1], [1.0], 5.0),                # lengths differ
    ([], [], 5.0),
    ([0.0, 0.1], [1.0, 1.0], 0.0),           # standstill has one point
])
def test_interpolator_refuses_malformed_profiles(angles, torques, omega):
    with pytest.raises(ValueError, match="profile"):
        FeedforwardInterpolator().set_profile(angles, torques, omega, 1000.0, True)


def test_interpolator_load_scaling():
    ff = FeedforwardInterpolator(scale_with_load=True)
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True)
    assert ff.torque_at(0.05, 5.0, 1500.0) == pytest.approx(3.0, rel=1e-15)
    assert ff.torque_at(0.05, 5.0, -1500.0) == pytest.approx(2.0, rel=1e-15)  # other flank


def test_interpolator_takes_the_message(ros_context):
    from bb_friction_msgs.msg import FeedforwardProfile
    msg = FeedforwardProfile(nut_angle_rad=[0.0, 0.1], torque_total_nm=[1.0, 2.0],
                             nut_velocity_rad_s=5.0, axial_load_n=1000.0, converged=True)
    msg.header.stamp.sec = 7
    ff = FeedforwardInterpolator()
    assert ff.set_profile_msg(msg) and ff.stamp_s == 7.0
    assert ff.torque_at(0.05, 5.0) == pytest.approx(1.5)


# --- safe feedforward when a step does not converge (issue #13, finding 2) ---------------

class ScriptedScrew:
    """Steps return scripted (torque, converged); the runner's policy is under test."""

    def __init__(self, script):
        self.script = list(script)

    def __copy__(self):
        return ScriptedScrew(self.script)     # look-ahead copies must not eat our script

    def reset(self, nut_angle_rad):
        pass

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s):
        torque, ok = self.script.pop(0)
        return SimpleNamespace(torque_total_nm=torque, torque_b2g_nm=torque, torque_b2b_nm=0.0,
                               converged=ok, groups=[], azimuth_rad=[0.0])


def test_nonconverged_steps_never_reach_the_feedforward():
    """Prediction keeps the raw unconverged number, flagged; feedforward holds or is 0."""
    runner = ModelRunner(ScriptedScrew([(0.21, True), (-58.0, False), (8.0, False),
                                        (-0.2, False), (0.0, True), (-0.22, True)]), 100.0)
    w = 6.0
    preds = [runner.process(InputSample(t, w * t, w, 20000.0))
             for t in (0.0, 0.01, 0.015, 0.02)]
    assert [p.converged for p in preds] == [True, False, False, False]
    assert preds[1].torque_total_nm == -58.0 and preds[3].torque_total_nm == 8.0
    assert [p.feedforward_nm for p in preds] == [0.21] * 4
    assert [p.feedforward_held for p in preds] == [False, True, True, True]
    # reversal: a held value of the old direction would push the wrong way -> 0
    back = runner.process(InputSample(0.03, 0.1, -w, 20000.0))
    assert back.stepped and not back.converged and back.feedforward_nm == 0.0
    # standstill (converged, zero torque) and then a converged step in the new direction
    still = runner.process(InputSample(0.04, 0.1, 0.0, 20000.0))
    assert still.converged and still.feedforward_nm == 0.0 and not still.feedforward_held
    again = runner.process(InputSample(0.05, 0.05, -w, 20000.0))
    assert again.converged and again.feedforward_nm == -0.22
    assert runner.stats.nonconverged_steps == 3
