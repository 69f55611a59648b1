"""
Look-ahead feedforward: the profile (runner), the controller-side interpolator, and the safe
feedforward policy when a step does not converge.
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
    # every due step before its answer, so a stepped prediction is the step's own state (the
    # answer-first rule: test_runner.py, test_node_servo.py)
    return build_runner(bundled_config("ball_screw.yaml"), 100.0,
                        step_after_answer_fraction=0.0)


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
    ff = FeedforwardInterpolator(scale_with_load=True, max_axial_load_n=10200.0)
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True)
    assert ff.torque_at(0.05, 5.0, 1500.0) == pytest.approx(3.0, rel=1e-15)
    assert ff.torque_at(0.05, 5.0, -1500.0) == pytest.approx(2.0, rel=1e-15)  # other flank


# --- hostile numbers ----------------------------------------------------------------------

NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("angles,torques,omega,load,what", [
    ([0.0, NAN, 0.2], [1.0, 1.0, 1.0], 5.0, 1000.0, "nut_angle_rad[1]"),   # passes "<= 0"
    ([NAN, 0.1], [1.0, 1.0], 5.0, 1000.0, "nut_angle_rad[0]"),
    ([0.0, INF], [1.0, 1.0], 5.0, 1000.0, "nut_angle_rad[1]"),
    ([0.0, 0.1], [1.0, NAN], 5.0, 1000.0, "torque_total_nm[1]"),
    ([0.0, 0.1], [-INF, 1.0], 5.0, 1000.0, "torque_total_nm[0]"),
    ([0.0, 0.1], [1.0, 1.0], NAN, 1000.0, "nut_velocity_rad_s"),
    ([0.0, 0.1], [1.0, 1.0], 5.0, INF, "axial_load_n"),
    ([NAN], [0.0], 0.0, 1000.0, "nut_angle_rad[0]"),
])
def test_non_finite_profile_is_refused_and_the_old_one_kept(angles, torques, omega, load, what):
    ff = FeedforwardInterpolator()
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True)
    with pytest.raises(ValueError, match=r"profile: " + what.replace("[", r"\[")):
        ff.set_profile(angles, torques, omega, load, True)
    assert ff.torque_at(0.05, 5.0) == pytest.approx(2.0)    # the previous profile


@pytest.mark.parametrize("angle,omega,load", [
    (NAN, 5.0, 1000.0), (INF, 5.0, 1000.0), (0.05, NAN, 1000.0), (0.05, -INF, 1000.0),
    (0.05, 5.0, INF), (0.05, 5.0, NAN), (NAN, None, None),
])
def test_non_finite_measurement_gives_zero_with_its_own_status(angle, omega, load):
    ff = FeedforwardInterpolator(scale_with_load=True, max_axial_load_n=10200.0)
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True)
    torque = ff.torque_at(angle, omega, load)
    assert torque == 0.0 and ff.status == "invalid_input"
    assert ff.torque_at(0.05, 5.0, 1000.0) == pytest.approx(2.0) and ff.status == "inside"


def test_load_scale_is_bounded_by_the_model_load_range():
    """1e5 N on a 1500 N profile scales by 10200/1500 = 6.8, not 66.7; counted."""
    ff = FeedforwardInterpolator(scale_with_load=True, max_axial_load_n=10200.0)
    ff.set_profile([0.0, 0.1], [1.0, 1.0], 5.0, 1500.0, True)
    assert ff.torque_at(0.05, 5.0, 1.0e5) == pytest.approx(10200.0 / 1500.0, rel=1e-15)
    assert ff.torque_at(0.05, 5.0, 1.0e300) == pytest.approx(6.8, rel=1e-15)
    assert ff.load_capped == 2
    assert ff.torque_at(0.05, 5.0, 3000.0) == pytest.approx(2.0, rel=1e-15)   # in range
    assert ff.load_capped == 2
    with pytest.raises(ValueError, match="max_axial_load_n"):
        FeedforwardInterpolator(scale_with_load=True)
    with pytest.raises(ValueError, match="max_axial_load_n"):
        FeedforwardInterpolator(scale_with_load=True, max_axial_load_n=NAN)


def test_the_load_range_of_the_paper_screw_bounds_the_scale(runner):
    """The bound a node user passes: the whole-screw model's own range (10.2 kN, Table 4)."""
    w_max = runner.screw.max_axial_load_n
    assert 9.0e3 < w_max < 11.0e3
    ff = FeedforwardInterpolator(scale_with_load=True, max_axial_load_n=w_max)
    ff.set_profile([0.0, 0.1], [0.2, 0.2], 5.0, W_LOAD_N, True)
    assert ff.torque_at(0.05, 5.0, 1.0e5) == pytest.approx(0.2 * w_max / W_LOAD_N, rel=1e-12)


def test_stale_profile_expires():
    """With max_profile_age_s, a profile older (or further ahead) than that gives 0 N m."""
    ff = FeedforwardInterpolator(max_profile_age_s=0.05)
    assert ff.torque_at(0.05, 5.0, now_s=100.0) == 0.0 and ff.status == "empty"
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True, stamp_s=100.0)
    assert ff.torque_at(0.05, 5.0, now_s=100.04) == pytest.approx(2.0)
    assert ff.status == "inside"
    assert ff.torque_at(0.05, 5.0, now_s=100.06) == 0.0 and ff.status == "stale"
    assert ff.torque_at(0.05, 5.0, now_s=1.0e4) == 0.0 and ff.status == "stale"
    assert ff.torque_at(0.05, 5.0, now_s=99.9) == 0.0 and ff.status == "stale"
    ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True, stamp_s=100.06)
    assert ff.torque_at(0.05, 5.0, now_s=100.06) == pytest.approx(2.0)
    # the clock is required, and so is a stamp on each profile
    with pytest.raises(ValueError, match="now_s"):
        ff.torque_at(0.05, 5.0)
    with pytest.raises(ValueError, match="stamp_s"):
        ff.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True)
    # without max_profile_age_s, nothing expires (the documented default)
    plain = FeedforwardInterpolator()
    plain.set_profile([0.0, 0.1], [1.0, 3.0], 5.0, 1000.0, True, stamp_s=100.0)
    assert plain.torque_at(0.05, 5.0, now_s=1.0e6) == pytest.approx(2.0)


def test_interpolator_takes_the_message(ros_context):
    from bb_friction_msgs.msg import FeedforwardProfile
    msg = FeedforwardProfile(nut_angle_rad=[0.0, 0.1], torque_total_nm=[1.0, 2.0],
                             nut_velocity_rad_s=5.0, axial_load_n=1000.0, converged=True)
    msg.header.stamp.sec = 7
    ff = FeedforwardInterpolator()
    assert ff.set_profile_msg(msg) and ff.stamp_s == 7.0
    assert ff.torque_at(0.05, 5.0) == pytest.approx(1.5)


# --- safe feedforward when a step does not converge -------------------------------------

class ScriptedScrew:
    """Steps return scripted (torque, converged); the runner's policy is under test."""

    def __init__(self, script):
        self.script = list(script)

    def __copy__(self):
        return ScriptedScrew(self.script)     # look-ahead copies must not eat our script

    def reset(self, nut_angle_rad):
        pass

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        torque, ok = self.script.pop(0)
        return SimpleNamespace(torque_total_nm=torque, torque_b2g_nm=torque, torque_b2b_nm=0.0,
                               converged=ok, groups=[], azimuth_rad=[0.0])


def test_nonconverged_steps_never_reach_the_feedforward():
    """Prediction keeps the raw unconverged number, flagged; feedforward holds or is 0."""
    # a step every 10 ms (the time floor; model_step_deg out of the way): the policy is tested
    runner = ModelRunner(ScriptedScrew([(0.21, True), (-58.0, False), (8.0, False),
                                        (-0.2, False), (0.0, True), (-0.22, True)]), 100.0,
                         model_step_deg=90.0, step_after_answer_fraction=0.0)
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
