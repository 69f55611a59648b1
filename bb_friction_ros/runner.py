"""
Input validation and the model runner shared by the live node and bag replay.

The node and ``bb-friction replay`` both feed samples, in order, to one ``ModelRunner``: the
same validation, the same model-step schedule (driven by header stamps, never by wall time)
and the same prediction rule.  Given the same accepted samples they give the same output,
which is what makes replay a faithful stand-in for the live node.

Schedule: the whole-screw model steps when the input stamps have advanced by at least one
model period (``1 / model_rate_hz``) since its last step, or at once when the direction of
the nut motion changes (start, stop, reversal); it then advances the ball azimuths by the
measured nut rotation since that step.  Every nut-state sample gets a prediction from
the latest model state (zero-order hold; its age is reported), so the output keeps the input
rate while the model runs at its own rate.

Feedforward policy (a step that did not converge): the prediction keeps the model's raw
numbers with ``converged = False``, but ``feedforward_nm``, the value meant for a controller,
holds the torque of the last converged step while the nut keeps moving in that step's
direction, and is 0 N m otherwise (after a reversal, at standstill, or before any converged
step): an unconverged solve can swing by tens of N m, and the old direction's friction after
a reversal would push the axis the wrong way.  ``feedforward_held`` says the value is held.

Look-ahead (``look_ahead_profile``): after a step, a copy of the model state is stepped ahead
along the extrapolated motion (same velocity and load) to give the torque at a row of angles
ahead of the input; a controller interpolates in it (``feedforward.FeedforwardInterpolator``).
"""

from collections import Counter
import copy
from dataclasses import dataclass, field
import math
import time

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import BBFrictionError
from bb_friction_ros.model_file import load_model_file, NoPhysics, physics_of


# Stamps are compared as float seconds: at epoch times (~1.7e9 s) their resolution is ~0.24 us,
# so five 2 ms intervals may sum to 9.9999998 ms.  Without this slack a 100 Hz model stepped
# every 12 ms on 500 Hz input (measured: 84 Hz in bench/bench_node.py).
STAMP_RESOLUTION_S = 1e-6


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


def _sign(x):
    """Sign of a float as -1.0, 0.0 or 1.0 (np.sign costs ~1 us per scalar call)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


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
    resets: int = 0
    rejected: Counter = field(default_factory=Counter)   # by reason, inputs of both topics
    rejected_nut_state: int = 0     # nut-state samples never answered (in ``rejected`` too)
    last_step_wall_s: float = 0.0
    last_error: str = ""            # of the last model step that raised


class ModelRunner:
    """
    Drive a whole-screw model from a stream of input samples (see module docstring).

    ``screw`` must provide ``reset(nut_angle_rad)`` and
    ``step(nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s)`` returning a result with
    ``torque_total_nm``, ``torque_b2g_nm``, ``torque_b2b_nm``, ``converged``, ``groups`` and
    ``n_balls``.
    """

    def __init__(self, screw, model_rate_hz, terms=None):
        """
        Wrap ``screw``; it steps at most once per 1/model_rate_hz of input time.

        ``terms`` (an empirical_terms.TermSet, optional) adds fitted empirical torque, evaluated
        at every sample's own inputs; its time is the stamp since the run's first sample.
        """
        if not model_rate_hz > 0:
            raise ValueError(f"model_rate_hz must be > 0, got {model_rate_hz}")
        self.screw = screw
        self.terms = terms
        # stateful per-sample evaluation: the inertia term's causal acceleration filter
        self._live_terms = terms.live() if terms is not None else None
        self._first_stamp = None
        self.period_s = 1.0 / model_rate_hz
        self.stats = RunnerStats()
        self._last_stamp = None
        self._model_stamp = None
        self._model_direction = 0.0
        self._state = None
        self._held = None           # (torque, direction) of the last converged step

    def reset(self):
        """Forget the model state; the next sample starts a new run."""
        self._first_stamp = None
        self._last_stamp = None
        self._model_stamp = None
        self._state = None
        if self._live_terms is not None:
            self._live_terms.reset()
        self._held = None

    def step_due(self, sample):
        """
        Return True if ``process(sample)`` would step the model (or reset it).

        Cheap; the live node answers samples with no step due at once, in its executor.
        """
        if self._state is None or self._last_stamp is None \
                or sample.stamp_s < self._last_stamp:
            return True
        return (sample.stamp_s - self._model_stamp >= self.period_s - STAMP_RESOLUTION_S
                or _sign(sample.nut_velocity_rad_s) != self._model_direction)

    def warm_up(self, axial_load_n, nut_velocity_rad_s):
        """
        Run one reset and step, then forget them (``stats`` untouched).

        Pays compilation and first-solve costs before inputs arrive, so a live node's
        first input is not late; node and replay both do it (identical state after).
        """
        self.screw.reset(0.0)
        self.screw.step(0.0, nut_velocity_rad_s, axial_load_n, 0.0)
        self.reset()

    def reject(self, reason, nut_state=False):
        """Count an input rejected before it reached the runner (``nut_state``: a sample)."""
        self.stats.rejected[reason] += 1
        self.stats.rejected_nut_state += bool(nut_state)

    def process(self, sample, allow_step=True):
        """
        Advance the model if a step is due and return the Prediction for ``sample``.

        With ``allow_step=False`` (the live node catching up on a backlog: only the newest
        input may step the model) the sample is answered from the current state, and a
        step it would have triggered is counted in ``stats.skipped_steps``.

        A model step that raises must stop neither the node nor replay, and both must then
        agree: the sample gets no prediction (None), it is counted as rejected
        ``model_error`` (message in ``stats.last_error``) and the state is reset.
        """
        try:
            return self._process(sample, allow_step)
        except Exception as exc:   # any failure of the physics: counted, never fatal
            self.reject("model_error", nut_state=True)
            self.stats.last_error = repr(exc)
            self.reset()
            return None

    def _process(self, sample, allow_step):
        if self._last_stamp is not None and sample.stamp_s < self._last_stamp:
            # A bag loop or a restarted source: the balls' history no longer applies.
            self.stats.resets += 1
            self.reset()
        self.stats.samples += 1
        self._last_stamp = sample.stamp_s
        stepped = False
        if self._state is None:
            self._first_stamp = sample.stamp_s
            self.screw.reset(sample.nut_angle_rad)
            self._state = self._step(sample, 0.0)
            self._model_stamp = sample.stamp_s
            self._model_direction = _sign(sample.nut_velocity_rad_s)
            stepped = True
        elif (sample.stamp_s - self._model_stamp >= self.period_s - STAMP_RESOLUTION_S
              or _sign(sample.nut_velocity_rad_s) != self._model_direction):
            # A reversal (or a start/stop) is due at once: Coulomb friction flips there, and
            # a held torque of the old sign is the worst feed-forward a controller can get.
            if allow_step:
                self._state = self._step(sample, sample.stamp_s - self._model_stamp)
                self._model_stamp = sample.stamp_s
                self._model_direction = _sign(sample.nut_velocity_rad_s)
                stepped = True
            else:
                self.stats.skipped_steps += 1
        st = self._state
        extra = 0.0
        if self._live_terms is not None:
            extra = self._live_terms.torque_nm(
                sample.stamp_s, sample.stamp_s - self._first_stamp, sample.nut_angle_rad,
                sample.nut_velocity_rad_s, sample.axial_load_n)
        total = st.torque_total_nm + extra
        if stepped:
            self._update_held(total, sample.nut_velocity_rad_s)
        converged = self._state_converged
        if converged:
            ff, held = total, False
        else:
            ff, held = 0.0, True
            if self._held is not None \
                    and self._held[1] == _sign(sample.nut_velocity_rad_s) != 0.0:
                ff = self._held[0]
        return Prediction(sample.stamp_s, sample.nut_angle_rad, sample.nut_velocity_rad_s,
                          sample.axial_load_n, total, st.torque_b2g_nm,
                          st.torque_b2b_nm, extra, converged,
                          sample.stamp_s - self._model_stamp, self._state_groups,
                          self._state_n_balls, stepped, ff, held)

    def _step(self, sample, dt_s):
        t0 = time.perf_counter()
        res = self.screw.step(sample.nut_angle_rad, sample.nut_velocity_rad_s,
                              sample.axial_load_n, dt_s)
        self.stats.last_step_wall_s = time.perf_counter() - t0
        # answered from for every input until the next step: convert once, here
        self._state_groups = _groups(res.groups)
        self._state_n_balls = int(np.size(res.azimuth_rad))
        self._state_converged = bool(res.converged)
        self.stats.model_steps += 1
        if not res.converged:
            self.stats.nonconverged_steps += 1
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

    def profile_seed(self, sample):
        """
        Capture what ``look_ahead_profile`` needs right after ``sample`` stepped the model.

        The screw is copied shallowly: a step rebinds its state arrays and never writes
        into them, so stepping the copy leaves this runner's model untouched (tested).
        """
        accel = None if self._live_terms is None else self._live_terms.last_accel_rad_s2
        return ProfileSeed(copy.copy(self.screw), sample, self._state.torque_total_nm,
                           self._state_converged, self.period_s, self.terms,
                           sample.stamp_s - self._first_stamp, accel)


@dataclass(frozen=True)
class ProfileSeed:
    """A model state right after a step, to be stepped ahead by ``look_ahead_profile``."""

    screw: object
    sample: InputSample
    torque_total_nm: float      # the step's own torque (model only, no empirical terms)
    converged: bool
    period_s: float
    terms: object
    run_time_s: float           # stamp since the run's first sample (empirical terms' time)
    # the inertia term's causal acceleration at the sample, held over the horizon (the
    # extrapolated velocity is constant, but the filter's alpha is the best guess of the
    # inertia torque for the next few ms); None without an inertia term
    nut_accel_rad_s2: object = None


def look_ahead_profile(seed, horizon_periods=2.0, n_points=3, should_stop=None):
    """
    Predicted friction torque ahead of a model step, at constant velocity and load.

    Points: the step's own angle psi_0 (its torque equals the prediction there), then
    ``n_points - 1`` angles evenly spaced up to psi_0 + sign(omega) * |omega| * horizon,
    horizon = ``horizon_periods`` model periods of motion; a copy of the model is stepped to
    each in turn.  At standstill (omega = 0) the profile is the single point psi_0.
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

    angles = [s.nut_angle_rad]
    torques = [seed.torque_total_nm + extra(0.0, s.nut_angle_rad)]
    converged = seed.converged
    if w == 0.0 or n_points < 2:
        return angles, torques, converged
    screw = seed.screw
    dt = horizon_periods * seed.period_s / (n_points - 1)
    for i in range(1, n_points):
        if should_stop is not None and should_stop():
            return None
        angle = s.nut_angle_rad + w * dt * i
        res = screw.step(angle, w, s.axial_load_n, dt)
        angles.append(angle)
        torques.append(res.torque_total_nm + extra(dt * i, angle))
        converged = converged and bool(res.converged)
    return angles, torques, converged


class InputAssembler:
    """
    Turn the two input streams into InputSamples, exactly as the node receives them.

    Axial-load messages update the held load; each nut-state message becomes a sample with
    the load held at that moment (arrival order, as ``ros2 bag play`` reproduces it).
    Raises InputError with a counted reason for anything unusable.
    """

    def __init__(self, nut_joint, max_axial_load_n):
        """Validate nut-state messages against ``nut_joint`` and loads against the limit."""
        self.nut_joint = nut_joint
        self.max_axial_load_n = max_axial_load_n
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

    def on_nut_state(self, stamp_s, names, positions, velocities):
        """Return the InputSample of a nut-state message."""
        if not math.isfinite(stamp_s):
            raise InputError("non_finite", f"stamp {stamp_s}")
        angle, velocity = joint_state_sample(names, positions, velocities, self.nut_joint)
        if self.load_n is None:
            raise InputError("no_load_yet", "no valid axial_load received yet")
        return InputSample(stamp_s, angle, velocity, self.load_n)


def build_runner(config_path, model_rate_hz):
    """
    Build a ModelRunner around the whole-screw model of a model file.

    Its ``empirical_terms`` (``augmented.yaml`` of the discrepancy workflow) add their fitted
    torque to every prediction.
    """
    cfg, terms = load_model_file(config_path)
    # physics: none (a discrepancy --baseline zero model): the terms are the whole torque
    screw = NoPhysics() if physics_of(config_path) == "none" else WholeScrew(cfg)
    runner = ModelRunner(screw, model_rate_hz, terms if len(terms) else None)
    runner.warm_up(cfg.operation.axial_load_n, cfg.operation.nut_velocity_rad_s)
    return runner


def _groups(groups):
    """Convert groups to hashable tuples ((ball ids), (forces N)) for change detection."""
    return tuple((tuple(int(i) for i in ids), tuple(float(f) for f in forces))
                 for ids, forces in groups)
