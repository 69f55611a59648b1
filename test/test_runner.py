"""The model runner shared by node and replay: validation, schedule, resets."""

import math

import pytest

from bb_friction_ros.runner import (axial_load_value, InputAssembler, InputError,
                                    InputSample, joint_state_sample, ModelRunner)


@pytest.mark.parametrize("names,pos,vel,reason", [
    ((), (), (), "empty"),
    (("other",), (1.0,), (1.0,), "wrong_joint"),
    (("nut_joint",), (1.0,), (), "missing_velocity"),
    (("nut_joint",), (math.nan,), (1.0,), "non_finite"),
    (("nut_joint",), (1.0,), (math.inf,), "non_finite"),
])
def test_bad_joint_states_are_rejected_with_a_reason(names, pos, vel, reason):
    with pytest.raises(InputError) as err:
        joint_state_sample(names, pos, vel, "nut_joint")
    assert err.value.reason == reason


def test_joint_picked_by_name():
    assert joint_state_sample(("a", "nut_joint"), (1.0, 2.0), (3.0, 4.0), "nut_joint") == \
        (2.0, 4.0)


@pytest.mark.parametrize("value,reason", [(math.nan, "non_finite"), (2e6, "absurd_load"),
                                          (-2e6, "absurd_load")])
def test_bad_loads_are_rejected(value, reason):
    with pytest.raises(InputError) as err:
        axial_load_value(value, 1e6)
    assert err.value.reason == reason


def test_no_sample_before_a_load():
    asm = InputAssembler("nut_joint", 1e5)
    with pytest.raises(InputError, match="no_load_yet"):
        asm.on_nut_state(0.0, ("nut_joint",), (0.0,), (1.0,))
    asm.on_axial_load(-800.0)     # negative: the other flank, kept
    assert asm.on_nut_state(0.0, ("nut_joint",), (0.0,), (1.0,)).axial_load_n == -800.0


class RecordingScrew:
    """Records the calls it gets; the runner's contract is about when and with what."""

    def __init__(self):
        self.calls = []

    def reset(self, nut_angle_rad):
        self.calls.append(("reset", nut_angle_rad))

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s):
        self.calls.append(("step", nut_angle_rad, dt_s))
        from types import SimpleNamespace
        return SimpleNamespace(torque_total_nm=nut_angle_rad, torque_b2g_nm=nut_angle_rad,
                               torque_b2b_nm=0.0, converged=True, groups=[],
                               azimuth_rad=[0.0, 1.0])


def test_schedule_follows_stamps_and_resets_on_backwards_time():
    screw = RecordingScrew()
    runner = ModelRunner(screw, model_rate_hz=100.0)
    preds = [runner.process(InputSample(t, t, 1.0, 100.0))
             for t in (0.0, 0.002, 0.009, 0.010, 0.015, 0.030)]
    assert [p.stepped for p in preds] == [True, False, False, True, False, True]
    assert preds[2].torque_total_nm == 0.0 and preds[2].model_age_s == pytest.approx(0.009)
    assert preds[2].torque_empirical_nm == 0.0
    assert [c for c in screw.calls if c[0] == "step"][1][2] == pytest.approx(0.010)
    p = runner.process(InputSample(0.001, 5.0, 1.0, 100.0))     # stamps went backwards
    assert runner.stats.resets == 1 and p.stepped and screw.calls[-2] == ("reset", 5.0)
    p = runner.process(InputSample(0.020, 6.0, 1.0, 100.0), allow_step=False)
    assert not p.stepped and runner.stats.skipped_steps == 1


def test_reversal_steps_at_once():
    """A change of direction is a step due now, not at the next period."""
    runner = ModelRunner(RecordingScrew(), model_rate_hz=100.0)
    steps = [runner.process(InputSample(t, t, w, 100.0)).stepped
             for t, w in ((0.0, 1.0), (0.002, 1.0), (0.004, -1.0), (0.006, -1.0),
                          (0.008, 0.0), (0.009, 0.0), (0.018, 0.0))]
    assert steps == [True, False, True, False, True, False, True]


def test_model_rate_holds_at_epoch_stamps():
    """A 100 Hz model on 500 Hz input at epoch-time stamps steps every 5th sample, not 6th."""
    runner = ModelRunner(RecordingScrew(), model_rate_hz=100.0)
    t0 = 1_795_000_000.123456789
    stepped = [runner.process(InputSample(t0 + k / 500.0, 0.0, 1.0, 100.0)).stepped
               for k in range(501)]
    assert sum(stepped) == 101


class FailingScrew(RecordingScrew):
    """Raises on the step at ``bad_angle``: a physics failure the runner must survive."""

    def __init__(self, bad_angle):
        super().__init__()
        self.bad_angle = bad_angle

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s):
        if nut_angle_rad == self.bad_angle:
            raise FloatingPointError("solver blew up")
        return super().step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)


def test_model_error_is_counted_and_resets_in_the_shared_runner():
    """
    A raising step: no prediction, counted ``model_error``, state reset; the next sample goes on.

    The runner does it, so the node and replay (``run_events``) behave the same (issue 14).
    """
    from bb_friction_ros.bags import Event
    from bb_friction_ros.replay import run_events
    events = [Event("axial_load", 0.0, value=100.0)] + [
        Event("nut_state", t, ("nut_joint",), (t,), (1.0,)) for t in (0.0, 0.01, 0.02, 0.03)]
    screw = FailingScrew(bad_angle=0.02)
    runner = ModelRunner(screw, model_rate_hz=100.0)
    preds = run_events(events, runner, InputAssembler("nut_joint", 1e5))
    assert [p.stamp_s for p in preds] == [0.0, 0.01, 0.03]
    assert runner.stats.rejected == {"model_error": 1}
    assert runner.stats.rejected_nut_state == 1
    assert "solver blew up" in runner.stats.last_error
    assert screw.calls[-2] == ("reset", 0.03)      # a new run starts after the failure
    assert preds[-1].stepped and preds[-1].model_age_s == 0.0
