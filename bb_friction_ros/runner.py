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

from bb_friction_ros.ball_screw.arrangement import mean_b2b
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.friction_sign import (check_friction_sign,  # noqa: F401
                                           friction_sign_violations, FrictionSignError)
from bb_friction_ros.inputs import (axial_load_value, InputAssembler, InputError,  # noqa: F401
                                    InputSample, joint_state_sample)
from bb_friction_ros.look_ahead import (_horizon_rad, _profile_substeps,  # noqa: F401
                                        look_ahead_profile, profile_due, profile_fits,
                                        profile_horizon_rad, ProfileSeed)
from bb_friction_ros.model_file import load_model_file, NoPhysics, physics_of
from bb_friction_ros.node_parameters import (B2B_AVERAGED, B2B_FEEDFORWARDS, B2B_MODEL,
                                             NodeParameters)
from bb_friction_ros.schedule import (_sign, AFTER, ANGLE_RESOLUTION_RAD,  # noqa: F401
                                      BEFORE, FIRST, LATE, LATE_SAMPLES_MAX,
                                      LATE_STAMP_TOLERANCE_S, MAX_SUBSTEPS, RELAX_MAX_S,
                                      RELAX_MIN_S, RESET, run_starts, Schedule, SKIP,
                                      STAMP_RESOLUTION_S, STEP_TIME_WEIGHT, STEPPING)

# FrictionPrediction.arrangement: which B2B torque the feedforward carries (the .msg's
# constants; an arrangement locked by an observer would be 2)
ARRANGEMENT_MODEL, ARRANGEMENT_AVERAGED = 0, 1


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
PREDICTION_FIELDS = _PREDICTION_FIELDS = tuple(f.name for f in fields(Prediction))
_new_object = object.__new__


def _prediction(*values):
    """Return ``Prediction(*values)`` (all 19 fields, positional), built without __init__."""
    pred = _new_object(Prediction)
    pred.__dict__.update(zip(_PREDICTION_FIELDS, values))
    return pred


def prediction_values(pred):
    """Return ``pred``'s fields as a tuple in their order (``process_values``'s answer)."""
    return tuple(getattr(pred, name) for name in _PREDICTION_FIELDS)


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


class _Answers:
    """
    The answer side of ``ModelRunner``: what a sample is answered, and what is fed forward.

    The feedforward policy of the module docstring: a converged state's torque with the
    sample's terms, cut to 0 where the friction would oppose the motion, 0 N m against the
    state's direction or at standstill, the last converged torque held after a step that
    did not converge.
    """

    def process_scalars(self, stamp_s, angle_rad, velocity_rad_s, load_n):
        """
        Return ``process_values(InputSample(stamp_s, angle_rad, velocity_rad_s, load_n))``.

        A held sample (``Schedule.holds``) of a runner without empirical terms takes the
        last held answer of the same state and direction (with ``mean_b2b``: load and
        speed) with its own stamp, angle, velocity, load and age; the counters advance as
        that answer advanced them.  The sample object, the plan and the answer's branches
        were most of the runner's work per held input in replay.
        """
        s = self.schedule
        c = self._hold_cache
        # what a held answer depends on besides the state: its sign (the averaged B2B
        # torque also depends on the load and speed)
        key = _sign(velocity_rad_s) if self.mean_b2b is None \
            else (_sign(velocity_rad_s), load_n, velocity_rad_s)
        if c is not None and self._pending is None and self._live_terms is None \
                and c[0] is self._state and c[1] is self._state_groups \
                and c[2] is self._held and c[3] == s.direction and c[4] == key \
                and s.holds(stamp_s, angle_rad, velocity_rad_s, load_n):
            # what _process does for a HOLD without terms, the answer's fields cached
            stats = self.stats
            s.late_run = 0
            stats.samples += 1
            if stamp_s == s.last_stamp:
                stats.stamp_stalls += 1
            self._last_extra = self._last_friction = 0.0
            s.last_stamp, s.last_angle = stamp_s, angle_rad
            stats.feedforward_zeroed += c[7]
            stats.friction_cut += c[8]
            return (stamp_s, angle_rad, velocity_rad_s, load_n) + c[5] \
                + (stamp_s - s.stamp,) + c[6]
        stats = self.stats
        zeroed, cut = stats.feedforward_zeroed, stats.friction_cut
        late, skipped = stats.late_samples, stats.skipped_steps
        v = self.process_values(InputSample(stamp_s, angle_rad, velocity_rad_s, load_n))
        # a HOLD neither stepped, nor left a step pending, nor was late or skipped (asked
        # after: at 20 rev/s every input steps)
        if v is not None and not v[12] and self._pending is None \
                and self._live_terms is None and stats.late_samples == late \
                and stats.skipped_steps == skipped:
            self._hold_cache = (
                self._state, self._state_groups, self._held, s.direction, key,
                v[4:9], v[10:], stats.feedforward_zeroed - zeroed, stats.friction_cut - cut)
        return v

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
        key = (sample.axial_load_n, sample.nut_velocity_rad_s)
        if key != self._mean_at[0]:
            # a stepping sample asks twice (the held value, then its answer); at a steady
            # load and speed every sample asks the same: one table look-up each
            self._mean_at = (key, self.mean_b2b.total_at(*key))
        return self._with_terms(self._mean_at[1], extra, sample.nut_velocity_rad_s)[0]

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
        self.schedule.late()
        self.stats.samples += 1
        self.stats.late_samples += 1
        # The state is newer than the sample; its age is the distance between the two.  The
        # empirical terms keep their clock and filter (a backward stamp would restart the
        # acceleration filter): the late sample gets the last sample's empirical torque.
        return self._answer_values(sample, self._last_extra, False,
                                   abs(sample.stamp_s - self.schedule.stamp))

    def _answer_values(self, sample, extra, stepped, model_age_s):
        """Return ``_answer``'s Prediction as the tuple of its fields, in their order."""
        st = self._state
        total = state_total = st.torque_total_nm + extra
        b2g, b2b = st.torque_b2g_nm, st.torque_b2b_nm
        converged = self._state_converged
        direction = _sign(sample.nut_velocity_rad_s)
        other = direction != 0.0 and direction != self.schedule.direction
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
        return (sample.stamp_s, sample.nut_angle_rad, sample.nut_velocity_rad_s,
                sample.axial_load_n, total, b2g, b2b, extra, converged, model_age_s,
                self._state_groups, self._state_n_balls, stepped, ff, held, state_total, other,
                self._arrangement, 0.0)

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


class _Steps:
    """
    The stepping side of ``ModelRunner``: the screw stepped to a sample, sub-steps first.

    Every model step goes through ``_step`` (counted, timed, its state converted once for
    the answers); ``warm_up`` pays the first steps' costs before any input.
    """

    def warm_up(self, axial_load_n, nut_velocity_rad_s):
        """
        Run a reset, a cold step, a warm step and a path, then forget them (``stats`` kept).

        Pays compilation and first-solve costs before inputs arrive, so a live node's
        first input is not late; node and replay both do it (identical state after).  The
        warm step has compiled calls of its own (``kernel.warm_step``), which numba loads at
        their first call: 67 ms from its cache (measured), a compile takes seconds.  Without
        it the node said "ready" and then fell ~70 inputs behind at its first warm step.
        """
        step_rad = self.schedule.step_rad
        self.screw.reset(0.0)
        self.screw.step(0.0, nut_velocity_rad_s, axial_load_n, 0.0)
        t0 = time.perf_counter()
        self.screw.step(math.copysign(step_rad, nut_velocity_rad_s), nut_velocity_rad_s,
                        axial_load_n, step_rad / max(abs(nut_velocity_rad_s), 1e-9))
        self._step_time_s = time.perf_counter() - t0   # a warm step prices the first profile
        if hasattr(self.screw, "step_path"):
            # the steps of an input in one call (kernel.warm_steps), loaded here too
            w = nut_velocity_rad_s
            a = math.copysign(step_rad, w)
            self.screw.step_path([2.0 * a, 3.0 * a], [w, w], [axial_load_n] * 2,
                                 step_rad / max(abs(w), 1e-9))
        self.reset()

    def _step_to(self, sample, extra, plan):
        """
        Step the model to ``sample`` (the plan's sub-steps first), the schedule's reference.

        ``extra``: the empirical torque of the sample (its terms' one evaluation), part of the
        feedforward held after the step.
        """
        between = self._substeps_to(sample, plan)
        self._take_step(sample, sample.stamp_s - self.schedule.stamp, between)
        self._update_held(self._state_feedforward(extra, sample), sample.nut_velocity_rad_s)

    def _substeps_to(self, sample, plan):
        """
        Step along the line from the last step to ``sample``, in ``plan.steps`` equal steps.

        Angle, velocity, load and stamp linear in between (``Schedule._steps_to``); the last
        of them is the sample's own step (``_take_step``).  A model with ``step_path`` takes
        them with the sample's own step in one call: they are returned for ``_take_step``
        as (angles, velocities, loads), else stepped here (and none returned).
        """
        n = plan.steps
        if n <= 1:
            return ()
        if plan.long_jump:
            self.stats.long_jumps += 1
        s = self.schedule
        a0, w0, f0, t0 = s.angle, s.velocity, s.load, s.stamp
        da = sample.nut_angle_rad - a0
        dw = sample.nut_velocity_rad_s - w0
        df = sample.axial_load_n - f0
        dt = sample.stamp_s - t0
        if hasattr(self.screw, "step_path"):
            # the path's columns, as _step passes them (an InputSample per sub-step, or a
            # comprehension per column, was a cost per input at 20 rev/s)
            angles, velocities, loads = path = ([], [], [])
            for i in range(1, n):
                r = i / n
                angles.append(a0 + r * da)
                velocities.append(w0 + r * dw)
                loads.append(f0 + r * df)
            self.stats.substeps += n - 1
            s.stamp = t0 + (n - 1) / n * dt
            return path
        for i in range(1, n):
            r = i / n
            self._step(InputSample(t0 + r * dt, a0 + r * da, w0 + r * dw, f0 + r * df),
                       dt / n, answered=False)
            self.stats.substeps += 1
        s.stamp = t0 + (n - 1) / n * dt
        return ()

    def _take_step(self, sample, dt_s, between=()):
        """
        Step the model to ``sample`` (through ``between`` first) and make it the reference.

        ``between``: the sub-steps' (angles, velocities, loads) (``_substeps_to``), or ().
        """
        self._state = self._step(sample, dt_s, between=between)
        self.stats.coarse_steps += self.schedule.stepped(sample)

    def _step(self, sample, dt_s, answered=True, between=()):
        t0 = time.perf_counter()
        if between:
            # the sub-steps and this step in one call (WholeScrew.step_path); each step's
            # wall time is the call's share
            angles, velocities, loads = between
            res = self.screw.step_path(angles + [sample.nut_angle_rad],
                                       velocities + [sample.nut_velocity_rad_s],
                                       loads + [sample.axial_load_n], dt_s)
            self.stats.nonconverged_steps += res.substeps_not_converged
            points = len(angles) + 1
        else:
            points = 1
            res = self.screw.step(sample.nut_angle_rad, sample.nut_velocity_rad_s,
                                  sample.axial_load_n, dt_s, substep=not answered)
        self.stats.last_step_wall_s = took = (time.perf_counter() - t0) / points
        mean = self._step_time_s
        for _ in range(points):     # each step's share, in turn (in a local: a cost per step)
            mean = took if mean is None else mean + STEP_TIME_WEIGHT * (took - mean)
        self._step_time_s = mean
        self.stats.model_steps += points
        if not res.converged:
            self.stats.nonconverged_steps += 1
        if answered:    # a sub-step's state is never answered: nothing to convert
            # answered from for every input until the next step: convert once, here
            self._state_groups = _groups(res.groups)
            az = res.azimuth_rad
            # an array's own size: np.size's dispatch is a cost per step at 20 rev/s
            self._state_n_balls = az.size if type(az) is np.ndarray else int(np.size(az))
            self._state_converged = bool(res.converged)
        return res


class ModelRunner(_Answers, _Steps):
    """
    Drive a whole-screw model from a stream of input samples (see module docstring).

    ``screw`` must provide ``reset(nut_angle_rad)`` and
    ``step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False)`` returning a
    result with ``torque_total_nm``, ``torque_b2g_nm``, ``torque_b2b_nm``, ``converged``,
    ``groups`` and ``azimuth_rad`` (one per ball: its size is the ball count); ``substep`` is
    True for a step between two samples, whose state is never answered.  A look-ahead
    profile steps a shallow copy of it (``profile_seed``).  When to step is the
    ``schedule``'s decision (``schedule.Schedule.plan``); the runner carries it out.
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
        self._mean_at = (None, 0.0)     # (load, velocity) and mean_b2b's total there
        # stateful per-sample evaluation: the inertia term's causal acceleration filter
        self._live_terms = terms.live() if terms is not None else None
        self._first_stamp = None
        self.schedule = Schedule(model_rate_hz, model_step_deg, max_model_step_deg,
                                 step_after_answer_fraction)
        self._step_time_s = None    # running mean of the model steps' wall time [s]
        self.stats = RunnerStats()
        self._state = None
        self._held = None           # (torque, direction) of the last converged step
        self._last_extra = 0.0      # empirical torque of the last sample on time
        self._last_friction = 0.0   # its friction terms' share (empirical_terms.NOT_FRICTION)
        self._pending = None        # (sample, empirical torque, plan): a step after its answer
        # the last held answer and what it depends on (``process_scalars``)
        self._hold_cache = None

    # the schedule's settings and scale, as the live node and the tests read them
    period_s = property(lambda self: self.schedule.period_s)
    step_rad = property(lambda self: self.schedule.step_rad)
    max_scale = property(lambda self: self.schedule.max_scale)

    @property
    def scale(self):
        """Return the schedule's step and time floor now, as multiples of the configured."""
        return self.schedule.scale

    @scale.setter
    def scale(self, value):
        self.schedule.scale = value

    @property
    def model_step_rad(self):
        """Nut rotation between scheduled steps now [rad] (coarser when behind)."""
        return self.schedule.step_rad * self.schedule.scale

    def reset(self):
        """Forget the model state; the next sample starts a new run."""
        self._first_stamp = None
        self.schedule.reset()
        self._state = None
        if self._live_terms is not None:
            self._live_terms.reset()
        self._held = None
        self._last_extra = self._last_friction = 0.0
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
            self.schedule.last_stamp = old.schedule.last_stamp
            return True
        if self.terms is not None and old._first_stamp is not None:
            self.stats.term_restarts += 1
        return False

    def due_between(self, sample, later):
        """
        Return True if a step at ``sample`` would leave one due again at ``later``.

        The live node uses it to tell that its model fell behind the inputs waiting for it.
        """
        return self.schedule.due_between(sample, later)

    def step_due(self, sample):
        """
        Return True if ``process(sample)`` would step the model (or reset it).

        Cheap; the live node answers samples with no step due at once, in its input thread.
        """
        if self._pending is not None:
            self.settle()
        return self.schedule.plan(sample).action in STEPPING

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
        v = self.process_values(sample, allow_step)
        return None if v is None else _prediction(*v)

    def process_values(self, sample, allow_step=True):
        """
        Return ``process(sample, allow_step)``'s Prediction as the tuple of its fields.

        In ``Prediction``'s field order (``PREDICTION_FIELDS``), or None as ``process``.
        Replay writes each answer's numbers and never keeps the answer: building the frozen
        Prediction was a tenth of its work apart from the model (profiled at 1 rev/s).
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

    @property
    def state(self):
        """Return the latest model step's result (the screw's own torque), or None."""
        return self._state

    def probe(self):
        """
        Return a copy that answers a what-if sample and leaves this runner as it is.

        Shallow but for what processing changes in place: the schedule, the counters (fresh)
        and the terms' live state; the screw's step rebinds its arrays (``profile_seed``).
        """
        probe = copy.copy(self)
        probe.screw = copy.copy(self.screw)
        probe.schedule = copy.copy(self.schedule)
        probe._live_terms = copy.deepcopy(self._live_terms)
        probe.stats = RunnerStats()
        return probe

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
        sample, extra, plan = self._pending
        self._pending = None
        try:
            self._step_to(sample, extra, plan)
        except Exception as exc:   # any failure of the physics: counted, never fatal
            self._model_error(exc, nut_state=False)     # the sample itself was answered
            return None
        return True

    def _process(self, sample, allow_step):
        if self._pending is not None:
            self.settle()
        schedule, stats = self.schedule, self.stats
        plan = schedule.plan(sample, allow_step)
        action = plan.action
        if action is LATE:
            return self._answer_late(sample)
        schedule.late_run = 0
        if action is RESET:
            # A bag loop or a restarted source: the balls' history no longer applies.
            stats.resets += 1
            if self._live_terms is not None:
                stats.term_restarts += 1
            self.reset()
        stats.samples += 1
        if sample.stamp_s == schedule.last_stamp:
            stats.stamp_stalls += 1
        stepped = action is FIRST or action is RESET    # the first step of a run, taken
        if stepped:
            if self._first_stamp is None:   # else kept from the runner this one replaced
                self._first_stamp = sample.stamp_s
            self.screw.reset(sample.nut_angle_rad)
            self._take_step(sample, 0.0)
        elif action is SKIP:
            stats.skipped_steps += 1
            stats.coarsenings += schedule.coarsen(sample.stamp_s)
        extra = friction = 0.0
        if self._live_terms is not None:
            extra = self._live_terms.torque_nm(
                sample.stamp_s, sample.stamp_s - self._first_stamp, sample.nut_angle_rad,
                sample.nut_velocity_rad_s, sample.axial_load_n)
            friction = self._live_terms.last_friction_nm
        self._last_extra, self._last_friction = extra, friction
        schedule.answered(sample)
        if action is AFTER:
            self._pending = (sample, extra, plan)
        elif action is BEFORE:
            self._step_to(sample, extra, plan)
        elif stepped:
            self._update_held(self._state_feedforward(extra, sample),
                              sample.nut_velocity_rad_s)
        return self._answer_values(sample, extra, stepped or action is BEFORE,
                                   sample.stamp_s - schedule.stamp)

    def profile_fits(self, sample, horizon_periods, n_points):
        """Return True if a look-ahead profile from ``sample`` can end before the next step."""
        return profile_fits(self.schedule, self._step_time_s, sample, horizon_periods,
                            n_points)

    def profile_seed(self, sample):
        """
        Capture what ``look_ahead_profile`` needs right after ``sample`` stepped the model.

        The screw is copied shallowly: a step rebinds its state arrays and never writes
        into them, so stepping the copy leaves this runner's model untouched (tested).
        """
        s = self.schedule
        accel = None if self._live_terms is None else self._live_terms.last_accel_rad_s2
        return ProfileSeed(copy.copy(self.screw), sample, self._state.torque_total_nm,
                           self._state_converged, s.period_s * s.scale, self.terms,
                           sample.stamp_s - self._first_stamp, accel,
                           s.step_rad * s.scale, s.step_rad * s.max_scale,
                           self.mean_b2b)


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


def _groups(groups):
    """Convert groups to hashable tuples ((ball ids), (forces N)) for change detection."""
    # WholeScrew's are (ids, forces) tuples of Python ints and floats: taken as they are
    for g in groups:
        if type(g) is not tuple or len(g) != 2 or type(g[0]) is not tuple \
                or type(g[1]) is not tuple:
            return tuple([(ids if type(ids) is tuple else tuple(int(i) for i in ids),
                           forces if type(forces) is tuple else tuple(float(f) for f in forces))
                          for ids, forces in groups])
    return tuple(groups)
