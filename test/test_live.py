"""
live.LiveSchedule without ROS: answers, shedding, falling behind, health, log rate.

No DDS and no rclpy: the publishers are plain functions recording what they are given, the
clocks are handed in where a test needs to move time.  The model is the real whole-screw
runner (equality with replay) or a screw with a known step time (falling behind).
"""

import threading
import time

import pytest

from bb_friction_ros.bags import Event
from bb_friction_ros.config import bundled_config
from bb_friction_ros.live import (ERROR, LiveSchedule, OK, Outputs, process_age_s,
                                  process_cpu_s, WARN)
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay import run_events
from bb_friction_ros.runner import (build_runner, InputAssembler, InputError, InputSample,
                                    ModelRunner)
from recordings import short_recording
from test_node_feedforward_sign import SlowScrew


class Recorder:
    """The node's publishers as functions: what each was handed, in order."""

    def __init__(self):
        self.answers, self.groups, self.profiles, self.logs = [], [], [], []
        self.threads = set()        # the threads that published answers
        self._lock = threading.Lock()

    def outputs(self):
        return Outputs(answer=self._answer, groups=lambda p, s: self.groups.append((p, s)),
                       profile=lambda *a: self.profiles.append(a),
                       log=lambda level, text: self.logs.append((level, text)))

    def _answer(self, pred, stamp, latency_s, thread):
        with self._lock:
            self.answers.append((pred, stamp, latency_s, thread))
            self.threads.add(threading.get_ident())


class Clock:
    """A monotonic clock a test moves by hand."""

    def __init__(self, t=1000.0):
        self.t = t

    def __call__(self):
        return self.t


def schedule(params=None, runner=None, clock=None, clock_ns=time.time_ns):
    p = params or NodeParameters(max_answer_age_s=10.0)
    runner = runner or build_runner(bundled_config("ball_screw.yaml"), *p.schedule())
    rec = Recorder()
    live = LiveSchedule(runner, InputAssembler(p.nut_joint, p.max_axial_load_n), p,
                        rec.outputs(), clock_ns=clock_ns, monotonic=clock or time.monotonic)
    live.start()
    return live, rec


def feed(live, events, wait_idle=True, more_waiting=False):
    """
    Hand ``events`` in as the node's input thread would; wait for each to be answered.

    ``more_waiting`` an int k: as if the nut_states up to k later had already arrived with
    each one (the input thread's batch): the k-th later is handed in as the newest waiting.
    """
    states = [ev for ev in events if ev.kind == "nut_state"]
    k = more_waiting if type(more_waiting) is int else 1
    later = {id(a): (b.stamp_s, b.names, b.positions, b.velocities)
             for a, b in zip(states, states[k:])}
    for ev in events:
        if ev.kind == "axial_load":
            live.on_axial_load(ev.value)
        elif ev.kind == "nut_state":
            waiting = later.get(id(ev), False) if type(more_waiting) is int else more_waiting
            live.on_nut_state(ev.stamp_s, ev.names, ev.positions, ev.velocities,
                              time.time_ns(), ev.stamp_s, waiting)
            while wait_idle and not live.idle():
                time.sleep(0.0002)


def wait_until(cond, timeout_s=20.0):
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.001)


@pytest.mark.parametrize("more_waiting, young", [(False, False), (True, False), (1, False),
                                                 (6, False), (True, True), (6, True)])
def test_live_schedule_equals_replay(more_waiting, young):
    """
    Paced inputs (the model keeps up): the answers are replay's, value for value.  With no
    other input waiting a due step is taken in the caller's thread (no hand-off).  With
    ``max_backlog_s`` 0 (every waiting input counts as a backlog): with inputs waiting (a
    batch, not known which) it goes to the model thread; with the newest waiting input
    known (1 or 6 inputs later: 5 inputs per model period), only the steps after which that
    one would be due again go to the model thread (the model is behind).  With the default
    ``max_backlog_s`` (``young``: the waiting inputs are younger than it) everything is
    stepped in the caller's thread.  The same answers every way.
    """
    events = short_recording(state_rate_hz=500.0)     # 5 inputs per model period
    live, rec = schedule(NodeParameters(max_answer_age_s=10.0,
                                        max_backlog_s=0.005 if young else 0.0))
    try:
        feed(live, events, more_waiting=more_waiting)
    finally:
        live.stop()
    p = NodeParameters()
    ref = run_events(events, build_runner(bundled_config("ball_screw.yaml"), p.model_rate_hz),
                     InputAssembler(p.nut_joint, p.max_axial_load_n))
    got = sorted(rec.answers, key=lambda a: a[1])
    assert len(got) == len(ref) > 0
    for (pred, stamp, _, _), want in zip(got, ref):
        assert stamp == want.stamp_s
        assert pred == want
    values = live.values()[0]
    assert values["skipped_steps"] == values["dropped_inputs"] == values["shed_inputs"] == 0
    assert values["profiles"] == len(rec.profiles) > 0
    # the inputs a step was due at (stepped before their answer, or after it: the runner's
    # step_after_answer_fraction), and those after which the newest waiting one would be
    # due again (``more_waiting`` an int: the model is behind)
    runner = build_runner(bundled_config("ball_screw.yaml"), p.model_rate_hz)
    asm = InputAssembler(p.nut_joint, p.max_axial_load_n)
    due, behind = [], set()
    states = [ev for ev in events if ev.kind == "nut_state"]
    for ev in events:
        if ev.kind == "axial_load":
            asm.on_axial_load(ev.value)
            continue
        try:
            a = asm.on_nut_state(ev.stamp_s, ev.names, ev.positions, ev.velocities)
        except InputError:
            continue
        i = states.index(ev)
        if runner.step_due(a):
            due.append(a.stamp_s)
            if type(more_waiting) is int and i + more_waiting < len(states):
                b = states[i + more_waiting]
                try:        # a refused newest input tells nothing: handed off
                    late = runner.due_between(a, asm.on_nut_state(
                        b.stamp_s, b.names, b.positions, b.velocities))
                except InputError:
                    late = True
                if late:
                    behind.add(a.stamp_s)
        runner.process(a)
    assert 0 < len(due) < len(rec.answers)
    # at 500 Hz and 0.12 rad/s the inputs are dense: most steps follow their answer
    assert sum(a[0].stepped for a in rec.answers) < len(due) / 2
    if young or not more_waiting:   # everything in the caller's thread
        assert {a[3] for a in rec.answers} == {0}
        assert rec.threads == {threading.get_ident()}
        assert values["answered_inline"] == len(rec.answers)
    elif type(more_waiting) is int:   # handed off: the steps the newest would follow
        # the next input is never a step further (5 per period), the sixth nearly always
        # (not for the last steps, with fewer than six inputs after them)
        assert len(behind) == 0 if more_waiting == 1 else len(due) - 6 < len(behind)
        assert {a[1] for a in rec.answers if a[3] == 1} == behind
        assert values["answered_inline"] == len(rec.answers) - len(behind)
    else:               # due steps in the model thread, the rest in the caller's
        assert {a[1] for a in rec.answers if a[3] == 1} == set(due) and len(rec.threads) == 2
        assert values["answered_inline"] == len(rec.answers) - len(due)


def test_one_profile_per_model_period_of_motion():
    """
    At 1 rev/s the 1.8 deg step falls due twice per model period (3.6 deg of motion): a
    profile is started at every other step, and each one published lies a period of
    motion (or a reversal) past the last.  Once at every step, the old rule, asked for
    500-4000 profiles/s at 20 rev/s, each longer than the time between two steps.
    """
    import math
    live, rec = schedule()
    j = ("nut_joint",)
    w = 2 * math.pi
    try:
        feed(live, [Event("axial_load", 0.0, value=1500.0)])
        for k in range(300):    # 1 kHz, reversing after 150 ms
            t = 1e-3 * k
            angle, v = (w * t, w) if k < 150 else (w * (0.3 - t), -w)
            feed(live, [Event("nut_state", t, j, (angle,), (v,))])
            time.sleep(0.0005)  # leaves the model thread time for its profile
    finally:
        live.stop()
    values = live.values()[0]
    started = values["profiles"] + values["profiles_abandoned"]
    assert values["model_steps"] >= 55       # 108 deg of motion in 1.8 deg steps
    assert 0 < started <= values["model_steps"] // 2 + 2
    assert values["profiles"] == len(rec.profiles) > 0
    step = math.radians(NodeParameters().model_step_deg)
    for (a, *_), (b, *_) in zip(rec.profiles, rec.profiles[1:]):
        assert abs(b.nut_angle_rad - a.nut_angle_rad) >= 2 * step - 1e-9 \
            or b.nut_velocity_rad_s != a.nut_velocity_rad_s


def test_no_profile_while_the_schedule_is_coarser():
    """A model that could not keep its steps (scale > 1) starts no look-ahead profile."""
    import math
    live, rec = schedule()
    j = ("nut_joint",)
    w = 2 * math.pi
    events = [Event("nut_state", 1e-3 * k, j, (w * 1e-3 * k,), (w,)) for k in range(100)]
    try:
        feed(live, [Event("axial_load", 0.0, value=1500.0)] + events[:1])
        first = live.values(advance=False)[0]       # the first step's profile
        # a step the live model could not take: the schedule turns coarser (2 x 1.8 deg)
        live.runner.process(InputSample(events[10].stamp_s, events[10].positions[0], w,
                                        1500.0), allow_step=False)
        assert live.runner.scale == 2.0
        feed(live, events[11:50])
        coarse = live.values(advance=False)[0]
        live.runner.scale = 1.0
        feed(live, events[50:])
    finally:
        live.stop()
    values = live.values()[0]
    assert coarse["model_steps"] >= 5
    started = ("profiles", "profiles_abandoned")
    assert first["profiles"] == 1
    assert sum(coarse[k] for k in started) == sum(first[k] for k in started)
    assert values["profiles"] > 0


@pytest.mark.parametrize("waited_s", [0.0, 0.02])
def test_a_backlog_is_inputs_older_than_max_backlog_s(waited_s):
    """
    20 rev/s at 1 kHz: every input is due four 1.8 deg steps, and the newest waiting one is
    always due again after it.  Inputs younger than ``max_backlog_s`` (an input taken while
    the one before it steps: the normal pipeline at 20 rev/s) are stepped as replay steps
    them; older ones (``waited_s`` 20 ms, a real backlog) are caught up by skipping steps,
    and the schedule turns coarser.  Before max_backlog_s the first case skipped too, and
    the live node at 20 rev/s coarsened to 14.4 deg.
    """
    import math
    p = NodeParameters(max_answer_age_s=10.0)     # max_backlog_s: the default, 5 ms
    live, rec = schedule(p)
    j = ("nut_joint",)
    w = 40 * math.pi
    states = [(1e-3 * k, j, (w * 1e-3 * k,), (w,)) for k in range(40)]
    try:
        live.on_axial_load(1500.0)
        for k, state in enumerate(states):
            newest = states[k + 1] if k + 1 < len(states) else False
            live.on_nut_state(*state, time.time_ns() - int(waited_s * 1e9), state[0], newest)
            while waited_s < p.max_backlog_s and not live.idle():
                time.sleep(0.0002)      # young: each taken after the one before it
        wait_until(lambda: live.values(advance=False)[0]["published"] == len(states))
    finally:
        live.stop()
    values = live.values()[0]
    assert values["published"] == len(states)
    if waited_s < p.max_backlog_s:
        ref = run_events([Event("axial_load", 0.0, value=1500.0)]
                         + [Event("nut_state", *s) for s in states],
                         build_runner(bundled_config("ball_screw.yaml"), p.model_rate_hz),
                         InputAssembler(p.nut_joint, p.max_axial_load_n))
        assert [a[0] for a in rec.answers] == ref
        assert values["skipped_steps"] == values["coarse_steps"] == 0
        assert values["answered_inline"] == len(states)
    else:
        assert values["skipped_steps"] > 0 and values["coarse_steps"] > 0


def test_answers_older_than_the_limit_are_shed_and_counted():
    """A clock that says every answer is 1 s old: none published, every one counted."""
    events = short_recording()
    live, rec = schedule(NodeParameters(max_answer_age_s=0.02),
                         clock_ns=lambda: time.time_ns() + 1_000_000_000)
    try:
        feed(live, events)
    finally:
        live.stop()
    values = live.values()[0]
    n = sum(e.kind == "nut_state" for e in events)
    assert rec.answers == [] and values["published"] == 0
    assert values["shed_inputs"] == values["received_nut_state"] == n


def test_a_slow_model_falls_behind_coarsens_and_says_so():
    """A burst on a model slower than the input: steps skipped and coarser, WARN, all counted."""
    p = NodeParameters(max_answer_age_s=10.0, queue_size=100000)
    live, rec = schedule(p, runner=ModelRunner(SlowScrew(), p.model_rate_hz))
    j = ("nut_joint",)
    try:
        live.on_axial_load(1500.0)
        n = 300
        # 1 kHz stamps, 6 rad/s, received at once (one receipt time): each with more
        # waiting behind it, older than max_backlog_s once the first 20 ms step is done
        received_ns = time.time_ns()
        for k in range(n):
            live.on_nut_state(1e-3 * k, j, (6e-3 * k,), (6.0,), received_ns, k, k < n - 1)
        wait_until(lambda: live.values(advance=False)[0]["published"] == n)
    finally:
        live.stop()
    level, message, values = live.status()
    assert values["skipped_steps"] > 0 and values["coarse_steps"] > 0
    assert level == WARN and "steps skipped" in message and "coarser" in message
    # answered in arrival order, each exactly once
    assert [a[1] for a in rec.answers] == sorted(a[1] for a in rec.answers)
    assert len({a[1] for a in rec.answers}) == n


def test_no_input_is_an_error_and_inputs_make_it_ok():
    """As diagnostic_updater's FrequencyStatus: ERROR with no events, OK once they come."""
    clock = Clock()
    p = NodeParameters(max_answer_age_s=10.0, input_timeout_s=0.5)
    live, rec = schedule(p, clock=clock)
    try:
        assert live.ready
        clock.t += 0.6
        level, message, _ = live.status()
        assert level == ERROR and "no nut_state received yet" in message
        events = short_recording()
        feed(live, events)
        level, message, values = live.status()
        assert (level, message) == (OK, "ok"), message
        assert values["ready"] is True
        clock.t += 0.4                        # within input_timeout_s: still fine
        assert live.status()[0] == OK
        clock.t += 0.2                        # 0.6 s since the last nut_state
        level, message, _ = live.status()
        assert level == ERROR and "no nut_state for 0.6 s" in message
    finally:
        live.stop()


def test_a_model_rate_below_the_configured_floor_warns():
    """The model steps at 10 Hz where model_rate_hz = 100 asks for 100 steps/s: WARN."""
    p = NodeParameters(max_answer_age_s=10.0, model_step_deg=90.0, max_model_step_deg=90.0)
    slow = build_runner(bundled_config("ball_screw.yaml"), 10.0, 90.0, 90.0)
    live, _ = schedule(p, runner=slow)
    j = ("nut_joint",)
    try:
        feed(live, [Event("axial_load", 0.0, value=1500.0)])
        live.status()                          # a window starting now
        # 1 s of input at 1 kHz, 0.6 rad/s: the 90 deg step never falls due, the time floor
        # (10 Hz here) does
        feed(live, [Event("nut_state", 1e-3 * k, j, (6e-4 * k,), (0.6,))
                    for k in range(1000)])
        level, message, values = live.status()
        assert level == WARN and "model rate low" in message, message
        assert "expected at least 98" in message
        # the same inputs on a runner of the configured rate: no warning
        ok, _ = schedule(p, runner=build_runner(bundled_config("ball_screw.yaml"), 100.0,
                                                90.0, 90.0))
        feed(ok, [Event("axial_load", 0.0, value=1500.0)])
        ok.status()
        feed(ok, [Event("nut_state", 1e-3 * k, j, (6e-4 * k,), (0.6,)) for k in range(1000)])
        level, message, _ = ok.status()
        ok.stop()
        assert level == OK, message
    finally:
        live.stop()


def test_backward_stamps_are_counted_and_logged_at_most_once_per_period():
    """A reset at every sample used to give one warning each (1191 in 5 s)."""
    clock = Clock()
    p = NodeParameters(max_answer_age_s=10.0, diagnostics_rate_hz=1.0)
    live, rec = schedule(p, clock=clock)
    j = ("nut_joint",)
    try:
        feed(live, [Event("axial_load", 0.0, value=1500.0)])
        # every other sample goes back in time, further than a late stamp: 50 resets
        events = [Event("nut_state", 10.0 + (0.01 * k if k % 2 == 0 else -1.0 - 0.01 * k), j,
                        (0.06 * k,), (6.0,)) for k in range(101)]
        feed(live, events)
        warnings = [t for level, t in rec.logs if level == "warning"]
        resets = live.values(advance=False)[0]["resets"]
        assert resets >= 50 and len(warnings) == 1, (resets, warnings)
        clock.t += 1.0                         # one diagnostics period later
        feed(live, [Event("nut_state", 5.0, j, (0.0,), (6.0,))])
        warnings = [t for level, t in rec.logs if level == "warning"]
        assert len(warnings) == 2 and f"({resets - 1} more resets" in warnings[1]
        level, message, values = live.status()
        assert level == WARN and "model state reset" in message
        assert values["resets"] == resets + 1
    finally:
        live.stop()


def test_a_rebuilt_model_keeps_the_counters():
    """apply(): a new runner takes over the counters; parameters change in place."""
    live, _ = schedule()
    try:
        feed(live, short_recording())
        steps = live.values(advance=False)[0]["model_steps"]
        new = build_runner(bundled_config("ball_screw.yaml"), 50.0)
        live.apply(NodeParameters(model_rate_hz=50.0, nut_joint="other"), new)
        assert live.runner is new and live.values()[0]["model_steps"] == steps
        live.on_nut_state(100.0, ("nut_joint",), (0.0,), (1.0,), time.time_ns(), 100.0)
        assert live.values()[0]["rejected_wrong_joint"] == 1
    finally:
        live.stop()


def test_process_age_is_this_process():
    """The start-up figure of the ready log line: this process's age, not the machine's."""
    age = process_age_s()
    assert age is not None and 0.0 <= age < time.monotonic()
    # CPU time of all threads: positive, and no more than the cores could give since launch
    assert 0.0 < process_cpu_s() <= age * (__import__("os").cpu_count() or 1) + 0.05
    assert age == pytest.approx(time.monotonic() - _T_IMPORTED + _AGE_AT_IMPORT, abs=0.1)


_T_IMPORTED = time.monotonic()
_AGE_AT_IMPORT = process_age_s()


def test_ready_means_compiled_nothing_compiles_in_the_live_path():
    """
    After build_runner (the node's "ready"), steps and look-ahead profiles compile nothing.

    A read-only state array once made numba compile a second specialisation of the warm
    kernel at the first profile, seconds after "ready", in the model thread.
    """
    from bb_friction_ros import compiled
    from bb_friction_ros.ball_screw import kernel
    from bb_friction_ros.runner import InputSample, look_ahead_profile
    if not compiled.HAVE_NUMBA:
        pytest.skip("numba not installed: nothing is compiled")
    dispatchers = {name: f for name, f in vars(kernel).items() if hasattr(f, "signatures")}
    runner = build_runner(bundled_config("ball_screw.yaml"), 100.0)
    before = {name: len(f.signatures) for name, f in dispatchers.items()}
    w = 6.0
    for k in range(200):        # steps, a reversal, profiles after each step
        s = InputSample(1e-3 * k, w * 1e-3 * k if k < 100 else w * (0.2 - 1e-3 * k),
                        w if k < 100 else -w, 1500.0)
        if runner.process(s).stepped:
            look_ahead_profile(runner.profile_seed(s), 2.0, 3)
    after = {name: len(f.signatures) for name, f in dispatchers.items()}
    assert after == before


def test_changed_groups_and_profiles_wait_for_the_input_thread_to_be_idle():
    """
    With ``defer_to_idle`` (the node's fast input path), a step's changed contact groups and
    its profile's hand-off wait for ``flush`` (called when no input waits), so an input
    that came during the step is answered first.  The answers are replay's all the same,
    and after each flush the groups and profiles are what the immediate path publishes.
    """
    events = short_recording(state_rate_hz=500.0)
    runs = {}
    for defer in (False, True):
        live, rec = schedule()
        live.defer_to_idle = defer
        held_back = 0
        try:
            for ev in events:
                groups = len(rec.groups)
                feed(live, [ev], wait_idle=not defer)
                if defer and live.deferred:
                    held_back += 1
                    assert len(rec.groups) == groups        # nothing new published yet
                    live.flush()
                    assert not live.deferred
                    wait_until(live.idle)
        finally:
            live.stop()
        runs[defer] = rec, held_back
    (now, _), (later, held_back) = runs[False], runs[True]
    assert held_back > 0
    assert [(a[0], a[1]) for a in later.answers] == [(a[0], a[1]) for a in now.answers]
    assert [(p.groups, s) for p, s in later.groups] == [(p.groups, s) for p, s in now.groups]
    assert [p[1:] for p in later.profiles] == [p[1:] for p in now.profiles]


def test_a_profile_steps_only_in_the_input_threads_gaps(monkeypatch):
    """
    A look-ahead profile takes each of its steps in an idle gap of the input thread (after
    an input was answered and nothing is left to do for it), not beside it: the first in
    the gap after the step that seeded it, the next only after the next input's answer.
    Without inputs, GAP_WAIT_S releases the step (nothing to collide with then).  Every
    step before its answer here (``step_after_answer_fraction`` 0); a step after it:
    ``test_after_a_step_in_the_gap_a_profile_starts_in_the_next_gap``.
    """
    first = NodeParameters(max_answer_age_s=10.0, step_after_answer_fraction=0.0)
    import math
    from bb_friction_ros import live as live_module
    j = ("nut_joint",)
    w = 2 * math.pi            # 1 rev/s, 1 kHz: a profile of 3 points is 2 steps of 3.6 deg

    def state(k):
        return Event("nut_state", 1e-3 * k, j, (w * 1e-3 * k,), (w,))

    def seed_a_profile(live, rec):
        """Feed inputs 20 ms apart until one leaves a profile unfinished after 20 ms."""
        feed(live, [Event("axial_load", 0.0, value=1500.0)])
        for k in range(300):
            n = len(rec.profiles)
            feed(live, [state(k)], wait_idle=False)
            time.sleep(0.02)
            if not live.idle() or len(rec.profiles) > n:
                return k, n
        raise AssertionError("no profile was started")

    monkeypatch.setattr(live_module, "GAP_WAIT_S", 30.0)
    live, rec = schedule(first)
    try:
        k, n = seed_a_profile(live, rec)
        time.sleep(0.3)         # far more than a profile's steps take
        assert len(rec.profiles) == n and not live.idle()   # waits for a gap
        feed(live, [state(k + 1)], wait_idle=False)
        wait_until(lambda: len(rec.profiles) == n + 1, timeout_s=5.0)
    finally:
        live.stop()
    monkeypatch.setattr(live_module, "GAP_WAIT_S", 0.005)
    live, rec = schedule(first)
    try:
        k, n = seed_a_profile(live, rec)
        wait_until(lambda: len(rec.profiles) == n + 1, timeout_s=5.0)   # no input came
    finally:
        live.stop()
    assert len(rec.profiles[-1][2]) == 3


def test_after_a_step_in_the_gap_a_profile_starts_in_the_next_gap(monkeypatch):
    """
    Dense inputs (1 rev/s, 0.36 deg apart): the input thread takes the due step after the
    answer, in that input's gap, so the look-ahead profile seeded by that step waits for the
    next gap for its first step (one step-sized piece of work per gap), and for the one
    after for its second.
    """
    import math
    from bb_friction_ros import live as live_module
    j = ("nut_joint",)
    w = 2 * math.pi

    def state(k):
        return Event("nut_state", 1e-3 * k, j, (w * 1e-3 * k,), (w,))

    monkeypatch.setattr(live_module, "GAP_WAIT_S", 30.0)
    live, rec = schedule()
    try:
        feed(live, [Event("axial_load", 0.0, value=1500.0)])
        for k in range(300):        # 20 ms apart in wall time: every gap is long
            steps = live.runner.stats.model_steps
            feed(live, [state(k)], wait_idle=False)
            # stepped in this input's gap, after its answer (profiles are due every tenth
            # input, steps every fifth: an older profile has had five gaps to end)
            after = live.runner.stats.model_steps > steps and not rec.answers[-1][0].stepped
            time.sleep(0.02)
            if after and not live.idle():       # and a profile it seeded waits
                break
        else:
            raise AssertionError("no profile was started")
        n = len(rec.profiles)
        for extra in (1, 2):
            time.sleep(0.3)     # far more than a step of the profile takes
            assert len(rec.profiles) == n and not live.idle()     # waits for a gap
            feed(live, [state(k + extra)], wait_idle=False)
        wait_until(lambda: len(rec.profiles) == n + 1, timeout_s=5.0)
    finally:
        live.stop()


def _one_rev_s_at_1_khz(n):
    """A 100 N load, then ``n`` nut states of 1 rev/s at 1 kHz from angle 0."""
    import math
    w = 2 * math.pi
    return [Event("axial_load", 10.0, value=100.0)] + [
        Event("nut_state", 10.0 + k / 1000, ("nut_joint",), (w * k / 1000,), (w,))
        for k in range(n)]


def test_a_step_due_at_a_dense_input_runs_after_its_answer_is_published():
    """
    1 rev/s at 1 kHz (the runner's ``step_after_answer_fraction``): the step due at every
    fifth input is taken in the input thread after that input's answer is published, in the
    gap before the next one, so no answer waits for a step (docs/node_latency.md).
    """
    from test_runner import RecordingScrew
    published = []

    class CountingScrew(RecordingScrew):
        def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
            self.calls.append(("published", len(published), self))
            return super().step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)

    screw = CountingScrew()
    live, rec = schedule(runner=ModelRunner(screw, 100.0, model_step_deg=1.8))
    rec.answers = published         # the recorder appends each answer to this list
    try:
        feed(live, _one_rev_s_at_1_khz(26))
    finally:
        live.stop()
    counts = [c[1] for c in screw.calls if c[0] == "published" and c[2] is screw]
    # (the look-ahead profile steps copies of the screw, sharing its list of calls)
    # the first input steps before its answer (no state yet); then inputs 5, 10, 15, 20
    # and 25 (0-based) are due, each stepped once its own answer is out
    assert counts == [0, 6, 11, 16, 21, 26]
    assert [p.stepped for p, *_ in published] == [True] + [False] * 25
    assert {a[3] for a in published} == {0} and rec.threads == {threading.get_ident()}


def test_a_step_after_its_answer_that_fails_is_logged_and_the_next_input_restarts():
    """The answer went out; the failed step is counted, logged once, and the state reset."""
    import math
    from test_runner import FailingScrew
    bad = 2 * math.pi * 5 / 1000    # the first step due after the start (1.8 deg, 1 rev/s)
    live, rec = schedule(runner=ModelRunner(FailingScrew(bad_angle=bad), 100.0,
                                            model_step_deg=1.8))
    try:
        feed(live, _one_rev_s_at_1_khz(8))
    finally:
        live.stop()
    assert len(rec.answers) == 8        # every input answered, the one before its step too
    assert [lvl for lvl, text in rec.logs if "model step failed" in text] == ["error"]
    assert live.runner.stats.rejected == {"model_error": 1}
    assert rec.answers[6][0].stepped and rec.answers[6][0].model_age_s == 0.0   # restarted
