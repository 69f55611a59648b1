"""The model runner shared by node and replay: validation, schedule, resets."""

import math

import pytest

from bb_friction_ros.runner import (axial_load_value, InputAssembler, InputError,
                                    InputSample, joint_state_sample, ModelRunner)

# The schedule's tests below read when a step is taken from ``Prediction.stepped``: they run
# with every due step before its answer.  The answer-first rule (the default
# ``step_after_answer_fraction``) has its own tests at the end.
STEP_FIRST = dict(step_after_answer_fraction=0.0)


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

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        self.calls.append(("step", nut_angle_rad, dt_s))
        from types import SimpleNamespace
        return SimpleNamespace(torque_total_nm=nut_angle_rad, torque_b2g_nm=nut_angle_rad,
                               torque_b2b_nm=0.0, converged=True, groups=[],
                               azimuth_rad=[0.0, 1.0])


def test_schedule_follows_stamps_and_resets_on_backwards_time():
    screw = RecordingScrew()
    runner = ModelRunner(screw, model_rate_hz=100.0, **STEP_FIRST)
    preds = [runner.process(InputSample(t, t, 1.0, 100.0))
             for t in (0.0, 0.002, 0.009, 0.010, 0.015, 0.030)]
    assert [p.stepped for p in preds] == [True, False, False, True, False, True]
    assert preds[2].torque_total_nm == 0.0 and preds[2].model_age_s == pytest.approx(0.009)
    assert preds[2].torque_empirical_nm == 0.0
    assert [c for c in screw.calls if c[0] == "step"][1][2] == pytest.approx(0.010)
    p = runner.process(InputSample(-0.5, 5.0, 1.0, 100.0))   # back by more than a late stamp
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
    runner = ModelRunner(RecordingScrew(), model_rate_hz=100.0, **STEP_FIRST)
    t0 = 1_795_000_000.123456789
    stepped = [runner.process(InputSample(t0 + k / 500.0, 0.0, 1.0, 100.0)).stepped
               for k in range(501)]
    assert sum(stepped) == 101


class FailingScrew(RecordingScrew):
    """Raises on the step at ``bad_angle``: a physics failure the runner must survive."""

    def __init__(self, bad_angle):
        super().__init__()
        self.bad_angle = bad_angle

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        if nut_angle_rad == self.bad_angle:
            raise FloatingPointError("solver blew up")
        return super().step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)


def test_model_error_is_counted_and_resets_in_the_shared_runner():
    """
    A raising step: no prediction, counted ``model_error``, state reset; the next sample goes on.

    The runner does it, so the node and replay (``run_events``) behave the same.
    """
    from bb_friction_ros.bags import Event
    from bb_friction_ros.replay import run_events
    events = [Event("axial_load", 0.0, value=100.0)] + [
        Event("nut_state", t, ("nut_joint",), (t,), (1.0,)) for t in (0.0, 0.01, 0.02, 0.03)]
    screw = FailingScrew(bad_angle=0.02)
    runner = ModelRunner(screw, model_rate_hz=100.0, **STEP_FIRST)
    preds = run_events(events, runner, InputAssembler("nut_joint", 1e5))
    assert [p.stamp_s for p in preds] == [0.0, 0.01, 0.03]
    assert runner.stats.rejected == {"model_error": 1}
    assert runner.stats.rejected_nut_state == 1
    assert "solver blew up" in runner.stats.last_error
    assert screw.calls[-2] == ("reset", 0.03)      # a new run starts after the failure
    assert preds[-1].stepped and preds[-1].model_age_s == 0.0


def _opposes_motion(pred):
    """The feedforward pushes against the sample's motion, or is not 0 at standstill."""
    w = pred.nut_velocity_rad_s
    return pred.feedforward_nm * w < 0.0 or (w == 0.0 and pred.feedforward_nm != 0.0)


def test_skipped_reversal_never_feeds_forward_the_old_direction():
    """
    An axis holding position with +-0.02 rad/s velocity noise flipping sign every 1 kHz
    sample, the model allowed to step on one sample in ten (the live node behind): no
    feedforward opposes the motion, standstill gets 0 N m, and it is counted.
    """
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner
    runner = build_runner(bundled_config("ball_screw.yaml"), 100.0)
    preds = []
    for k in range(400):
        w = 0.0 if k % 50 == 49 else (0.02 if k % 2 == 0 else -0.02)
        s = InputSample(1e-3 * k, 1e-5 * (k % 2), w, 1500.0)
        preds.append(runner.process(s, allow_step=(k % 10 == 0)))
    assert runner.stats.skipped_steps > 100, "no reversal step was skipped: test is void"
    assert not [p for p in preds if _opposes_motion(p)]
    # the state's torque is fed forward where its direction matches (not all zeroed)
    assert sum(p.converged and p.feedforward_nm != 0.0 for p in preds) > 100
    assert runner.stats.feedforward_zeroed > 100
    # no answer carries the other direction's torque as valid either: the prediction says
    # 0 N m, not converged, and why; the state's own torque stays for diagnostics
    other = [p for p in preds if p.state_other_direction]
    assert len(other) > 100
    assert all(p.torque_total_nm == p.torque_b2g_nm == p.torque_b2b_nm == 0.0
               and not p.converged for p in other)
    assert any(p.torque_state_nm * p.nut_velocity_rad_s < 0 for p in other)
    assert not [p for p in preds if p.torque_total_nm * p.nut_velocity_rad_s < 0]


def test_lowered_load_limit_applies_to_the_held_load():
    """5000 N held, the limit lowered to 1000 N: the next sample is
    refused (absurd_load, naming the held load) until a load within the limit arrives."""
    asm = InputAssembler("nut_joint", 1e5)
    asm.on_axial_load(-5000.0)
    assert asm.on_nut_state(0.0, ("nut_joint",), (0.0,), (1.0,)).axial_load_n == -5000.0
    asm.max_axial_load_n = 1000.0
    with pytest.raises(InputError, match="5000 N exceeds max_axial_load_n = 1000 N") as err:
        asm.on_nut_state(0.001, ("nut_joint",), (0.0,), (1.0,))
    assert err.value.reason == "absurd_load"
    asm.on_axial_load(800.0)
    assert asm.on_nut_state(0.002, ("nut_joint",), (0.0,), (1.0,)).axial_load_n == 800.0
    asm.max_axial_load_n = 900.0      # still within: kept
    assert asm.on_nut_state(0.003, ("nut_joint",), (0.0,), (1.0,)).axial_load_n == 800.0


def _steps_at(runner, samples):
    return [k for k, s in enumerate(samples) if runner.process(s).stepped]


@pytest.mark.parametrize("rev_s,every", [
    (20.0, 1),      # 7.2 deg per 1 kHz sample: a 3.6 deg step is due at every sample
    (2.0, 5),       # 0.72 deg per sample: every 5th (3.6 deg)
    (0.01, 10),     # creeping: the 100 Hz time floor
])
def test_schedule_steps_by_nut_rotation_with_a_time_floor(rev_s, every):
    """A step every model_step_deg of nut rotation, at least every period."""
    w = 2 * math.pi * rev_s
    runner = ModelRunner(RecordingScrew(), model_rate_hz=100.0, model_step_deg=3.6, **STEP_FIRST)
    samples = [InputSample(5.0 + k * 1e-3, 0.3 + w * k * 1e-3, w, 100.0) for k in range(41)]
    assert _steps_at(runner, samples) == list(range(0, 41, every))


class SubstepScrew(RecordingScrew):
    """Records which steps the runner calls sub-steps (never answered)."""

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        self.calls.append(("substep" if substep else "answered", nut_angle_rad))
        return super().step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)


def test_only_the_steps_between_two_inputs_are_substeps():
    """
    Inputs 10.8 deg apart with a 3.6 deg step: two sub-steps, then the input's own step.

    A sub-step's state is never answered, so the screw may solve it to the looser
    ``solver.substep_tolerance``; the step an input is answered from never is one.
    """
    screw = SubstepScrew()
    runner = ModelRunner(screw, model_rate_hz=100.0, model_step_deg=3.6, **STEP_FIRST)
    d = math.radians(10.8)
    for k in range(3):
        runner.process(InputSample(1e-3 * k, d * k, 1.0, 100.0))
    kinds = [c[0] for c in screw.calls if c[0] in ("substep", "answered")]
    assert kinds == ["answered"] + ["substep", "substep", "answered"] * 2
    assert runner.stats.substeps == 4


def test_schedule_step_is_the_nut_rotation_either_way():
    """Backwards rotation steps the same; a step's reference is the angle it was taken at."""
    runner = ModelRunner(RecordingScrew(), model_rate_hz=1.0, model_step_deg=10.0, **STEP_FIRST)
    d = math.radians(1.0)
    angles = [-d * k for k in range(25)]
    samples = [InputSample(1e-3 * k, a, -1.0, 100.0) for k, a in enumerate(angles)]
    assert _steps_at(runner, samples) == [0, 10, 20]


@pytest.mark.parametrize("stamp", [0.0, 1234.5])
def test_stalled_stamps_step_on_angle_and_load_and_are_counted(stamp):
    """
    Every stamp equal (a driver leaving header.stamp at 0, or one stamp
    repeated).  The model still steps by nut rotation, and at once when the load changes, so
    an answer with model_age_s = 0 is never from a state of another load; stalls are counted.
    """
    screw = RecordingScrew()
    runner = ModelRunner(screw, model_rate_hz=100.0, model_step_deg=3.6)
    d = math.radians(0.9)
    preds = [runner.process(InputSample(stamp, d * k, 1.0, 1500.0)) for k in range(9)]
    assert [p.stepped for p in preds] == [k % 4 == 0 for k in range(9)]
    loads = [1500.0, 6000.0, 6000.0, 6000.0, 2000.0]
    preds = [runner.process(InputSample(stamp, 8 * d, 1.0, f)) for f in loads]
    assert [p.stepped for p in preds] == [False, True, False, False, True]
    assert runner.stats.stamp_stalls == 13
    assert runner.stats.resets == 0


def test_stalled_stamps_follow_the_load_in_the_real_model():
    """The case seen: load 1500 -> 6000 N on stamps all 0 moves the torque as it should."""
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner
    cfg = bundled_config("ball_screw.yaml")
    w = 2 * math.pi

    def run(stamps):
        runner = build_runner(cfg, 100.0)
        out = []
        for k in range(60):
            load = 1500.0 if k < 30 else 6000.0
            out.append(runner.process(InputSample(stamps(k), w * k * 1e-3, w, load)))
        return out, runner

    stalled, runner = run(lambda k: 0.0)
    advancing, _ = run(lambda k: 1e-3 * k)
    assert runner.stats.stamp_stalls == 59
    # the first sample at 6000 N steps, and the torque follows the load (~4x at 4x the load)
    assert stalled[30].stepped and stalled[30].model_age_s == 0.0
    assert stalled[59].torque_total_nm == pytest.approx(advancing[59].torque_total_nm,
                                                        rel=0.02)
    assert stalled[59].torque_total_nm > 3.0 * stalled[29].torque_total_nm


def _drift_terms():
    from bb_friction_ros.empirical_terms import load_terms
    return load_terms([{"name": "thermal_drift",
                        "params": {"delta_torque_nm": 0.5, "time_constant_s": 2.0}}])


def test_rebuild_with_the_same_terms_keeps_their_clock():
    """
    A runner rebuilt mid-run (a runtime parameter change) continues a
    thermal_drift term where it was; a runner with other terms restarts them, counted.
    """
    old = ModelRunner(RecordingScrew(), 100.0, _drift_terms())
    for k in range(6):
        p = old.process(InputSample(10.0 + k, 0.0, 1.0, 100.0))
    before = p.torque_empirical_nm
    assert before > 0.4                  # 5 s into a 2 s time constant
    new = ModelRunner(RecordingScrew(), 200.0, _drift_terms())
    assert new.continue_from(old)
    after = new.process(InputSample(16.0, 0.0, 1.0, 100.0))
    assert after.torque_empirical_nm >= before and after.stepped
    assert new.stats is old.stats and new.stats.term_restarts == 0
    other = ModelRunner(RecordingScrew(), 100.0, None)
    assert not other.continue_from(new)
    from bb_friction_ros.empirical_terms import load_terms
    changed = ModelRunner(RecordingScrew(), 100.0, load_terms([{
        "name": "thermal_drift", "params": {"delta_torque_nm": 0.1, "time_constant_s": 2.0}}]))
    assert not changed.continue_from(new)
    assert changed.stats is old.stats and changed.stats.term_restarts == 1
    assert changed.process(InputSample(17.0, 0.0, 1.0, 100.0)).torque_empirical_nm == 0.0


def test_falling_behind_takes_coarser_steps_and_recovers():
    """
    A skipped step doubles the schedule's step (once per step taken, up to
    max_model_step_deg), steps taken coarser are counted, and after a calm of input time with
    none skipped the step halves again: RELAX_MIN_S at first, doubled (up to RELAX_MAX_S)
    when the finer step fails within RELAX_MAX_S of a halving, RELAX_MIN_S again for a fall
    later than that.  Replay never skips, so it never coarsens.
    """
    from bb_friction_ros.runner import RELAX_MAX_S, RELAX_MIN_S
    runner = ModelRunner(RecordingScrew(), model_rate_hz=1.0, model_step_deg=1.0,
                         max_model_step_deg=4.0, **STEP_FIRST)
    d = math.radians(1.0)
    k = 0

    def feed(n, allow):
        nonlocal k
        out = []
        for _ in range(n):
            out.append(runner.process(InputSample(1e-3 * k, d * k, 1.0, 100.0), allow))
            k += 1
        return out

    assert all(p.stepped for p in feed(3, True))
    assert not feed(1, False)[0].stepped and runner.scale == 2.0
    assert not feed(1, False)[0].stepped and runner.scale == 2.0      # once per step
    assert feed(1, True)[0].stepped                                    # 3 deg since the last
    feed(2, False)                                                     # 1 deg: not due; 2: due
    assert runner.scale == 4.0 and runner.stats.coarsenings == 2
    feed(2, False)
    assert runner.scale == 4.0                                         # the max
    steps = [p.stepped for p in feed(12, True)]
    assert steps == [True, False, False, False] * 3                    # every 4 deg now
    assert runner.stats.coarse_steps == 4 and runner.stats.skipped_steps == 4

    def calm_then_halves(calm_s, scale):
        """After calm_s of no skip (1 ms inputs; the last skip 9-30 ms back), halved."""
        n = int(round(calm_s / 1e-3))
        feed(n - 30, True)
        assert runner.scale == 2.0 * scale                             # not yet
        feed(40, True)
        assert runner.scale == scale

    calm_then_halves(RELAX_MIN_S, 2.0)
    feed(2, False)                          # the finer step fails at once: back to 4 deg
    assert runner.scale == 4.0
    calm_then_halves(2.0 * RELAX_MIN_S, 2.0)      # and the next calm is twice as long
    calm_then_halves(2.0 * RELAX_MIN_S, 1.0)
    feed(int(RELAX_MAX_S / 1e-3), True)     # a long calm at the fine step
    feed(1, False)                          # a new fall: from RELAX_MIN_S again
    assert runner.scale == 2.0
    calm_then_halves(RELAX_MIN_S, 1.0)
    assert runner.step_rad == pytest.approx(d)


def test_inputs_further_apart_than_the_step_are_substepped():
    """
    At 20 rev/s, 1 kHz input is 7.2 deg per sample; a 1.8 deg schedule steps
    the model at 1.8 deg along the line between the samples (stamps, angles, loads linear),
    never across a reversal, and crosses an angle jump in at most MAX_SUBSTEPS steps.
    """
    from bb_friction_ros.runner import MAX_SUBSTEPS
    screw = RecordingScrew()
    runner = ModelRunner(screw, model_rate_hz=100.0, model_step_deg=1.8)
    w = 2 * math.pi * 20.0
    for k in range(3):
        runner.process(InputSample(1.0 + 1e-3 * k, w * 1e-3 * k, w, 100.0))
    steps = [c for c in screw.calls if c[0] == "step"]
    assert len(steps) == 1 + 2 * 4 and runner.stats.substeps == 2 * 3
    angles = [c[1] for c in steps]
    assert angles == pytest.approx([math.radians(1.8) * i for i in range(9)], abs=1e-12)
    assert [c[2] for c in steps[1:]] == pytest.approx([0.25e-3] * 8)
    # a reversal steps once, at the sample
    runner.process(InputSample(1.003, 0.0, -w, 100.0))
    assert len([c for c in screw.calls if c[0] == "step"]) == 10
    # an angle jump of 100 rev: MAX_SUBSTEPS steps, counted
    runner.process(InputSample(1.004, -200 * math.pi, -w, 100.0))
    assert len([c for c in screw.calls if c[0] == "step"]) == 10 + MAX_SUBSTEPS
    assert runner.stats.long_jumps == 1


def test_look_ahead_is_spaced_in_nut_angle_and_covers_the_schedule():
    """
    The profile's points are evenly spaced in nut angle over
    profile_horizon_periods model periods of motion, and never less than that many model
    steps when the nut creeps (where a period turns it less than a step).
    """
    from bb_friction_ros.runner import look_ahead_profile
    step = math.radians(1.8)
    for w, span in ((2 * math.pi * 10, 2 * 0.01 * 2 * math.pi * 10), (0.01, 2 * step)):
        runner = ModelRunner(RecordingScrew(), 100.0, model_step_deg=1.8)
        s = InputSample(3.0, 0.5, -w, 100.0)
        runner.process(s)
        angles, _, _ = look_ahead_profile(runner.profile_seed(s), 2.0, 5)
        assert angles[0] == 0.5
        assert [a - b for a, b in zip(angles, angles[1:])] == pytest.approx([span / 4] * 4)


def test_look_ahead_steps_no_further_than_max_model_step_and_can_stop_between():
    """
    At 20 rev/s the 3 points of the default profile are 72 deg apart: the copy of the model
    reaches them in 14.4 deg steps (max_model_step_deg), each with its share of the time, and
    the live node's should_stop is asked before every one of them.
    """
    from bb_friction_ros.runner import look_ahead_profile
    w = 2 * math.pi * 20
    screw = RecordingScrew()
    runner = ModelRunner(screw, 100.0, model_step_deg=1.8, max_model_step_deg=14.4)
    s = InputSample(3.0, 0.5, w, 100.0)
    runner.process(s)
    n_before = len(screw.calls)
    angles, torques, _ = look_ahead_profile(runner.profile_seed(s), 2.0, 3)
    steps = screw.calls[n_before:]      # the copy shares the record (a shallow copy)
    assert len(steps) == 10
    walked = [b[1] - a[1] for a, b in zip([("step", 0.5, 0.0)] + steps, steps)]
    assert walked == pytest.approx([math.radians(14.4)] * 10, rel=1e-9)
    assert sum(c[2] for c in steps) == pytest.approx(2 * 0.01, rel=1e-9)
    assert angles == [0.5, steps[4][1], steps[9][1]] == pytest.approx(
        [0.5, 0.5 + 0.01 * w, 0.5 + 0.02 * w], rel=1e-12)
    assert torques[1:] == [steps[4][1], steps[9][1]]    # RecordingScrew: torque = angle
    asked = []
    assert look_ahead_profile(runner.profile_seed(s), 2.0, 3,
                              should_stop=lambda: asked.append(1) or len(asked) > 3) is None
    assert len(screw.calls) - n_before - 10 == 3       # stopped after the third sub-step


def test_replay_of_a_bag_with_stamps_at_zero_follows_the_load_and_warns(tmp_path):
    """Stalled stamps in replay: header.stamp 0 on every message (log times advance)."""
    from bb_friction_ros.bags import Event, write_events
    from bb_friction_ros.replay import replay
    w = 2 * math.pi
    events, log_t = [], []
    for k in range(300):
        if k % 10 == 0:
            events.append(Event("axial_load", 0.0, value=1500.0 if k < 150 else 6000.0))
            log_t.append(1.0 + k * 1e-3)
        events.append(Event("nut_state", 0.0, ("nut_joint",), (w * k * 1e-3,), (w,)))
        log_t.append(1.0 + k * 1e-3 + 1e-4)
    bag = tmp_path / "bag"
    write_events(bag, events, log_times_s=log_t)
    summary = replay(bag, tmp_path / "out", progress=False, write_bag=False)
    assert summary["stamp_stalls"] == 299
    assert any("stamp" in warning for warning in summary["warnings"])
    rows = (tmp_path / "out" / "prediction.csv").read_text().splitlines()
    col = rows[0].split(",").index("torque_pred_nm")
    first, last = float(rows[1].split(",")[col]), float(rows[-1].split(",")[col])
    assert last > 3.0 * first > 0.0       # the model followed the load to 6000 N


def _stream(late_at=None, late_by_s=0.0105, n=400, rev_s=1.0):
    """1 kHz samples of a steady 1 rev/s motion at 1500 N; sample ``late_at`` stamped late."""
    w = 2 * math.pi * rev_s
    out = []
    for k in range(n):
        t = 1e-3 * k
        stamp = t - late_by_s if k == late_at else t
        out.append(InputSample(stamp, w * t, w, 1500.0))
    return out


def test_one_late_stamp_is_answered_from_the_state_not_a_reset():
    """
    One nut_state stamped 10.5 ms late (jitter) used to reset the balls' history, and every
    later prediction moved (up to 0.14 N m on the demo bag).  Now it is answered from the
    current state and counted; the stream goes on as if it had not come.
    """
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner
    cfg = bundled_config("ball_screw.yaml")
    clean, late = build_runner(cfg, 100.0), build_runner(cfg, 100.0)
    a = [clean.process(s) for s in _stream()]
    b = [late.process(s) for s in _stream(late_at=202)]
    assert not a[202].stepped, "the late sample would have stepped: the comparison is void"
    assert late.stats.resets == 0 and late.stats.late_samples == 1
    assert not b[202].stepped and b[202].converged
    assert b[202].model_age_s > 0.0
    assert b[202].torque_total_nm == b[201].torque_total_nm
    assert b[202].feedforward_nm * b[202].nut_velocity_rad_s >= 0.0
    # every other sample is answered exactly as without the late one
    assert [p.torque_total_nm for i, p in enumerate(b) if i != 202] == \
        [p.torque_total_nm for i, p in enumerate(a) if i != 202]


@pytest.mark.parametrize("back_s,run,resets", [
    (0.0105, 1, 0),        # one late sample
    (0.0105, 3, 0),        # LATE_SAMPLES_MAX in a row: still late
    (0.0105, 4, 1),        # one more: the source restarted
    (0.5, 1, 1),           # further back than LATE_STAMP_TOLERANCE_S: a restart
])
def test_late_samples_and_restarts_are_told_apart(back_s, run, resets):
    from bb_friction_ros.bags import LATE_SAMPLES_MAX, LATE_STAMP_TOLERANCE_S
    assert LATE_SAMPLES_MAX == 3 and LATE_STAMP_TOLERANCE_S < 0.5   # the cases above
    runner = ModelRunner(RecordingScrew(), model_rate_hz=100.0)
    for k in range(50):
        runner.process(InputSample(1e-3 * k, 1e-3 * k, 1.0, 100.0))
    t_last = 0.049
    for j in range(run):
        s = InputSample(t_last - back_s + 1e-4 * j, t_last, 1.0, 100.0)
        assert runner.step_due(s) == (j == LATE_SAMPLES_MAX or back_s > LATE_STAMP_TOLERANCE_S)
        runner.process(s)
    assert runner.stats.resets == resets
    assert runner.stats.late_samples == min(run, LATE_SAMPLES_MAX) * (back_s < 0.1)


def test_predictions_built_without_init_are_the_dataclass_s_own():
    """
    The runner builds its Predictions without the frozen dataclass's __init__ (1.9 us of
    the ~6 us a held answer costs, per input sample).  They must be the same objects to every
    user: equal, with equal hashes and repr, every field set, and still frozen.
    """
    import dataclasses
    from bb_friction_ros.runner import _prediction, Prediction
    values = (100.001, 0.25, 6.28, 1500.0, 0.21, 0.2, 0.01, 0.0, True, 0.0005,
              (((1, 2), (0.3,)),), 37, False, 0.21, False, 0.21, False, 1, 0.0)
    assert len(values) == len(dataclasses.fields(Prediction))
    fast, slow = _prediction(*values), Prediction(*values)
    assert type(fast) is Prediction
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.astuple(fast) == values
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.torque_total_nm = 1.0


@pytest.mark.parametrize("rev_s, fits", [(0.0, True), (1.0, True), (5.0, True),
                                         (10.0, False), (20.0, False)])
def test_a_profile_is_started_only_if_it_can_end_before_the_next_step(rev_s, fits):
    """
    ``profile_fits``: the look-ahead's steps at the steps' mean wall time (0.2 ms here)
    against the input time to the next step.  Defaults (1.8 deg, 100 Hz floor, 14.4 deg
    largest step; 2 periods, 3 points): 1 rev/s, 2 steps (0.4 ms) before a step due in 5 ms;
    5 rev/s, 36 deg in 2 x 2 steps (0.8 ms) against 1 ms; 10 rev/s, 72 deg in 2 x 3 steps
    (1.2 ms) against 0.5 ms; 20 rev/s, 10 steps (2 ms) against 0.25 ms.  Standstill: a
    single point, no step.
    """
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner
    runner = build_runner(bundled_config("ball_screw.yaml"), 100.0)
    runner._step_time_s = 2e-4
    w = 2 * math.pi * rev_s
    assert runner.profile_fits(InputSample(0.0, 0.0, w, 1500.0), 2.0, 3) is fits


# --- answer first, then step (step_after_answer_fraction) -----------------------------------

def _turning(rev_s, n, rate_hz=1000.0, t0=10.0, load_n=100.0):
    w = 2 * math.pi * rev_s
    return [InputSample(t0 + k / rate_hz, w * k / rate_hz, w, load_n) for k in range(n)]


def test_a_step_due_at_a_dense_input_follows_its_answer():
    """
    1 rev/s at 1 kHz (0.36 deg a sample, a fifth of the 1.8 deg step): a due step waits for
    its sample's answer, which comes from the state before it; it is taken by ``settle`` or
    by the next sample, whichever comes first, with the same answers either way (the node
    settles at once, replay lazily: live = replay).
    """
    samples = _turning(1.0, 60)
    lazy = ModelRunner(RecordingScrew(), 100.0, model_step_deg=1.8)
    eager = ModelRunner(RecordingScrew(), 100.0, model_step_deg=1.8)
    first = ModelRunner(RecordingScrew(), 100.0, model_step_deg=1.8, **STEP_FIRST)
    got_lazy, got_eager, got_first = [], [], []
    for s in samples:
        due = lazy.step_due(s)
        got_lazy.append(lazy.process(s))
        # RecordingScrew's torque is the angle of its last step: the answer's state
        assert lazy.pending == (due and len(got_lazy) > 1)
        if lazy.pending:
            assert got_lazy[-1].torque_total_nm < s.nut_angle_rad and not got_lazy[-1].stepped
            assert lazy.screw.calls[-1][1] < s.nut_angle_rad      # not stepped yet
        got_eager.append(eager.process(s))
        eager.settle()
        got_first.append(first.process(s))
    assert got_lazy == got_eager
    lazy.settle()
    assert lazy.screw.calls == eager.screw.calls == first.screw.calls    # the same steps
    assert lazy.stats.model_steps == eager.stats.model_steps == 12
    # the answer lags its sample by up to a step and a sample (0.2 of a step here), five
    # samples; stepping first, by up to four
    step = math.radians(1.8)
    lag = [s.nut_angle_rad - p.torque_total_nm for s, p in zip(samples, got_lazy)]
    lag_first = [s.nut_angle_rad - p.torque_total_nm for s, p in zip(samples, got_first)]
    assert max(lag_first) == pytest.approx(0.8 * step, rel=1e-9)
    assert max(lag) == pytest.approx(step, rel=1e-9)
    assert sum(p.stepped for p in got_lazy) == 1 and sum(p.stepped for p in got_first) == 12


@pytest.mark.parametrize("case", ["sparse", "reversal", "stalled_load", "fraction_0"])
def test_sparse_inputs_reversals_and_stalled_load_changes_step_first(case):
    """
    Where the state before the step would be the wrong answer, the step comes first: inputs
    more than the fraction of a step apart (5 rev/s at 1 kHz: a whole step), a reversal (the
    old direction's torque would push along the motion), a load change on stalled stamps,
    and any due step with ``step_after_answer_fraction`` 0.
    """
    runner = ModelRunner(RecordingScrew(), 100.0, model_step_deg=1.8,
                         **(STEP_FIRST if case == "fraction_0" else {}))
    rev_s = 5.0 if case == "sparse" else 1.0
    samples = _turning(rev_s, 12)
    if case == "reversal":
        last = samples[-1]
        samples.append(InputSample(last.stamp_s + 1e-3, last.nut_angle_rad,
                                   -last.nut_velocity_rad_s, last.axial_load_n))
    elif case == "stalled_load":
        last = samples[-1]
        samples.append(InputSample(last.stamp_s, last.nut_angle_rad, last.nut_velocity_rad_s,
                                   2.0 * last.axial_load_n))
    preds = [runner.process(s) for s in samples]
    if case in ("sparse", "fraction_0"):
        due = [k for k, p in enumerate(preds) if p.stepped]
        assert len(due) == (12 if case == "sparse" else 3) and not runner.pending
    else:
        assert preds[-1].stepped and preds[-1].model_age_s == 0.0 and not runner.pending


def test_a_step_after_its_answer_that_fails_is_counted_and_resets():
    """The sample was answered: counted ``model_error`` but not as an unanswered sample."""
    samples = _turning(1.0, 12)
    bad = samples[5].nut_angle_rad      # the first step due after the start
    runner = ModelRunner(FailingScrew(bad_angle=bad), 100.0, model_step_deg=1.8)
    preds = [runner.process(s) for s in samples[:6]]
    assert all(p is not None for p in preds) and runner.pending
    assert runner.settle() is None and not runner.pending
    assert runner.stats.rejected == {"model_error": 1} and runner.stats.rejected_nut_state == 0
    assert "solver blew up" in runner.stats.last_error
    nxt = runner.process(samples[6])        # a new run starts at the next sample
    assert nxt.stepped and runner.screw.calls[-2] == ("reset", samples[6].nut_angle_rad)


def test_feedforward_after_its_answer_never_carries_a_nonconverged_torque():
    """The held-feedforward policy under the default rule: steps that did not converge."""
    from test_feedforward import ScriptedScrew
    runner = ModelRunner(ScriptedScrew([(0.21, True), (-58.0, False), (8.0, False),
                                        (0.23, True)]), 100.0, model_step_deg=1.8)
    preds = [runner.process(s) for s in _turning(1.0, 16, load_n=1500.0)]
    assert sum(not p.converged for p in preds) == 10      # answered from the two bad steps
    assert all(p.feedforward_nm in (0.21, 0.23) for p in preds)
    assert [p.feedforward_held for p in preds] == [not p.converged for p in preds]


class _SignedScrew(RecordingScrew):
    """Torques of either sign, a step in five not converged, groups that change."""

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        from types import SimpleNamespace
        self.calls.append(("step", nut_angle_rad, dt_s))
        k = len(self.calls)
        return SimpleNamespace(torque_total_nm=math.sin(7.0 * k), torque_b2g_nm=0.5,
                               torque_b2b_nm=math.cos(3.0 * k), converged=k % 5 != 0,
                               groups=[((k % 3, 4), (1.0, 2.0))] if k % 2 else [],
                               azimuth_rad=[0.0] * (3 + k % 2))


class _Mean:
    """A stand-in for mean_b2b: a total that depends on load and speed."""

    def total_at(self, load_n, nut_velocity_rad_s):
        return 1e-4 * load_n - 0.3 * nut_velocity_rad_s


def _mixed_stream(n=3000):
    """1 kHz samples: noisy speed that reverses and stops, load steps, stalls, late, a loop."""
    out, angle = [], 0.0
    for k in range(n):
        t = 1e-3 * k - (0.5 if k >= 2500 else 0.0)        # a restart after 2500
        if k % 97 == 5:
            t -= 0.004                                      # a late sample
        if k % 211 == 7:
            t = out[-1][0]                                  # a stalled stamp
        w = (0.0 if 900 <= k < 950 else 3.0 * math.sin(1e-3 * k * 5.0)
             + 0.05 * math.sin(1.7 * k))
        angle += 1e-3 * w
        load = 1500.0 + 200.0 * (k // 300 % 2) + (50.0 if k % 211 == 7 else 0.0)
        out.append((t, angle, w, load))
    return out


@pytest.mark.parametrize("mean", [None, _Mean()])
def test_held_samples_answered_from_numbers_equal_process_values(mean):
    """
    ``process_scalars`` answers every sample as ``process_values`` does, bit for bit, and
    leaves the same counters; without mean_b2b most samples take its held path (no
    process_values).
    """
    from bb_friction_ros.runner import RunnerStats
    slow = ModelRunner(_SignedScrew(), 100.0, mean_b2b=mean)
    fast = ModelRunner(_SignedScrew(), 100.0, mean_b2b=mean)
    calls = []
    real = fast.process_values
    fast.process_values = lambda sample: calls.append(1) or real(sample)
    stream = _mixed_stream()
    for t, a, w, f in stream:
        want = slow.process_values(InputSample(t, a, w, f))
        assert repr(fast.process_scalars(t, a, w, f)) == repr(want), (t, a, w, f)
        assert fast.schedule.__dict__ == slow.schedule.__dict__
    for name in RunnerStats.__dataclass_fields__:
        if name != "last_step_wall_s":
            assert getattr(fast.stats, name) == getattr(slow.stats, name), name
    assert fast.stats.feedforward_zeroed and fast.stats.friction_cut and \
        fast.stats.late_samples and fast.stats.stamp_stalls and fast.stats.resets
    if mean is None:    # (with mean_b2b it holds only at a repeated load and speed)
        assert len(calls) < len(stream) / 2, "the held path was not taken: test is void"


def test_schedule_holds_is_plan_s_hold():
    """``Schedule.holds`` of a sample's numbers says what ``plan`` says of the sample."""
    from bb_friction_ros.schedule import HOLD
    runner = ModelRunner(_SignedScrew(), 100.0)
    held = 0
    for t, a, w, f in _mixed_stream():
        s = InputSample(t, a, w, f)
        hold = runner.schedule.plan(s).action is HOLD
        assert runner.schedule.holds(t, a, w, f) == hold
        held += hold
        runner.process_values(s)
    assert held > 1000
