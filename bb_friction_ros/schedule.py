"""
The runner's schedule: when the model steps, and which stamps are late or restart a run.

One source for the rules ``runner.ModelRunner`` follows, live and offline alike, and for
the late-stamp policy the analysis of a recording (``alignment``, ``run_starts``) shares
with it.  ``Schedule.plan`` is the decision: for the schedule's state and one sample, what
happens (``Plan``: a new run, late, no step, a step before or after the answer and its
sub-steps, or a step skipped); it changes nothing.  The runner carries the plan out and
tells the schedule what it did (``stepped``, ``substepped``, ``coarsen``, ``late``,
``answered``), and the live node reads the same rules (``due_between``).
"""

from dataclasses import dataclass
import math

import numpy as np

# Stamps are compared as float seconds: at epoch times (~1.7e9 s) their resolution is ~0.24 us,
# so five 2 ms intervals may sum to 9.9999998 ms.  Without this slack a 100 Hz model stepped
# every 12 ms on 500 Hz input (measured: 84 Hz in bench/bench_node.py).
STAMP_RESOLUTION_S = 1e-6
# Nut angles are compared as float radians too: a step of exactly model_step_deg computed as
# w * t may come out a few ulp short of it; 1e-9 rad is far below any encoder's resolution.
ANGLE_RESOLUTION_RAD = 1e-9
# A schedule made coarser because the live model fell behind returns to half that step after
# a calm (input time with no step skipped) of RELAX_MIN_S first: most falls are transients
# (the first, cold step at start; the machine taking the CPU away for a few ms), and each
# halving after a fixed 2 s kept 1.8 deg steps away for up to 6 s after one of them at
# 20 rev/s (docs/model_schedule.md).  A fall within RELAX_MAX_S of a halving (the finer step
# did not hold) doubles the calm, up to RELAX_MAX_S, so a node that cannot keep the fine step
# soon retries it only once per RELAX_MAX_S, each try costing a backlog of max_backlog_s; a
# fall later than that starts again from RELAX_MIN_S.  Counted in input time, not steps: at
# 4000 steps/s a count of steps would retry 20x a second.
RELAX_MIN_S = 0.25
RELAX_MAX_S = 2.0
# Weight of the newest step in the running mean of step wall times that prices a look-ahead
# profile (``profile_fits``): the cold first step (about 3.7 ms, 20-40 warm steps) moves it
# by a fraction, a trend moves it within some 10 steps.
STEP_TIME_WEIGHT = 0.1
# Sub-steps between two input samples at most: more is a jump of the angle (a gap in the
# input or an encoder glitch), crossed in this many coarser steps rather than a burst of CPU.
MAX_SUBSTEPS = 64
# A stamp that goes back by at most LATE_STAMP_TOLERANCE_S is a late sample (jitter, a
# delayed driver thread) if its stream is past its old newest stamp again within
# LATE_SAMPLES_MAX more samples; late samples are aligned by their stamps in the same run.
# If the stream carries on below for longer, or goes back by more, it restarted (a looping
# bag, a restarted source) and a new run begins; unless the newest stamp had jumped ahead
# by more than the tolerance and the stream carries on past its stamp before that jump: that
# one stamp was far ahead (a driver's glitch) and the run goes on.  Late samples seen in
# practice are one sample a few ms late (10.5 ms in a measured recording); a restart goes
# on below its old newest stamp for the length of a recording.
LATE_STAMP_TOLERANCE_S = 0.1
LATE_SAMPLES_MAX = 3


def _sign(x):
    """Sign of a float as -1.0, 0.0 or 1.0 (np.sign costs ~1 us per scalar call)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


# What a sample makes the runner do (``Plan.action``)
FIRST = "first"     # no model state: reset the balls at the sample and step there
RESET = "reset"     # stamps went back further than a late sample: a new run (then FIRST)
LATE = "late"       # a late sample: answered from the current state, no step, no reset
HOLD = "hold"       # no step due: answered from the current state (zero-order hold)
BEFORE = "before"   # a step due, taken (with its sub-steps) before the answer
AFTER = "after"     # a step due, taken after the answer (``ModelRunner.settle``)
SKIP = "skip"       # a step due that the live node cannot take now: coarser schedule
STEPPING = frozenset({FIRST, RESET, BEFORE, AFTER, SKIP})   # a step (or a reset) is due


@dataclass(frozen=True)
class Plan:
    """What happens at one sample: the action and, for a step, its model steps."""

    action: str
    steps: int = 1              # model steps to reach the sample (the sub-steps and its own)
    long_jump: bool = False     # more were due than MAX_SUBSTEPS: crossed in MAX_SUBSTEPS


_PLANS = {a: Plan(a) for a in (FIRST, RESET, LATE, HOLD, SKIP)}
# The plans of steps, one instance per value (frozen): at 20 rev/s every input steps, and a
# frozen dataclass's __init__ cost ~0.4 us each time
_STEP_PLANS = {}


def _step_plan(action, steps, long_jump):
    """Return ``Plan(action, steps, long_jump)``, the instance shared by that value."""
    key = (action, steps, long_jump)
    plan = _STEP_PLANS.get(key)
    if plan is None:
        plan = _STEP_PLANS[key] = Plan(action, steps, long_jump)
    return plan


class Schedule:
    """
    The state the schedule decides on, and its rules (``plan``; module docstring).

    ``stamp``, ``angle``, ``velocity``, ``load``, ``direction``: the last model step's
    sample (the reference of the angle schedule and the time floor; ``stamp`` None: no model
    state); ``last_stamp``, ``last_angle``: the last sample on time; ``scale``: the step and
    the time floor now, a power of two of the configured ones (coarser when behind).
    """

    def __init__(self, model_rate_hz, model_step_deg, max_model_step_deg,
                 step_after_answer_fraction):
        """Take validated settings (``ModelRunner``): rate [Hz], steps [deg], fraction."""
        self.period_s = 1.0 / model_rate_hz
        self.step_rad = math.radians(model_step_deg)
        # coarsening when behind: the step and the time floor are multiplied by a power of
        # two, at most max_model_step_deg / model_step_deg
        self.max_scale = max_model_step_deg / model_step_deg
        self.scale = 1.0
        self._calm_since = None     # input stamp of the last skip, or of the last halving
        self._relaxed_at = None     # input stamp of the last halving
        self._relax_s = RELAX_MIN_S     # the calm the next halving waits for
        self._coarsened = False     # the scale went up since the last step
        self._after_answer_rad = self.step_rad * step_after_answer_fraction
        self.stamp = None
        self.angle = self.velocity = self.load = self.direction = 0.0
        self.last_stamp = None
        self.last_angle = None
        self.late_run = 0           # consecutive late samples (``_is_late``)

    def reset(self):
        """Forget the run: the next sample starts a new one (the scale is kept)."""
        self.stamp = self.last_stamp = self.last_angle = None
        self.late_run = 0

    # --- the decision -----------------------------------------------------------------
    def plan(self, sample, allow_step=True):
        """
        Return the Plan for ``sample``: what the runner does with it (changes nothing).

        ``allow_step`` False (the live node catching up on a backlog): a due step is SKIP.
        """
        last = self.last_stamp
        if last is not None and sample.stamp_s < last:
            if self.stamp is not None and self._is_late(sample):
                return _PLANS[LATE]
            return _PLANS[RESET]
        if self.stamp is None:
            return _PLANS[FIRST]
        # A reversal (or a start/stop) is due at once: Coulomb friction flips there, and
        # a held torque of the old sign is the worst feed-forward a controller can get.
        if not self._due(sample.stamp_s, sample.nut_angle_rad, sample.nut_velocity_rad_s,
                         sample.axial_load_n):
            return _PLANS[HOLD]
        if not allow_step:
            return _PLANS[SKIP]
        steps, long_jump = self._steps_to(sample)
        return _step_plan(AFTER if self._after_answer(sample) else BEFORE, steps, long_jump)

    def holds(self, stamp_s, angle_rad, velocity_rad_s, load_n):
        """
        Return True if ``plan`` would answer this sample from the current state (HOLD).

        ``plan``'s decision for a sample given as numbers, without building it: a held
        sample is most of a stream (every input between two steps), and replay answers it
        through ``ModelRunner.process_scalars``.  False for every other plan.
        """
        last = self.last_stamp
        return last is not None and self.stamp is not None and stamp_s >= last \
            and not self._due(stamp_s, angle_rad, velocity_rad_s, load_n)

    def _due_after(self, direction, angle_rad, stamp_s, velocity_next, angle_next,
                   stamp_next):
        """
        Return True if a step is due at the next sample after one at (direction, angle, stamp).

        A change of direction, ``model_step_deg`` of rotation or the time floor, at the
        current scale.  One test for the model state (``_due``) and between two waiting
        inputs (``due_between``).
        """
        return _sign(velocity_next) != direction \
            or abs(angle_next - angle_rad) >= self.step_rad * self.scale - ANGLE_RESOLUTION_RAD \
            or stamp_next - stamp_s >= self.period_s * self.scale - STAMP_RESOLUTION_S

    def _due(self, stamp_s, angle_rad, velocity_rad_s, load_n):
        """Whether a step is due for a sample (a state exists, stamps not backwards)."""
        if self._due_after(self.direction, self.angle, self.stamp, velocity_rad_s, angle_rad,
                           stamp_s):
            return True
        # Stamps that do not advance leave the time floor no time: a load change then steps
        # at once, so a state of another load is never answered as fresh.
        return stamp_s == self.last_stamp and load_n != self.load

    def due_between(self, sample, later):
        """Return True if a step at ``sample`` would leave one due again at ``later``."""
        return self._due_after(_sign(sample.nut_velocity_rad_s), sample.nut_angle_rad,
                               sample.stamp_s, later.nut_velocity_rad_s, later.nut_angle_rad,
                               later.stamp_s)

    def _is_late(self, sample):
        """
        Whether ``sample``, stamped before the newest, is a late sample rather than a restart.

        The rule of ``LATE_STAMP_TOLERANCE_S`` without its look-ahead: back by at most the
        tolerance, and at most ``LATE_SAMPLES_MAX`` such samples in a row; more, or further
        back, is a restart (a bag loop, a restarted source).  A single sample 10.5 ms late
        used to reset the balls' history and move every later prediction (up to 0.14 N m on
        the demo bag).
        """
        back = self.last_stamp - sample.stamp_s
        return 0.0 < back <= LATE_STAMP_TOLERANCE_S and self.late_run < LATE_SAMPLES_MAX

    def _after_answer(self, sample):
        """
        Whether the step due at ``sample`` may follow its answer (``step_after_answer_fraction``).

        Only a step of the angle schedule or the time floor with the nut turning on in the
        state's direction (a reversal, a start or a stop steps first: the held torque would
        have the old sign) and stamps advancing (a load change on stalled stamps steps at
        once), and only when the sample is at most that fraction of a step past the one before
        it: the answer then comes from a state that much older in nut angle at most.
        """
        return (self._after_answer_rad > 0.0 and self.last_angle is not None
                and sample.stamp_s != self.last_stamp
                and _sign(sample.nut_velocity_rad_s) == self.direction != 0.0
                and abs(sample.nut_angle_rad - self.last_angle)
                <= self._after_answer_rad * self.scale)

    def _steps_to(self, sample):
        """
        Return (model steps from the last step to ``sample``, more than MAX_SUBSTEPS due).

        Input samples may be further apart than the model step (at 20 rev/s, 1 kHz input
        is 7.2 deg per sample): the model then steps along the straight line between the two
        inputs, one model step apart, so its step size is the schedule's, not the input
        rate's.  Not across a change of direction: the path between two samples of opposite
        directions is unknown (the reversal steps at once).  A jump of the angle (a gap in
        the input, an encoder glitch) is not motion the schedule can follow step by step:
        crossed in MAX_SUBSTEPS coarser steps.
        """
        if _sign(sample.nut_velocity_rad_s) != self.direction or self.direction == 0.0:
            return 1, False
        turned = abs(sample.nut_angle_rad - self.angle)
        n = math.ceil(turned / (self.step_rad * self.scale) - ANGLE_RESOLUTION_RAD)
        if n <= 1:
            return 1, False
        if n > MAX_SUBSTEPS:
            return MAX_SUBSTEPS, True
        return n, False

    # --- what the runner did ----------------------------------------------------------
    def late(self):
        """Count a late sample answered (``LATE``)."""
        self.late_run += 1

    def answered(self, sample):
        """Make ``sample``, answered on time, the last sample (after ``plan``'s action)."""
        self.last_stamp = sample.stamp_s
        self.last_angle = sample.nut_angle_rad

    def stepped(self, sample):
        """
        Make the model step at ``sample`` the schedule's reference; return True if coarse.

        Kept up for a while at a coarser scale (a calm of ``_relax_s`` input time): the
        finer step is tried again.
        """
        self.stamp = sample.stamp_s
        self.angle = sample.nut_angle_rad
        self.velocity = sample.nut_velocity_rad_s
        self.load = sample.axial_load_n
        self.direction = _sign(sample.nut_velocity_rad_s)
        coarse = self.scale > 1.0
        if coarse and sample.stamp_s - self._calm_since >= self._relax_s:
            self.scale = max(1.0, self.scale / 2.0)
            self._calm_since = self._relaxed_at = sample.stamp_s
        self._coarsened = False
        return coarse

    def coarsen(self, stamp_s):
        """
        Double the step (once per step taken, up to max): the live model fell behind.

        Returns True if the scale went up.
        """
        self._calm_since = stamp_s
        if self._coarsened or self.scale >= self.max_scale:
            return False
        since = None if self._relaxed_at is None else stamp_s - self._relaxed_at
        if since is not None and 0.0 <= since < RELAX_MAX_S:
            self._relax_s = min(2.0 * self._relax_s, RELAX_MAX_S)   # the finer step failed
        else:
            self._relax_s = RELAX_MIN_S                             # a new fall
        self.scale = min(2.0 * self.scale, self.max_scale)
        self._coarsened = True
        return True


def run_starts(stamps_s):
    """
    Return (starts, late): where the runner starts a run, and which samples it takes as late.

    The runner's own rule (``ModelRunner._is_late``), for the stamps of the nut-state samples
    it answers, in order: a stamp back by at most ``LATE_STAMP_TOLERANCE_S``, at most
    ``LATE_SAMPLES_MAX`` in a row, is late (answered, no reset); any other backward stamp
    restarts.  The analysis of a recording cuts its runs here, so that one late stamp does
    not restart its clock where the runner carried on.
    """
    t = np.asarray(stamps_s, dtype=float)
    starts = np.zeros(t.size, dtype=bool)
    late = np.zeros(t.size, dtype=bool)
    if t.size == 0:
        return starts, late
    starts[0] = True
    if np.all(np.diff(t) >= 0.0):
        return starts, late
    last, run = t[0], 0
    for i in range(1, t.size):
        back = last - t[i]
        if back > 0.0:
            if back <= LATE_STAMP_TOLERANCE_S and run < LATE_SAMPLES_MAX:
                late[i] = True
                run += 1
                continue
            starts[i] = True
        run = 0
        last = t[i]
    return starts, late
