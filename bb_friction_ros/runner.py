"""
Input validation and the model runner shared by the live node and bag replay.

The node and ``bb-friction replay`` both feed samples, in order, to one ``ModelRunner``: the
same validation, the same model-step schedule (driven by the nut angle and the header
stamps, never by wall time) and the same prediction rule.  Given the same accepted samples
they give the same output, which is what makes replay a faithful stand-in for the live node.

Schedule: the whole-screw model is quasi-static, its balls follow the nut angle,
so it steps by nut rotation: when the nut has turned ``model_step_deg`` since the last step,
at once when the direction of the nut motion changes (start, stop, reversal), and, as a
floor when the nut creeps or stands, when the input stamps have advanced by one model period
(``1 / model_rate_hz``).  A step advances the ball azimuths by the measured nut rotation since
the last one; when the inputs are further apart than the step (1 kHz input at 20 rev/s is
7.2 deg per sample), the model steps along the line between the two samples, so its step
size is the schedule's, not the input rate's (``stats.substeps``).  Stamps that do not
advance (a driver leaving ``header.stamp`` at 0) leave the floor no time: they are counted
(``stats.stamp_stalls``), and a change of the axial load then steps at once.  Every
nut-state sample gets a prediction from the latest model state (zero-order hold; its age in
input time is reported), so the output keeps the input rate while the model steps at its own.

Answer first, then step (``step_after_answer_fraction``, default 0.5): when the inputs are
dense against the step (at 1 rev/s a 1 kHz input is 0.36 deg, a fifth of the 1.8 deg step), a
step due at a sample at most that fraction of a step past the one before is taken *after*
the sample is answered, from the state before it (``settle``; ``process`` takes a pending
step first).  The answer is then at most that fraction of a step older in nut angle, and the
live node answers every such input without a step in the way: the step runs in the gap
before the next input (docs/node_latency.md).  Reversals, starts, stops and load changes on
stalled stamps step first as before, and so do sparse inputs (5 rev/s and faster at 1 kHz,
where one input is a step or more: answering from the state before would lag a whole step,
docs/model_schedule.md).  Replay follows the same rule, so live = replay stays exact.

Falling behind (the live node only: replay always steps): a sample that cannot step
(``process(sample, allow_step=False)``) is answered from the current state, and the schedule
turns coarser, the step and the floor doubled (up to ``max_model_step_deg``), rather than
building a backlog; after a calm of input time with none skipped it halves again (0.25 s at
first, doubled up to 2 s while the finer step keeps failing: ``RELAX_MIN_S``, ``RELAX_MAX_S``).
Steps taken coarser are counted (``stats.coarse_steps``); only then do live and replay differ.

Feedforward policy (a step that did not converge): the prediction keeps the model's raw
numbers with ``converged = False``, but ``feedforward_nm``, the value meant for a controller,
holds the torque of the last converged step while the nut keeps moving in that step's
direction, and is 0 N m otherwise (after a reversal, at standstill, or before any converged
step): an unconverged solve can swing by tens of N m, and the old direction's friction after
a reversal would push the axis the wrong way.  ``feedforward_held`` says the value is held.
The same rule covers a converged state: a sample that stands still, or that moves against
the direction of the state answering it (a reversal whose step was skipped because the live
model fell behind), gets 0 N m, counted in ``stats.feedforward_zeroed``.

Look-ahead (``look_ahead_profile``): after a step, a copy of the model state is stepped ahead
along the extrapolated motion (same velocity and load) to give the torque at a row of nut
angles ahead of the input, spaced in angle; a controller interpolates in it
(``feedforward.FeedforwardInterpolator``).
"""

from collections import Counter
import copy
from dataclasses import dataclass, field, fields
import math
import time

import numpy as np

from bb_friction_ros.bags import LATE_SAMPLES_MAX, LATE_STAMP_TOLERANCE_S
from bb_friction_ros.ball_screw.arrangement import mean_b2b
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import BBFrictionError, ConfigError
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.model_file import load_model_file, NoPhysics, physics_of
from bb_friction_ros.node_parameters import B2B_AVERAGED, B2B_FEEDFORWARDS, B2B_MODEL


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
# FrictionPrediction.arrangement: which B2B torque the feedforward carries (the .msg's
# constants; an arrangement locked by an observer would be 2)
ARRANGEMENT_MODEL, ARRANGEMENT_AVERAGED = 0, 1
# Sub-steps between two input samples at most: more is a jump of the angle (a gap in the
# input or an encoder glitch), crossed in this many coarser steps rather than a burst of CPU.
MAX_SUBSTEPS = 64


@dataclass(frozen=True)
class InputSample:
    """One nut-state sample with the axial load held at its stamp (SI units)."""

    stamp_s: float
    nut_angle_rad: float
    nut_velocity_rad_s: float
    axial_load_n: float


@dataclass(frozen=True)
class Prediction:
    """Predicted friction torque for one input sample (friction only: no load torque)."""

    stamp_s: float
    nut_angle_rad: float
    nut_velocity_rad_s: float
    axial_load_n: float
    torque_total_nm: float
    torque_b2g_nm: float
    torque_b2b_nm: float
    torque_empirical_nm: float  # fitted terms (discrepancy workflow); 0 without them
    converged: bool
    model_age_s: float          # input time since the model state used was computed
    groups: tuple               # ((ball ids rear first), (b2b forces N)) per contact group
    n_balls: int
    stepped: bool               # this sample triggered a model step
    feedforward_nm: float = 0.0     # safe value for a controller (module docstring)
    feedforward_held: bool = False  # feedforward_nm is held from the last converged step
    # the state's own torque (physics + the sample's terms), for diagnostics: the torques
    # above are 0 N m when the state belongs to the other direction (state_other_direction)
    torque_state_nm: float = 0.0
    state_other_direction: bool = False
    # which B2B torque feedforward_nm carries: ARRANGEMENT_MODEL (the state's own) or
    # ARRANGEMENT_AVERAGED (the mean over arrangements); the confidence of a locked one
    arrangement: int = 0
    arrangement_confidence: float = 0.0


# A Prediction is built for every input sample; the frozen dataclass's __init__ sets each of
# its 19 fields through object.__setattr__: 1.9 us of the ~6 us the runner spends on a sample
# answered from the held state (measured in replay at 1 rev/s).  ``_prediction`` fills the same
# instance dict in one update (0.8 us): an equal, equally frozen and hashable Prediction.
_PREDICTION_FIELDS = tuple(f.name for f in fields(Prediction))
_new_object = object.__new__


def _prediction(*values):
    """Return ``Prediction(*values)`` (all 19 fields, positional), built without __init__."""
    pred = _new_object(Prediction)
    pred.__dict__.update(zip(_PREDICTION_FIELDS, values))
    return pred


def _sign(x):
    """Sign of a float as -1.0, 0.0 or 1.0 (np.sign costs ~1 us per scalar call)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


def interrupted(exc):
    """
    Tell whether ``exc`` is a Ctrl-C that compiled code turned into another exception.

    A KeyboardInterrupt raised while numba's code runs comes out as a ``SystemError`` ("returned
    a result with an exception set") chained to it.  Counted as a model error, the run went on
    and exited 0 with spurious resets; it must stop the run instead.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


class InputError(BBFrictionError):
    """An input message is rejected; ``reason`` is a short key counted in diagnostics."""

    def __init__(self, reason, detail):
        """Keep the counted reason key and the human-readable detail."""
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def joint_state_sample(names, positions, velocities, joint):
    """
    Return (angle, velocity) of ``joint`` from JointState arrays, or raise InputError.

    Reasons: ``empty``, ``wrong_joint``, ``missing_velocity``, ``non_finite``.
    """
    if len(names) == 0 or len(positions) == 0:
        raise InputError("empty", "JointState has no joints")
    try:
        i = list(names).index(joint)
    except ValueError:
        raise InputError("wrong_joint", f"no joint named {joint!r} (got {list(names)})")
    if i >= len(positions):
        raise InputError("empty", f"joint {joint!r} has no position")
    if i >= len(velocities):
        raise InputError("missing_velocity", f"joint {joint!r} has no velocity")
    angle, velocity = float(positions[i]), float(velocities[i])
    if not (math.isfinite(angle) and math.isfinite(velocity)):
        raise InputError("non_finite", f"position {angle}, velocity {velocity}")
    return angle, velocity


def axial_load_value(force_z_n, max_axial_load_n):
    """
    Return the axial load [N] from WrenchStamped force.z, or raise InputError.

    The sign is kept (it says which flank carries the load); magnitudes above
    ``max_axial_load_n`` are rejected as ``absurd_load``.
    """
    value = float(force_z_n)
    if not math.isfinite(value):
        raise InputError("non_finite", f"force.z = {value}")
    if abs(value) > max_axial_load_n:
        raise InputError("absurd_load", f"|force.z| = {abs(value):.6g} N exceeds "
                         f"max_axial_load_n = {max_axial_load_n:.6g} N")
    return value


@dataclass
class RunnerStats:
    """Counters reported in diagnostics."""

    samples: int = 0
    model_steps: int = 0
    nonconverged_steps: int = 0
    skipped_steps: int = 0
    # answers whose converged torque was not fed forward (0 N m instead): the sample stands
    # still or moves against the state's direction (a reversal whose step was skipped)
    feedforward_zeroed: int = 0
    coarse_steps: int = 0           # steps taken at a coarser schedule (live model behind)
    coarsenings: int = 0            # times the schedule was made coarser
    stamp_stalls: int = 0           # samples whose stamp equals the previous sample's
    term_restarts: int = 0          # empirical terms' clock and filter restarted mid-stream
    substeps: int = 0               # model steps between two input samples (in model_steps)
    long_jumps: int = 0             # angle jumps crossed in MAX_SUBSTEPS coarser steps
    resets: int = 0
    # samples stamped a little before the newest (jitter, a delayed driver thread; the rule of
    # bags.LATE_STAMP_TOLERANCE_S): answered from the current state, neither stepping nor
    # resetting it (one late sample used to reset the balls' history)
    late_samples: int = 0
    # answers whose friction (the state and the friction terms) opposed the motion, cut to 0:
    # a pre-rolling state right after a reversal
    friction_cut: int = 0
    rejected: Counter = field(default_factory=Counter)   # by reason, inputs of both topics
    rejected_nut_state: int = 0     # nut-state samples never answered (in ``rejected`` too)
    last_step_wall_s: float = 0.0
    last_error: str = ""            # of the last model step that raised


class ModelRunner:
    """
    Drive a whole-screw model from a stream of input samples (see module docstring).

    ``screw`` must provide ``reset(nut_angle_rad)`` and
    ``step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False)`` returning a
    result with ``torque_total_nm``, ``torque_b2g_nm``, ``torque_b2b_nm``, ``converged``,
    ``groups`` and ``azimuth_rad`` (one per ball: its size is the ball count); ``substep`` is
    True for a step between two samples, whose state is never answered.  A look-ahead
    profile steps a shallow copy of it (``profile_seed``).
    """

    def __init__(self, screw, model_rate_hz, terms=None, model_step_deg=None,
                 max_model_step_deg=None, step_after_answer_fraction=None, mean_b2b=None):
        """
        Wrap ``screw``, stepped by nut rotation with a time floor (module docstring).

        It steps every ``model_step_deg`` of nut rotation, at every change of direction, and
        at least once per 1/model_rate_hz of input time.  ``model_step_deg`` None: the node's
        default; ``max_model_step_deg`` (None: the node's default) bounds the coarser steps
        taken when the live model falls behind.  ``step_after_answer_fraction`` (None: the
        node's default; 0: never) lets a due step follow its sample's answer when that sample
        is at most this fraction of a step past the one before (module docstring).
        ``terms`` (an empirical_terms.TermSet, optional) adds fitted empirical torque, evaluated
        at every sample's own inputs; its time is the stamp since the run's first sample.
        ``mean_b2b`` (``ball_screw.arrangement.MeanB2B``, optional): the feedforward carries
        the B2B torque averaged over the balls' arrangements instead of the model state's own
        (the prediction keeps the state's); None: the state's.
        """
        from bb_friction_ros.node_parameters import NodeParameters
        defaults = NodeParameters()
        if model_step_deg is None:
            model_step_deg = defaults.model_step_deg
        if max_model_step_deg is None:
            max_model_step_deg = max(defaults.max_model_step_deg, model_step_deg)
        if step_after_answer_fraction is None:
            step_after_answer_fraction = defaults.step_after_answer_fraction
        if not 0.0 <= step_after_answer_fraction <= 1.0:
            raise ValueError(f"step_after_answer_fraction must be in [0, 1], got "
                             f"{step_after_answer_fraction}")
        if not model_rate_hz > 0:
            raise ValueError(f"model_rate_hz must be > 0, got {model_rate_hz}")
        if not 0.0 < model_step_deg <= max_model_step_deg:
            raise ValueError(f"model_step_deg must be > 0 and <= max_model_step_deg, got "
                             f"{model_step_deg} and {max_model_step_deg}")
        self.screw = screw
        self.terms = terms
        self.mean_b2b = mean_b2b
        self._arrangement = ARRANGEMENT_MODEL if mean_b2b is None else ARRANGEMENT_AVERAGED
        # stateful per-sample evaluation: the inertia term's causal acceleration filter
        self._live_terms = terms.live() if terms is not None else None
        self._first_stamp = None
        self.period_s = 1.0 / model_rate_hz
        self.step_rad = math.radians(model_step_deg)
        # coarsening when behind: the step and the time floor are multiplied by a power of
        # two, at most max_model_step_deg / model_step_deg
        self.max_scale = max_model_step_deg / model_step_deg
        self.scale = 1.0
        self._step_time_s = None    # running mean of the model steps' wall time [s]
        self._calm_since = None     # input stamp of the last skip, or of the last halving
        self._relaxed_at = None     # input stamp of the last halving
        self._relax_s = RELAX_MIN_S     # the calm the next halving waits for
        self._coarsened = False     # the scale went up since the last step
        self.stats = RunnerStats()
        self._last_stamp = None
        self._model_stamp = None
        self._model_angle = 0.0
        self._model_velocity = 0.0
        self._model_load = 0.0
        self._model_direction = 0.0
        self._state = None
        self._held = None           # (torque, direction) of the last converged step
        self._late_run = 0          # consecutive late samples (see _is_late)
        self._last_extra = 0.0      # empirical torque of the last sample on time
        self._last_friction = 0.0   # its friction terms' share (empirical_terms.NOT_FRICTION)
        self._last_angle = None     # nut angle of the last sample on time [rad]
        self._pending = None        # (sample, empirical torque): a step after its answer
        self._after_answer_rad = self.step_rad * step_after_answer_fraction

    def reset(self):
        """Forget the model state; the next sample starts a new run."""
        self._first_stamp = None
        self._last_stamp = None
        self._model_stamp = None
        self._state = None
        if self._live_terms is not None:
            self._live_terms.reset()
        self._held = None
        self._late_run = 0
        self._last_extra = self._last_friction = 0.0
        self._last_angle = None
        self._pending = None

    def continue_from(self, old):
        """
        Take over from ``old``, the runner this one replaces (a runtime parameter change).

        The counters go on (diagnostics stay cumulative).  With the same empirical terms the
        terms' run clock and acceleration filter carry over (a
        ``thermal_drift`` term would otherwise restart from 0); the model state itself does
        not (the next sample starts a new run of the balls).  Returns True if the terms'
        clock carried over; False (counted in ``stats.term_restarts`` when this runner has
        terms) if they restart.
        """
        self.stats = old.stats
        same = self.terms is not None and old.terms is not None \
            and self.terms.to_list() == old.terms.to_list()
        if same and old._first_stamp is not None:
            self._live_terms = old._live_terms
            self._first_stamp = old._first_stamp
            self._last_stamp = old._last_stamp
            return True
        if self.terms is not None and old._first_stamp is not None:
            self.stats.term_restarts += 1
        return False

    @property
    def model_step_rad(self):
        """Nut rotation between scheduled steps now [rad] (coarser when behind)."""
        return self.step_rad * self.scale

    def _due_after(self, direction, angle_rad, stamp_s, later):
        """
        Return True if a step is due at ``later`` after one at (direction, angle, stamp).

        A change of direction, ``model_step_deg`` of rotation or the time floor, at the
        current scale.  One test for the model state (``_due``) and between two waiting
        inputs (``due_between``).
        """
        return _sign(later.nut_velocity_rad_s) != direction \
            or abs(later.nut_angle_rad - angle_rad) \
            >= self.step_rad * self.scale - ANGLE_RESOLUTION_RAD \
            or later.stamp_s - stamp_s >= self.period_s * self.scale - STAMP_RESOLUTION_S

    def _due(self, sample):
        """Whether a step is due for ``sample`` (a state exists, stamps not backwards)."""
        if self._due_after(self._model_direction, self._model_angle, self._model_stamp,
                           sample):
            return True
        # Stamps that do not advance leave the time floor no time: a load change then steps
        # at once, so a state of another load is never answered as fresh.
        return sample.stamp_s == self._last_stamp \
            and sample.axial_load_n != self._model_load

    def due_between(self, sample, later):
        """
        Return True if a step at ``sample`` would leave one due again at ``later``.

        The live node uses it to tell that its model fell behind the inputs waiting for it.
        """
        return self._due_after(_sign(sample.nut_velocity_rad_s), sample.nut_angle_rad,
                               sample.stamp_s, later)

    def step_due(self, sample):
        """
        Return True if ``process(sample)`` would step the model (or reset it).

        Cheap; the live node answers samples with no step due at once, in its input thread.
        """
        if self._pending is not None:
            self.settle()
        if self._state is None or self._last_stamp is None:
            return True
        if sample.stamp_s < self._last_stamp:
            return not self._is_late(sample)
        return self._due(sample)

    def _is_late(self, sample):
        """
        Whether ``sample``, stamped before the newest, is a late sample rather than a restart.

        The rule of ``bags.LATE_STAMP_TOLERANCE_S`` without its look-ahead: back by at most
        the tolerance, and at most ``LATE_SAMPLES_MAX`` such samples in a row; more, or further
        back, is a restart (a bag loop, a restarted source).  A single sample 10.5 ms late
        used to reset the balls' history and move every later prediction (up to 0.14 N m on
        the demo bag).
        """
        back = self._last_stamp - sample.stamp_s
        return 0.0 < back <= LATE_STAMP_TOLERANCE_S and self._late_run < LATE_SAMPLES_MAX

    def warm_up(self, axial_load_n, nut_velocity_rad_s):
        """
        Run a reset, a cold step, a warm step and a path, then forget them (``stats`` kept).

        Pays compilation and first-solve costs before inputs arrive, so a live node's
        first input is not late; node and replay both do it (identical state after).  The
        warm step has compiled calls of its own (``kernel.warm_step``), which numba loads at
        their first call: 67 ms from its cache (measured), a compile takes seconds.  Without
        it the node said "ready" and then fell ~70 inputs behind at its first warm step.
        """
        self.screw.reset(0.0)
        self.screw.step(0.0, nut_velocity_rad_s, axial_load_n, 0.0)
        t0 = time.perf_counter()
        self.screw.step(math.copysign(self.step_rad, nut_velocity_rad_s), nut_velocity_rad_s,
                        axial_load_n, self.step_rad / max(abs(nut_velocity_rad_s), 1e-9))
        self._step_time_s = time.perf_counter() - t0   # a warm step prices the first profile
        if hasattr(self.screw, "step_path"):
            # the steps of an input in one call (kernel.warm_steps), loaded here too
            w = nut_velocity_rad_s
            a = math.copysign(self.step_rad, w)
            self.screw.step_path([2.0 * a, 3.0 * a], [w, w], [axial_load_n] * 2,
                                 self.step_rad / max(abs(w), 1e-9))
        self.reset()

    def reject(self, reason, nut_state=False):
        """Count an input rejected before it reached the runner (``nut_state``: a sample)."""
        self.stats.rejected[reason] += 1
        self.stats.rejected_nut_state += bool(nut_state)

    def process(self, sample, allow_step=True):
        """
        Advance the model if a step is due and return the Prediction for ``sample``.

        With ``allow_step=False`` (the live node catching up on a backlog: only the newest
        input may step the model) the sample is answered from the current state, a step it
        would have triggered is counted in ``stats.skipped_steps``, and the schedule turns
        coarser (``scale`` doubles, up to ``max_scale``; module docstring).

        A model step that raises must stop neither the node nor replay, and both must then
        agree: the sample gets no prediction (None), it is counted as rejected
        ``model_error`` (message in ``stats.last_error``) and the state is reset.
        """
        try:
            return self._process(sample, allow_step)
        except Exception as exc:   # any failure of the physics: counted, never fatal
            self._model_error(exc, nut_state=True)
            return None

    def _model_error(self, exc, nut_state):
        """Count a step that raised (``model_error``) and reset the state; Ctrl-C stops."""
        if interrupted(exc):
            raise KeyboardInterrupt from exc
        self.reject("model_error", nut_state=nut_state)
        self.stats.last_error = repr(exc)
        self.reset()

    @property
    def pending(self):
        """Whether a step due at the last sample waits to be taken after its answer."""
        return self._pending is not None

    def settle(self):
        """
        Take the step due at the last sample, answered before it (module docstring).

        The next ``process`` (or ``step_due``) takes it first anyway, so when it runs does
        not change any answer: the live node calls this right after publishing, in the gap
        before the next input; replay leaves it to the next sample.  Returns True if it
        stepped, False if no step was pending, None if the step raised: counted
        (``model_error``, the sample itself was answered) and the state reset, as in
        ``process``.
        """
        if self._pending is None:
            return False
        sample, extra = self._pending
        self._pending = None
        try:
            self._step_to(sample, extra)
        except Exception as exc:   # any failure of the physics: counted, never fatal
            self._model_error(exc, nut_state=False)     # the sample itself was answered
            return None
        return True

    def _after_answer(self, sample):
        """
        Whether the step due at ``sample`` may follow its answer (``step_after_answer_fraction``).

        Only a step of the angle schedule or the time floor with the nut turning on in the
        state's direction (a reversal, a start or a stop steps first: the held torque would
        have the old sign) and stamps advancing (a load change on stalled stamps steps at
        once), and only when the sample is at most that fraction of a step past the one before
        it: the answer then comes from a state that much older in nut angle at most.
        """
        return (self._after_answer_rad > 0.0 and self._last_angle is not None
                and sample.stamp_s != self._last_stamp
                and _sign(sample.nut_velocity_rad_s) == self._model_direction != 0.0
                and abs(sample.nut_angle_rad - self._last_angle)
                <= self._after_answer_rad * self.scale)

    def _process(self, sample, allow_step):
        if self._pending is not None:
            self.settle()
        if self._state is not None and self._last_stamp is not None \
                and sample.stamp_s < self._last_stamp and self._is_late(sample):
            return self._answer_late(sample)
        self._late_run = 0
        if self._last_stamp is not None and sample.stamp_s < self._last_stamp:
            # A bag loop or a restarted source: the balls' history no longer applies.
            self.stats.resets += 1
            if self._live_terms is not None:
                self.stats.term_restarts += 1
            self.reset()
        self.stats.samples += 1
        if sample.stamp_s == self._last_stamp:
            self.stats.stamp_stalls += 1
        stepped = False         # the first step of a run, taken
        step = after = False    # a due step: before the answer, or after it (``settle``)
        if self._state is None:
            if self._first_stamp is None:   # else kept from the runner this one replaced
                self._first_stamp = sample.stamp_s
            self.screw.reset(sample.nut_angle_rad)
            self._take_step(sample, 0.0)
            stepped = True
        elif self._due(sample):
            # A reversal (or a start/stop) is due at once: Coulomb friction flips there, and
            # a held torque of the old sign is the worst feed-forward a controller can get.
            if allow_step:
                after = self._after_answer(sample)
                step = not after
            else:
                self.stats.skipped_steps += 1
                self._coarsen(sample.stamp_s)
        self._last_stamp = sample.stamp_s
        extra = friction = 0.0
        if self._live_terms is not None:
            extra = self._live_terms.torque_nm(
                sample.stamp_s, sample.stamp_s - self._first_stamp, sample.nut_angle_rad,
                sample.nut_velocity_rad_s, sample.axial_load_n)
            friction = self._live_terms.last_friction_nm
        self._last_extra, self._last_friction = extra, friction
        self._last_angle = sample.nut_angle_rad
        if after:
            self._pending = (sample, extra)
        elif step:
            self._step_to(sample, extra)
        elif stepped:
            self._update_held(self._state_feedforward(extra, sample),
                              sample.nut_velocity_rad_s)
        return self._answer(sample, extra, stepped or step,
                            sample.stamp_s - self._model_stamp)

    def _step_to(self, sample, extra):
        """
        Step the model to ``sample`` (sub-steps first), the schedule's new reference.

        ``extra``: the empirical torque of the sample (its terms' one evaluation), part of the
        feedforward held after the step.
        """
        between = self._substeps_to(sample)
        self._take_step(sample, sample.stamp_s - self._model_stamp, between)
        self._update_held(self._state_feedforward(extra, sample), sample.nut_velocity_rad_s)

    def _state_feedforward(self, extra, sample):
        """Return the feedforward of the state just stepped at ``sample`` (held if needed)."""
        total, cut = self._with_terms(self._state.torque_total_nm, extra,
                                      sample.nut_velocity_rad_s)
        return self._feedforward(total, cut, extra, sample)

    def _feedforward(self, total, cut, extra, sample):
        """
        Return the feedforward of an answered ``total``: its physics averaged over arrangements.

        With ``mean_b2b`` the state's own torque of the physics is replaced by its mean over
        the balls' arrangements at the sample's load (ball-to-groove and B2B: the B2B forces
        change the balls' loads, so both carry the arrangement's ripple), plus the sample's
        terms ``extra``, under the same friction-sign rule; a friction cut to 0 stays 0.
        """
        if self.mean_b2b is None or cut:
            return total
        physics = self.mean_b2b.total_at(sample.axial_load_n, sample.nut_velocity_rad_s)
        return self._with_terms(physics, extra, sample.nut_velocity_rad_s)[0]

    def _with_terms(self, state_nm, extra, nut_velocity_rad_s):
        """
        Return (the state's torque plus the terms', True if its friction was cut to 0).

        The friction (the state's torque and the terms that are friction) never opposes the
        motion in an answer: a fitted pre-rolling state right after a reversal, or any term
        that overturns the physics, would make every topic that carries it push the axis
        along its motion.  Cut, it is 0 N m (the build-up of pre-rolling from 0); the terms
        that are not friction (inertia, offset, lead error, ripple) stay.
        """
        friction = state_nm + self._last_friction
        if friction * nut_velocity_rad_s < 0.0:
            return extra - self._last_friction, True
        return state_nm + extra, False

    def _answer_late(self, sample):
        """Answer a late sample (``_is_late``) from the current state: no step, no reset."""
        self._late_run += 1
        self.stats.samples += 1
        self.stats.late_samples += 1
        # The state is newer than the sample; its age is the distance between the two.  The
        # empirical terms keep their clock and filter (a backward stamp would restart the
        # acceleration filter): the late sample gets the last sample's empirical torque.
        return self._answer(sample, self._last_extra, False,
                            abs(sample.stamp_s - self._model_stamp))

    def _answer(self, sample, extra, stepped, model_age_s):
        """Return the Prediction for ``sample`` from the current state, with its feedforward."""
        st = self._state
        total = state_total = st.torque_total_nm + extra
        b2g, b2b = st.torque_b2g_nm, st.torque_b2b_nm
        converged = self._state_converged
        direction = _sign(sample.nut_velocity_rad_s)
        other = direction != 0.0 and direction != self._model_direction
        if direction == 0.0 or other:
            # A state of the other direction (a skipped reversal step) or a standing nut:
            # the state's Coulomb torque would push the axis the wrong way, or hold it.
            ff, held = 0.0, False
            if converged and total != 0.0:
                self.stats.feedforward_zeroed += 1
            if other:
                # No topic a controller may read carries that torque as if it were valid:
                # the prediction answers 0 N m, not converged, and says why; the state's
                # own torque stays in torque_state_nm for diagnostics.
                total = b2g = b2b = extra = 0.0
                converged = False
        elif converged:         # (an unconverged answer keeps its raw numbers, flagged)
            total, cut = self._with_terms(st.torque_total_nm, extra, direction)
            ff, held = self._feedforward(total, cut, extra, sample), False
            if cut:             # the parts still sum to the total
                self.stats.friction_cut += 1
                extra = total - b2g - b2b
        else:
            ff, held = 0.0, True
            if self._held is not None and self._held[1] == direction:
                ff = self._held[0]
        return _prediction(sample.stamp_s, sample.nut_angle_rad, sample.nut_velocity_rad_s,
                           sample.axial_load_n, total, b2g, b2b, extra, converged,
                           model_age_s, self._state_groups,
                           self._state_n_balls, stepped, ff, held, state_total, other,
                           self._arrangement, 0.0)

    def _substeps_to(self, sample):
        """
        Step through the angles between the last step and ``sample``, one model step apart.

        Input samples may be further apart than the model step (at 20 rev/s, 1 kHz input
        is 7.2 deg per sample): the model then steps along the straight line between the two
        inputs (angle, velocity, load and stamp linear in between), so its step size is the
        schedule's, not the input rate's.  Not across a change of direction: the path
        between two samples of opposite directions is unknown (the reversal steps at once).
        A model with ``step_path`` takes them with the sample's own step in one call: they
        are returned for ``_take_step``, else stepped here (and none returned).
        """
        if _sign(sample.nut_velocity_rad_s) != self._model_direction \
                or self._model_direction == 0.0:
            return ()
        turned = abs(sample.nut_angle_rad - self._model_angle)
        n = math.ceil(turned / (self.step_rad * self.scale) - ANGLE_RESOLUTION_RAD)
        if n <= 1:
            return ()
        if n > MAX_SUBSTEPS:
            # a jump of the angle (a gap in the input, an encoder glitch): not motion the
            # schedule can follow step by step; crossed in MAX_SUBSTEPS coarser steps
            self.stats.long_jumps += 1
            n = MAX_SUBSTEPS
        a0, w0, f0, t0 = (self._model_angle, self._model_velocity, self._model_load,
                          self._model_stamp)
        da = sample.nut_angle_rad - a0
        dw = sample.nut_velocity_rad_s - w0
        df = sample.axial_load_n - f0
        dt = sample.stamp_s - t0
        path = hasattr(self.screw, "step_path")
        points = []
        for i in range(1, n):
            r = i / n
            between = InputSample(t0 + r * dt, a0 + r * da, w0 + r * dw, f0 + r * df)
            if path:
                points.append(between)
            else:
                self._step(between, dt / n, answered=False)
            self.stats.substeps += 1
        self._model_stamp = t0 + (n - 1) / n * dt
        return points

    def _take_step(self, sample, dt_s, between=()):
        """Step the model to ``sample`` (through ``between`` first) and make it the reference."""
        self._state = self._step(sample, dt_s, between=between)
        self._model_stamp = sample.stamp_s
        self._model_angle = sample.nut_angle_rad
        self._model_velocity = sample.nut_velocity_rad_s
        self._model_load = sample.axial_load_n
        self._model_direction = _sign(sample.nut_velocity_rad_s)
        if self.scale > 1.0:
            self.stats.coarse_steps += 1
            if sample.stamp_s - self._calm_since >= self._relax_s:
                # kept up for a while at this scale: try the finer step again
                self.scale = max(1.0, self.scale / 2.0)
                self._calm_since = self._relaxed_at = sample.stamp_s
        self._coarsened = False

    def _coarsen(self, stamp_s):
        """Double the step (once per step taken, up to max): the live model fell behind."""
        self._calm_since = stamp_s
        if self._coarsened or self.scale >= self.max_scale:
            return
        since = None if self._relaxed_at is None else stamp_s - self._relaxed_at
        if since is not None and 0.0 <= since < RELAX_MAX_S:
            self._relax_s = min(2.0 * self._relax_s, RELAX_MAX_S)   # the finer step failed
        else:
            self._relax_s = RELAX_MIN_S                             # a new fall
        self.scale = min(2.0 * self.scale, self.max_scale)
        self._coarsened = True
        self.stats.coarsenings += 1

    def _step(self, sample, dt_s, answered=True, between=()):
        t0 = time.perf_counter()
        if between:
            # the sub-steps and this step in one call (WholeScrew.step_path); each step's
            # wall time is the call's share
            points = list(between) + [sample]
            res = self.screw.step_path([p.nut_angle_rad for p in points],
                                       [p.nut_velocity_rad_s for p in points],
                                       [p.axial_load_n for p in points], dt_s)
            self.stats.nonconverged_steps += res.substeps_not_converged
        else:
            points = (sample,)
            res = self.screw.step(sample.nut_angle_rad, sample.nut_velocity_rad_s,
                                  sample.axial_load_n, dt_s, substep=not answered)
        self.stats.last_step_wall_s = took = (time.perf_counter() - t0) / len(points)
        for _ in points:
            mean = self._step_time_s
            self._step_time_s = took if mean is None \
                else mean + STEP_TIME_WEIGHT * (took - mean)
        self.stats.model_steps += len(points)
        if not res.converged:
            self.stats.nonconverged_steps += 1
        if answered:    # a sub-step's state is never answered: nothing to convert
            # answered from for every input until the next step: convert once, here
            self._state_groups = _groups(res.groups)
            self._state_n_balls = int(np.size(res.azimuth_rad))
            self._state_converged = bool(res.converged)
        return res

    def _update_held(self, total_nm, nut_velocity_rad_s):
        """
        Keep the feedforward to hold after the step just taken (module docstring).

        ``total_nm`` is the step's own total: physics plus the terms at the step's inputs,
        evaluated once per sample (the inertia term's causal filter advances with each call).
        """
        if not self._state_converged:
            return
        w = nut_velocity_rad_s
        self._held = (total_nm, _sign(w)) if w != 0.0 else None

    def profile_fits(self, sample, horizon_periods, n_points):
        """
        Return True if a look-ahead profile from ``sample`` can end before the next step.

        Its model steps (``look_ahead_profile``: ``n_points - 1`` points, each reached in
        sub-steps of at most the coarsest step) at the steps' mean wall time, against the
        input time to the next step due at this velocity (a model step of rotation, or the
        time floor).  The live node gives way to every due step, so a profile that cannot end
        before it is abandoned: at 20 rev/s with 1 kHz inputs (a step due at every input,
        1 ms apart) a 144 deg profile is ten 14.4 deg steps, 1.5-4 ms, and every one started
        was abandoned, at 0.3-0.4 of a core (docs/model_schedule.md).
        """
        w = abs(sample.nut_velocity_rad_s)
        if w == 0.0 or n_points < 2:
            return True
        step = self.step_rad * self.scale       # as profile_seed gives them
        period = self.period_s * self.scale
        n_sub = _profile_substeps(_horizon_rad(w, period, step, horizon_periods), n_points,
                                  self.step_rad * self.max_scale)
        cost_s = (n_points - 1) * n_sub * (self._step_time_s or 0.0)
        return cost_s < min(step / w, period)

    def profile_seed(self, sample):
        """
        Capture what ``look_ahead_profile`` needs right after ``sample`` stepped the model.

        The screw is copied shallowly: a step rebinds its state arrays and never writes
        into them, so stepping the copy leaves this runner's model untouched (tested).
        """
        accel = None if self._live_terms is None else self._live_terms.last_accel_rad_s2
        return ProfileSeed(copy.copy(self.screw), sample, self._state.torque_total_nm,
                           self._state_converged, self.period_s * self.scale, self.terms,
                           sample.stamp_s - self._first_stamp, accel,
                           self.step_rad * self.scale, self.step_rad * self.max_scale,
                           self.mean_b2b, self._state.torque_b2b_nm)


@dataclass(frozen=True)
class ProfileSeed:
    """A model state right after a step, to be stepped ahead by ``look_ahead_profile``."""

    screw: object
    sample: InputSample
    torque_total_nm: float      # the step's own torque (model only, no empirical terms)
    converged: bool
    period_s: float             # the schedule's time floor [s]
    terms: object
    run_time_s: float           # stamp since the run's first sample (empirical terms' time)
    # the inertia term's causal acceleration at the sample, held over the horizon (the
    # extrapolated velocity is constant, but the filter's alpha is the best guess of the
    # inertia torque for the next few ms); None without an inertia term
    nut_accel_rad_s2: object = None
    step_rad: float = 0.0       # the schedule's nut rotation between steps [rad]
    # the largest step the copy takes between two points [rad] (max_model_step_deg): steps
    # are cheapest per degree there, and the live node can abandon a profile between them
    max_step_rad: float = math.inf
    mean_b2b: object = None     # the runner's: the profile's physics averaged too
    torque_b2b_nm: float = 0.0  # the step's own B2B torque


def profile_horizon_rad(seed, horizon_periods):
    """
    Nut rotation the look-ahead covers [rad]: ``horizon_periods`` model periods of motion.

    A model period is the time floor's (``period_s``, the look-ahead the profile had when
    the model stepped by the clock), or, when the nut creeps so slowly that it turns less
    than one model step in it, the model step: the profile never covers less than
    ``horizon_periods`` steps of the angle schedule.
    """
    return _horizon_rad(abs(seed.sample.nut_velocity_rad_s), seed.period_s, seed.step_rad,
                        horizon_periods)


def _horizon_rad(w_abs, period_s, step_rad, horizon_periods):
    return horizon_periods * max(w_abs * period_s, step_rad)


def _profile_substeps(horizon_rad, n_points, max_step_rad):
    """Model steps from one profile point to the next (each at most ``max_step_rad``)."""
    return max(1, math.ceil(horizon_rad / (n_points - 1) / max_step_rad - ANGLE_RESOLUTION_RAD))


def profile_due(last, sample):
    """
    Return True if a step at ``sample`` should start a new look-ahead profile.

    ``last`` is the ProfileSeed of the last profile published (None: none yet).  A profile
    covers ``profile_horizon_periods`` (at least 2) model periods of motion ahead, so one per
    model period keeps a controller covered a period ahead at all times: a new one is due
    when the nut has turned one period of motion (``profile_horizon_rad(last, 1)``: at
    least one model step) since the last, its stamps have advanced one model period (a load
    change), or the direction changed (start, stop, reversal: at once).  At every step, the
    old rule, a 20 rev/s motion asked for 500-4000 profiles/s of 5-20 ms each.
    """
    if last is None:
        return True
    prev = last.sample
    return _sign(sample.nut_velocity_rad_s) != _sign(prev.nut_velocity_rad_s) \
        or abs(sample.nut_angle_rad - prev.nut_angle_rad) \
        >= profile_horizon_rad(last, 1.0) - ANGLE_RESOLUTION_RAD \
        or not 0.0 <= sample.stamp_s - prev.stamp_s < last.period_s - STAMP_RESOLUTION_S


def look_ahead_profile(seed, horizon_periods=2.0, n_points=3, should_stop=None):
    """
    Predicted friction torque ahead of a model step, at constant velocity and load.

    Points, in the nut-angle domain: the step's own angle psi_0 (its torque equals the
    prediction there), then ``n_points - 1`` angles evenly spaced up to
    psi_0 + sign(omega) * ``profile_horizon_rad``; a copy of the model is stepped to each in
    turn (the time between points, for the empirical terms and the step, is the angle over
    |omega|).  Points further apart than ``seed.max_step_rad`` are reached in equal
    sub-steps no longer than it: at 20 rev/s two points are 72 deg apart, and one 72 deg step
    cost 28 ms per profile against 18 ms in 14.4 deg steps (load 7 on 2 cores,
    docs/model_schedule.md), and held the model thread all that time.
    At standstill (omega = 0) the profile is the single point psi_0.
    Returns (angles [rad], torques [N m], converged), or None if ``should_stop()`` became
    true between two steps (the live node gives way to a pending model step).
    """
    s = seed.sample
    w = s.nut_velocity_rad_s

    def extra(t_s, angle):
        if seed.terms is None:
            return 0.0
        return float(seed.terms.torque_nm(seed.run_time_s + t_s, angle, w, s.axial_load_n,
                                          seed.nut_accel_rad_s2))

    def physics(own_nm):
        """Return a point's torque of the physics: its own, or the mean over arrangements."""
        if seed.mean_b2b is None:
            return own_nm
        return seed.mean_b2b.total_at(s.axial_load_n, w)

    angles = [s.nut_angle_rad]
    torques = [physics(seed.torque_total_nm) + extra(0.0, s.nut_angle_rad)]
    converged = seed.converged
    if w == 0.0 or n_points < 2:
        return angles, torques, converged
    screw = seed.screw
    horizon = profile_horizon_rad(seed, horizon_periods)
    d_angle = math.copysign(horizon / (n_points - 1), w)
    dt = d_angle / w
    n_sub = _profile_substeps(horizon, n_points, seed.max_step_rad)
    path = hasattr(screw, "step_path")
    for i in range(1, n_points):
        if path:
            # a point's sub-steps and its answered step in one call (WholeScrew.step_path)
            if should_stop is not None and should_stop():
                return None
            points = [s.nut_angle_rad + d_angle * (i - 1 + j / n_sub)
                      for j in range(1, n_sub + 1)]
            res = screw.step_path(points, [w] * n_sub, [s.axial_load_n] * n_sub, dt / n_sub)
            converged = converged and bool(res.converged) and not res.substeps_not_converged
            angle = points[-1]
        for j in range(1, n_sub + 1) if not path else ():
            if should_stop is not None and should_stop():
                return None
            angle = s.nut_angle_rad + d_angle * (i - 1 + j / n_sub)
            # only each point's last sub-step is answered (published)
            res = screw.step(angle, w, s.axial_load_n, dt / n_sub, substep=j < n_sub)
            converged = converged and bool(res.converged)
        angles.append(angle)
        torques.append(physics(res.torque_total_nm) + extra(dt * i, angle))
    return angles, torques, converged


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


class InputAssembler:
    """
    Turn the two input streams into InputSamples, exactly as the node receives them.

    Axial-load messages update the held load; each nut-state message becomes a sample with
    the load held at that moment (arrival order, as ``ros2 bag play`` reproduces it).
    Raises InputError with a counted reason for anything unusable.
    """

    def __init__(self, nut_joint, max_axial_load_n):
        """Validate nut-state messages against ``nut_joint`` and loads against the limit."""
        self.load_n = None
        self._refused_load = None   # held load refused by a lowered limit: (load, limit)
        self.nut_joint = nut_joint
        self.max_axial_load_n = max_axial_load_n

    @property
    def max_axial_load_n(self):
        """Largest accepted |axial load| [N]."""
        return self._max_axial_load_n

    @max_axial_load_n.setter
    def max_axial_load_n(self, value):
        # A limit lowered at runtime applies to the load already held too: samples are
        # refused until a load within the new limit arrives.
        self._max_axial_load_n = value
        if self.load_n is not None and abs(self.load_n) > value:
            self._refused_load = (self.load_n, value)
            self.load_n = None

    @property
    def nut_joint(self):
        """Name of the nut joint in JointState messages (never empty)."""
        return self._nut_joint

    @nut_joint.setter
    def nut_joint(self, name):
        # an empty name matches no JointState entry: every input would be rejected
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"nut_joint must be a non-empty joint name, got {name!r}")
        self._nut_joint = name

    def on_axial_load(self, force_z_n):
        """Hold a new axial load [N]."""
        self.load_n = axial_load_value(force_z_n, self.max_axial_load_n)
        self._refused_load = None

    def on_nut_state(self, stamp_s, names, positions, velocities):
        """Return the InputSample of a nut-state message."""
        if not math.isfinite(stamp_s):
            raise InputError("non_finite", f"stamp {stamp_s}")
        angle, velocity = joint_state_sample(names, positions, velocities, self.nut_joint)
        if self.load_n is None:
            if self._refused_load is not None:
                load, limit = self._refused_load
                raise InputError("absurd_load", f"held |force.z| = {abs(load):.6g} N exceeds "
                                 f"max_axial_load_n = {limit:.6g} N (lowered while held); "
                                 "waiting for a new axial_load")
            raise InputError("no_load_yet", "no valid axial_load received yet")
        return InputSample(stamp_s, angle, velocity, self.load_n)


def load_checked_model(config_path):
    """
    Return (config, terms, screw model) of a model file whose friction has the right sign.

    Raises FrictionSignError (``check_friction_sign``) for one that follows the motion.
    """
    cfg, terms = load_model_file(config_path)
    # physics: none (a discrepancy --baseline zero model): the terms are the whole torque
    screw = NoPhysics() if physics_of(config_path) == "none" else WholeScrew(cfg)
    check_friction_sign(screw, terms, config_path, cfg.operation.axial_load_n,
                        cfg.operation.nut_velocity_rad_s)
    return cfg, terms, screw


def build_runner(config_path, model_rate_hz, model_step_deg=None, max_model_step_deg=None,
                 step_after_answer_fraction=None, b2b_feedforward=B2B_MODEL):
    """
    Build a ModelRunner around the whole-screw model of a model file.

    Its ``empirical_terms`` (``augmented.yaml`` of the discrepancy workflow) add their fitted
    torque to every prediction.  ``model_step_deg``/``max_model_step_deg`` None: the node's
    defaults (``node_parameters.NodeParameters``), and so is ``step_after_answer_fraction``.
    """
    cfg, terms, screw = load_checked_model(config_path)
    if b2b_feedforward not in B2B_FEEDFORWARDS:
        raise ValueError(f"b2b_feedforward must be one of {B2B_FEEDFORWARDS}, got "
                         f"{b2b_feedforward!r}")
    mean = None
    if b2b_feedforward == B2B_AVERAGED and not isinstance(screw, NoPhysics):
        mean = mean_b2b(cfg)
    runner = ModelRunner(screw, model_rate_hz, terms if len(terms) else None,
                         model_step_deg, max_model_step_deg, step_after_answer_fraction, mean)
    runner.warm_up(cfg.operation.axial_load_n, cfg.operation.nut_velocity_rad_s)
    return runner


# Loads at which a model's friction sign is checked, as multiples of its operating load: the
# physics and the load-dependent terms are close to linear in |W|, so the ends and the middle of
# twice the operating range find a term that overturns the physics there.
SIGN_CHECK_LOAD_FACTORS = (0.0, 1.0, 2.0)
# Points along a stroke_position term's fitted stroke (its polynomial is held beyond it).
SIGN_CHECK_STROKE_POINTS = 9
# Run time at which a thermal_drift term is taken as settled [s] (its exp(-t/tau) is 0).
SIGN_CHECK_SETTLED_S = 1e12


class FrictionSignError(ConfigError):
    """A model whose friction has the sign opposite to the nut velocity: it would push along."""


def friction_sign_violations(screw, terms, axial_load_n, nut_velocity_rad_s):
    """
    Return the states where a model's friction does not have the sign of the nut velocity.

    Friction is dissipated at the contacts: on the nut it acts against the motion, so in the
    model's convention (the torque the drive spends on it) it has the sign of the velocity.
    A model that gives the opposite sign would make every controller that feeds it forward
    push the axis along its motion.  The physics (a cold step of ``screw``) plus the terms
    that are friction (``empirical_terms.NOT_FRICTION`` left out) are evaluated in both
    directions at |W| = ``SIGN_CHECK_LOAD_FACTORS`` x ``axial_load_n``, at the start and after
    the warm-up of a ``thermal_drift`` term, and along a ``stroke_position`` term's stroke.
    Returns a list of (load N, velocity rad/s, friction N m), empty when the sign holds.
    """
    speed = abs(nut_velocity_rad_s) or 1.0
    if terms is not None:       # in steady motion a pre-rolling term is 0 (z = sign omega);
        # after a reversal the answers cut its friction at 0 (ModelRunner._with_terms)
        terms = TermSet(t for t in terms.terms if t.name != "pre_rolling")
    angles = [0.0]
    for t in (terms.terms if terms is not None else ()):
        if t.name == "stroke_position":
            p = t.params
            angles += list(p.center_rad + p.half_range_rad
                           * np.linspace(-1.0, 1.0, SIGN_CHECK_STROKE_POINTS))
    angles = np.array(angles)
    bad = []
    for factor in SIGN_CHECK_LOAD_FACTORS:
        load = factor * abs(axial_load_n)
        for w in (speed, -speed):
            sign = math.copysign(1.0, w)
            screw.reset(0.0)
            # friction x sign(velocity): >= 0 for a torque that dissipates
            along = sign * float(screw.step(0.0, w, load, 0.0).torque_total_nm)
            if terms is not None and len(terms):
                along = along + np.minimum(
                    sign * terms.friction_nm(0.0, angles, w, load),
                    sign * terms.friction_nm(SIGN_CHECK_SETTLED_S, angles, w, load)).min()
            if along < 0.0:
                bad.append((load, w, sign * float(along)))
    return bad


def check_friction_sign(screw, terms, config_path, axial_load_n, nut_velocity_rad_s):
    """
    Refuse a model whose friction follows the motion (``friction_sign_violations``).

    Raises FrictionSignError (a config error: the CLI exits 2, the node refuses to start)
    naming the file and the first state; a model fitted to a measured torque of the wrong
    sign (a motor current positive in the other direction) is the usual cause.
    """
    bad = friction_sign_violations(screw, terms, axial_load_n, nut_velocity_rad_s)
    if bad:
        load, w, torque = bad[0]
        raise FrictionSignError(
            f"{config_path}: its friction follows the motion (friction {torque:.4g} N m at nut "
            f"velocity {w:.4g} rad/s and |axial load| {load:.4g} N; {len(bad)} of "
            f"{2 * len(SIGN_CHECK_LOAD_FACTORS)} checked states): friction has the sign of the "
            "nut velocity, so a controller feeding this model forward would push the axis "
            "along its motion; was it fitted to a measured torque or motor current of the "
            "opposite sign convention?")


def _groups(groups):
    """Convert groups to hashable tuples ((ball ids), (forces N)) for change detection."""
    return tuple((tuple(int(i) for i in ids), tuple(float(f) for f in forces))
                 for ids, forces in groups)
