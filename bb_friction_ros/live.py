"""
The live schedule of ``friction_node``, without ROS: who answers an input, and when.

``node.py`` is a shell around this class: it takes messages off the wire and hands them in
(``on_nut_state``, ``on_axial_load``), and hands in its publishers as functions
(``Outputs``).  Everything between is here, so it is tested without DDS
(``test/test_live.py``).

Per-input path: a nut-state sample is validated (``runner.InputAssembler``) and reaches the
runner in arrival order, so the answers equal replay's exactly (the runner is the same).
Who steps and answers:

- no step due (most inputs at low speed: the model steps every ``model_step_deg`` of nut
  rotation, the inputs come at the controller's rate): answered at once from the latest
  model state, in the caller's (input) thread;
- a step due at an input close to the one before it (at most
  ``step_after_answer_fraction`` of a step: 1 rev/s at 1 kHz): answered at once as well,
  and the step taken after the answer in the same thread, in the gap before the next input
  (``runner.settle``; the runner's rule, so replay gives the same answers);
- a step due, the model thread idle and no other input waiting (``more_waiting`` False:
  the input thread's batch held nothing after it), or inputs waiting but none that would
  be due another step after this one: stepped and answered in the caller's thread too.
  A hand-off to the model thread costs a scheduler wake-up: in-process at 1 rev/s, load
  8, the p99 from input to answer was 1.1-21.5 ms through the model thread and 0.7-0.8 ms
  stepped in the caller's thread (bench/bench_live_handoff.py, docs/model_schedule.md);
- a step due while inputs wait that would be due another step after it and it has waited
  longer than ``max_backlog_s`` (the model is behind), or any input while the model thread
  works: queued for the model thread, which steps, answers it and everything queued behind
  it in order.  Younger inputs waiting are no backlog: at 20 rev/s every 1 kHz input is
  due a step, and the next one is nearly always taken while this one steps.

After a step, once per model period of motion (``runner.profile_due``), the model thread
steps a copy of the state ahead for the look-ahead profile, giving way to the next step.
Each of the copy's steps waits for an idle gap of the input thread (``flush`` marks one
after every answered input), so that it does not take a core when an input arrives.

Answer age is bounded: an answer older than ``max_answer_age_s`` since the input was
received by the middleware is not published but counted (``shed_inputs``); its sample still
goes through the runner, so the model is not disturbed.  When the model itself falls behind
(a step now would leave another due at an input already waiting in its queue, and this
input waited longer than ``max_backlog_s``), a step due
on a queued sample is not taken (``process(allow_step=False)``: the runner counts it and
turns its schedule coarser); the newest sample steps.  Answers then differ from replay's,
and diagnostics say so.

Health (``status``), as diagnostic_updater's ``FrequencyStatus`` would judge it: ERROR when
no nut_state arrived for ``input_timeout_s``; WARN when the model stepped less often than
its configured floor allows (``model_rate_tolerance``), took coarser steps, shed, skipped,
rejected or dropped inputs; OK otherwise.
"""

import collections
from dataclasses import dataclass
import math
import os
import threading
import time
from typing import Callable

from bb_friction_ros.inputs import InputError
from bb_friction_ros.live_health import ERROR, LiveHealth, OK, WARN  # noqa: F401
from bb_friction_ros.look_ahead import look_ahead_profile, profile_due
# The thread that answers, so a publisher may keep one reusable message per thread.
INLINE, MODEL = 0, 1
# How long the model thread waits for work before it looks at the stop flag again [s].
IDLE_WAIT_S = 0.5
# Longest wait of a look-ahead profile's step for a gap between inputs [s] (``_gap_gate``):
# 2.5x the slowest controller period served (0.5 kHz), so at every supported input rate a
# gap, not this, releases the step; when the inputs stop, a profile ends this much later per
# step (nothing to collide with then).
GAP_WAIT_S = 0.005


@dataclass
class Outputs:
    """The node's publishers, handed in as functions (no ROS here)."""

    # (pred, stamp, latency_s, thread): publish the prediction and the feedforward
    answer: Callable
    # (pred, stamp): publish the contact groups (on change, and on the node's timer)
    groups: Callable
    # (sample, stamp, angles, torques, converged): publish the look-ahead profile
    profile: Callable
    # (level, text) with level "info", "warning" or "error"
    log: Callable


class _LookAheadProfiles:
    """
    The look-ahead side of ``LiveSchedule``: when a profile starts, and its steps in gaps.

    After a step, once per model period of motion (``runner.profile_due``), the model thread
    steps a copy of the state ahead, giving way to the next step; each of the copy's steps
    waits for an idle gap of the input thread (``LiveSchedule.flush`` marks one).
    """

    def _init_profiles(self):
        self._profile_seed = None   # (seed, stamp, gap) handed to the model thread
        self._deferred_seed = None  # the same, captured inline, handed over by ``flush``
        self._gaps = 0              # idle gaps of the input thread so far (``flush``)
        self._gated = False         # a profile's step waits for the next gap
        self._profiled = None       # the seed of the last profile published
        self._profiles = 0
        self._profiles_abandoned = 0
        self._profiles_not_started = 0
        self._profile_errors = 0

    def _profile_wanted(self, runner, stepped, sample):
        """
        Whether the step just taken for ``sample`` should start a look-ahead profile.

        Once per model period of motion (``runner.profile_due``), not while the schedule is
        coarser than configured (a model that could not keep its steps has no CPU for a
        look-ahead), and only if it can end before the next step is due
        (``runner.profile_fits``; counted in ``profiles_not_started`` otherwise): at
        20 rev/s every profile started was abandoned at the next step, 0 published per
        second, and the ones started cost 0.3-0.4 of a core beside 1.8 deg steps.
        """
        if not (stepped and runner.scale == 1.0
                and profile_due(self._profiled, sample)):
            return False
        if runner.profile_fits(sample, *self._profile_shape):
            return True
        with self._lock:
            self._profiles_not_started += 1
        return False

    def _gap_gate(self, seen):
        """
        Wait for an idle gap of the input thread, then say whether a profile should stop.

        A look-ahead profile's ``should_stop``.  ``seen``: a one-item list, the gap count
        the profile's last step began in (steps wait for a later gap, or GAP_WAIT_S when
        none comes).  Returns True (abandon) when an input waits for the model thread, the
        input thread steps, or the node stops.
        """
        with self._lock:
            self._gated = True
            self._wake.wait_for(lambda: self._gaps > seen[0] or self._queue or self._stop,
                                timeout=GAP_WAIT_S)
            self._gated = False
            seen[0] = self._gaps
            return bool(self._busy or self._stepping or self._queue or self._stop)

    def _publish_profile(self, seed_stamp):
        seed, stamp, gap = seed_stamp
        horizon, points = self._profile_shape
        seen = [gap]
        try:
            out = look_ahead_profile(seed, horizon, points,
                                     should_stop=lambda: self._gap_gate(seen))
        except Exception as exc:     # a failed look-ahead must not stop the answers
            with self._lock:
                self._profile_errors += 1
            self.outputs.log("error", f"look-ahead profile failed: {exc!r}")
            return
        if out is None:
            with self._lock:
                self._profiles_abandoned += 1
            return
        angles, torques, converged = out
        self.outputs.profile(seed.sample, stamp, angles, torques, converged)
        self._profiled = seed
        with self._lock:
            self._profiles += 1

    @property
    def deferred(self):
        """Whether ``flush`` has work: changed groups to publish or a profile to hand over."""
        return self._deferred_groups or self._deferred_seed is not None

    def flush(self):
        """Publish changed groups and hand a profile's seed to the model thread (if any)."""
        if self._deferred_groups:
            self._deferred_groups = False
            self.publish_groups()
        seed, self._deferred_seed = self._deferred_seed, None
        # The input thread is idle from here to its next input: a gap.  A look-ahead
        # profile steps only in such gaps (``_gap_gate``), so that it runs while the input
        # thread waits instead of beside it: on two cores shared with the controller, a
        # profile running when an input arrived delayed it by 0.25-0.7 ms (p99), whether
        # the profile held the GIL or not (docs/node_latency.md).
        with self._lock:
            self._gaps += 1
            if seed is not None:
                self._profile_seed = seed
            if seed is not None or self._gated:
                self._wake.notify()     # not at every input: a wake-up costs the GIL


class LiveSchedule(LiveHealth, _LookAheadProfiles):
    """
    The queue, the inline answers, the model thread, shedding, the profile and the counters.

    ``runner`` (runner.ModelRunner) and ``assembler`` (runner.InputAssembler) are the same
    objects replay uses; ``params`` is a node_parameters.NodeParameters.  ``clock_ns`` gives
    the wall time the input's ``recv_ns`` is measured in (answer age).
    """

    def __init__(self, runner, assembler, params, outputs, clock_ns=time.time_ns,
                 monotonic=time.monotonic):
        """Keep the collaborators; ``start()`` starts the model thread."""
        self.outputs = outputs
        self._clock_ns = clock_ns
        self._monotonic = monotonic
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue = collections.deque(maxlen=params.queue_size)
        self._busy = False          # the model thread owns the runner until it clears this
        self._stepping = False      # the input thread is stepping the model
        self._profiling = False     # the model thread is stepping a copy for a profile
        self._runner = runner
        self._assembler = assembler
        self._apply(params)
        self._dropped = 0
        self._shed = 0
        self._received = collections.Counter()
        self._published = 0
        self._inline = 0
        self._ff_held = 0
        self._latest = None
        self._latest_stamp = None
        self._last_groups = None
        self._notes = []            # one-off notes for the next status (a model rebuilt)
        now = monotonic()
        self._last_input = None     # monotonic time of the last nut_state received
        self._t_start = now
        # the status window: (monotonic time, model steps, shed, stalls, coarse, skipped)
        # at the last report, and the accepted samples' stamps since
        self._window = self._window_start(now)
        self._resets_logged = (0, -math.inf)      # (resets, monotonic) at the last warning
        self.ready = False
        self._stop = False
        self._thread = None
        # True when the caller's input thread calls flush() whenever it finds no input
        # waiting (ros_inputs.InputTaker): changed groups and a profile's hand-off then wait
        # for that, not delaying an input that arrived during a step (docs/node_latency.md)
        self.defer_to_idle = False
        self._deferred_groups = False
        self._init_profiles()

    def _apply(self, params):
        self._params = params
        self._max_age_ns = int(params.max_answer_age_s * 1e9)
        self._max_backlog_ns = int(min(params.max_backlog_s, params.max_answer_age_s) * 1e9)
        self._profile_shape = (params.profile_horizon_periods, params.profile_points)

    # --- life cycle -----------------------------------------------------------------------
    def start(self):
        """Start the model thread; the schedule is ready (model built and warm)."""
        self._thread = threading.Thread(target=self._model_loop, name="friction_model",
                                        daemon=True)
        self._thread.start()
        self.ready = True

    def stop(self, timeout_s=5.0):
        """Stop the model thread (a step in progress finishes first)."""
        with self._lock:
            self._stop = True
            self._wake.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)

    @property
    def runner(self):
        """Return the ModelRunner answering now (``apply`` replaces it on a rebuild)."""
        return self._runner

    @runner.setter
    def runner(self, runner):
        with self._lock:
            self._runner = runner

    def idle(self):
        """Return True when no input waits or is being stepped and no profile waits or runs."""
        with self._lock:
            return not (self._queue or self._busy or self._stepping or self._profiling
                        or self._profile_seed is not None or self.deferred)

    # --- inputs ---------------------------------------------------------------------------
    def on_nut_state(self, stamp_s, names, positions, velocities, recv_ns, stamp,
                     more_waiting=False):
        """
        Take one nut-state sample: answer it now, or queue it for the model thread.

        ``recv_ns``: when the middleware received it (``clock_ns`` time); ``stamp``: the
        header stamp as the publisher wants it back (the original goes out unchanged: float
        seconds lose ~0.2 us at epoch times).  ``more_waiting``: more nut_state inputs were
        already received after this one (the input thread's batch), given as the newest of
        them, (stamp_s, names, positions, velocities), or True if unknown.  A due step then
        goes to the model thread, which answers them in order and skips steps, only if the
        model is behind (``runner.due_between``: another step would be due by the newest);
        otherwise it is stepped here as when nothing waits.  A hand-off waits for a
        scheduler wake-up: with every due step handed off when two inputs came in one batch,
        those 1-2 % of the answers were half of the slowest 1 % at 1 kHz
        (docs/node_latency.md).
        """
        with self._lock:
            self._received["nut_state"] += 1
            self._last_input = self._monotonic()
            try:
                sample = self._assembler.on_nut_state(stamp_s, names, positions, velocities)
            except InputError as err:
                self._runner.reject(err.reason, nut_state=True)
                return
            w = self._window
            if w["first_stamp"] is None:
                w["first_stamp"] = sample.stamp_s
            w["last_stamp"] = sample.stamp_s
            w["accepted"] += 1
            runner = self._runner
            due = runner.step_due(sample)
            if self._busy or (due and more_waiting and self._backlog(recv_ns)
                              and self._behind(runner, sample, more_waiting)):
                # the model thread answers it, in order, after the step it waits for
                if len(self._queue) == self._queue.maxlen:
                    self._dropped += 1      # deque drops the oldest: the newest input wins
                self._queue.append((sample, recv_ns, stamp))
                self._busy = True
                self._wake.notify()
                return
            self._stepping = due        # a profile in progress gives way
        # The model thread idle (only this thread makes it busy), and no step due, or one
        # due with no other input waiting: step if due, answer at once.
        try:
            resets = runner.stats.resets
            pred = runner.process(sample)
        finally:
            self._stepping = False
        self._inline += 1
        # the answer first: the profile's seed and its hand-off wait (nothing steps the
        # runner before this thread's next input)
        self._finish(runner, pred, recv_ns, stamp, INLINE)
        stepped = pred is not None and pred.stepped
        settled = runner.pending
        if settled:
            # a step due at this input, after its answer (runner.step_after_answer_fraction):
            # in the gap before the next input instead of before this answer
            self._stepping = True
            try:
                stepped = self._settle(runner)
            finally:
                self._stepping = False
        if due:
            if runner.stats.resets != resets:
                self._reset_warning(runner.stats.resets, sample.stamp_s)
            if self._profile_wanted(runner, stepped, sample):
                # captured now (the next input may step the runner), handed over when idle;
                # after a step in this gap its first step waits for the next gap
                self._deferred_seed = (runner.profile_seed(sample), stamp,
                                       self._gaps + 1 if settled else self._gaps)
        if not (self.defer_to_idle and self.deferred):
            self.flush()        # nothing left to do for this input: the gap begins

    def _backlog(self, recv_ns):
        """Whether an input received at ``recv_ns`` has waited longer than max_backlog_s."""
        return self._clock_ns() - recv_ns > self._max_backlog_ns

    def _behind(self, runner, sample, newest):
        """
        Whether a step at ``sample`` would leave another due at ``newest``, a waiting input.

        ``newest``: (stamp_s, names, positions, velocities), or True when not known (then
        assumed behind).  A newest input the assembler refuses tells nothing: behind.
        """
        if newest is True:
            return True
        try:
            later = self._assembler.on_nut_state(*newest)
        except InputError:          # counted when it is taken, not here
            return True
        return runner.due_between(sample, later)

    def on_axial_load(self, force_z_n):
        """Take one axial load [N] (held until the next)."""
        with self._lock:
            self._received["axial_load"] += 1
            try:
                self._assembler.on_axial_load(force_z_n)
            except InputError as err:
                self._runner.reject(err.reason)

    def _finish(self, runner, pred, recv_ns, stamp, thread):
        """Publish the answer to one sample unless it is too old; count either."""
        if pred is None:        # counted by the runner as model_error
            self._log_model_error(runner)
            return
        age_ns = self._clock_ns() - recv_ns
        if age_ns > self._max_age_ns:
            with self._lock:
                self._shed += 1
            return
        self.outputs.answer(pred, stamp, 1e-9 * age_ns, thread)
        with self._lock:
            self._published += 1
            self._ff_held += pred.feedforward_held
            self._latest = pred
            self._latest_stamp = stamp
            changed = pred.groups is not self._last_groups and pred.groups != self._last_groups
        if changed and thread == INLINE and self.defer_to_idle:
            self._deferred_groups = True            # published by flush()
        elif changed:
            self.publish_groups()

    def publish_groups(self):
        """Hand the latest contact groups to ``Outputs.groups`` (also the node's timer)."""
        with self._lock:
            pred, stamp = self._latest, self._latest_stamp
            if pred is None:
                return
            self._last_groups = pred.groups
        self.outputs.groups(pred, stamp)

    # --- model thread ---------------------------------------------------------------------
    def _model_loop(self):
        while True:
            with self._lock:
                while not self._queue and not self._stop:
                    if self._profile_seed is not None:
                        break
                    self._busy = False
                    self._wake.wait(timeout=IDLE_WAIT_S)
                if self._stop:
                    return
                if not self._queue:
                    # queue drained, a profile to compute: inputs are answered inline
                    # meanwhile; a step falling due abandons the profile
                    seed, self._profile_seed = self._profile_seed, None
                    self._busy = False
                    self._profiling = True
                    item = None
                else:
                    item = self._queue.popleft()
                    newest = self._queue[-1][0] if self._queue else None
                    runner = self._runner
            if item is None:
                try:
                    self._publish_profile(seed)
                finally:
                    self._profiling = False
                continue
            sample, recv_ns, stamp = item
            # Behind: a step due now would be followed at once by another for an input
            # already waiting (the schedule's own terms: angle, direction, time floor), and
            # this input has waited longer than max_backlog_s.  The step is then left to the
            # newest sample (the model tracks the present, not its backlog).  Without the
            # age any input waiting behind a due step counted: at 20 rev/s, where every
            # 1 kHz input is due four 1.8 deg steps, one input arriving while the one before
            # it stepped skipped a step and doubled the schedule (for 2 s per halving), and
            # the cold first step at start did the same at 1 rev/s.  (The test before the
            # angle test, a queue spanning a model period, let the queue grow to 10 ms at
            # 20 rev/s and shed 25 % of the answers.)
            behind = newest is not None and self._backlog(recv_ns) \
                and runner.due_between(sample, newest)
            resets = runner.stats.resets
            pred = runner.process(sample, allow_step=not behind)
            self._finish(runner, pred, recv_ns, stamp, MODEL)
            stepped = self._settle(runner) or (pred is not None and pred.stepped)
            if runner.stats.resets != resets:
                self._reset_warning(runner.stats.resets, sample.stamp_s)
            if self._profile_wanted(runner, stepped, sample):
                self._profile_seed = (runner.profile_seed(sample), stamp, self._gaps)

    def _settle(self, runner):
        """Take the step left to follow an answer (``runner.settle``); log one that fails."""
        stepped = runner.settle()
        if stepped is None:     # counted by the runner as model_error
            self._log_model_error(runner)
        return bool(stepped)

    # --- parameters -----------------------------------------------------------------------
    def apply(self, params, runner=None):
        """
        Take changed parameters (validated by the caller); ``runner``: a rebuilt model.

        Counters go on across a model swap (diagnostics stay cumulative, the rate window
        keeps its base); the same empirical terms keep their clock and filter.
        """
        with self._lock:
            if runner is not None:
                if not runner.continue_from(self._runner) and runner.terms is not None:
                    self._notes.append("empirical terms restarted (model rebuilt)")
                self._runner = runner
            self._assembler.nut_joint = params.nut_joint
            self._assembler.max_axial_load_n = params.max_axial_load_n
            self._apply(params)


def process_cpu_s():
    """
    CPU seconds this process has used (all threads): its start-up cost without the wait.

    On a shared machine the wall time to "ready" measures the other processes as well; the
    CPU time is what the start-up itself costs.
    """
    t = os.times()
    return t.user + t.system


def process_age_s():
    """Seconds since this process started (Linux /proc), or None elsewhere: start-up time."""
    try:
        with open("/proc/self/stat") as fh:
            start_ticks = int(fh.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as fh:
            uptime_s = float(fh.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")
