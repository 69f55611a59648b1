"""
The friction feedforwards under test, one object per mode, and the safety gate around them.

Timing: a ``measured`` mode answers the measured state (the encoder's angle, the loop's
velocity estimate), as the node does; a ``commanded`` mode answers the reference (its
angle and velocity), as a planner-side feedforward would.

=============================  ===============================================================
mode                           feedforward
=============================  ===============================================================
none                           0
coulomb_viscous[_commanded]    c omega + T_c sign(omega), fitted (baselines.CoulombViscous)
lugre[_commanded]              LuGre fitted on the same data (baselines.LuGre)
model[_commanded]              the product's model, as the node answers (its safe
                               ``feedforward_nm``: 0 at standstill and against the state)
truth                          the plant's own friction at the measured state: the floor of a
                               measured-state feedforward
node                           the real friction_node over DDS (servo.node_mode)
planned                        ``bb-friction feedforward`` of the reference (planned.py): the
                               model stepped along the commanded angle, breakaway before a
                               planned start, pre-rolling from the plan; played back by time
node_planned                   ``planned`` through the real node: the reference sent as a
                               JointTrajectory (servo.node_mode)
=============================  ===============================================================

Safety gate (every mode): a feedforward whose sign is not its own motion's direction (the
velocity it answered), or that is not 0 at its own standstill, would push the axis against
its motion or move it from rest: it is set to 0 and counted (``wrong_sign``).  How often a
feedforward opposes the plant's actual motion is counted beside it (``against_motion``:
a commanded feedforward may lead a reversal by design).  A study may run without the gate
(``gate`` False, ``servo-test --no-safety-gate``): the feedforward then passes as computed,
still counted, to measure what the gate costs; nothing a controller runs takes that path.
"""

import math

import numpy as np

from bb_friction_ros.servo.baselines import LuGreState
from bb_friction_ros.node_parameters import B2B_AVERAGED
from bb_friction_ros.runner import InputSample, ModelRunner

MEASURED = "measured"
COMMANDED = "commanded"
BASE_MODES = ("none", "coulomb_viscous", "coulomb_viscous_commanded", "lugre",
              "lugre_commanded", "model", "model_commanded", "truth")
ALL_MODES = BASE_MODES + ("node", "planned", "node_planned")
# computed ahead along the reference, played back by time
PLANNED_MODES = ("planned", "node_planned")


def timing_of(name):
    """Return the timing of a mode name."""
    return COMMANDED if name.endswith("_commanded") or name in PLANNED_MODES else MEASURED


class Mode:
    """A feedforward: ``value(t, measured angle, velocity, reference angle, velocity, load)``."""

    name = "none"
    gate = True             # False: a study of what the safety gate costs (module docstring)

    def __init__(self, name):
        """Name the mode; its timing follows from the name."""
        self.name = name
        self.timing = timing_of(name)
        self.wrong_sign = 0
        self.against_motion = 0

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the feedforward at the state of its timing [N m] (0: none)."""
        return 0.0

    def value(self, t_s, meas_angle, meas_velocity, ref_angle, ref_velocity, load_n,
              plant_velocity):
        """Return the gated feedforward [N m] (module docstring)."""
        if self.timing == COMMANDED:
            angle, w = ref_angle, ref_velocity
        else:
            angle, w = meas_angle, meas_velocity
        return self._gated(self.raw(t_s, angle, w, load_n), w, plant_velocity)

    def _gated(self, ff, direction, plant_velocity):
        """
        Return ``ff`` through the safety gate (module docstring), counting what it saw.

        ``direction``: the motion ``ff`` belongs to (0: none, so only 0 N m passes).
        """
        if ff != 0.0 and (direction == 0.0 or (ff > 0.0) != (direction > 0.0)):
            self.wrong_sign += 1
            if self.gate:
                ff = 0.0
        if ff != 0.0 and plant_velocity != 0.0 and (ff > 0.0) != (plant_velocity > 0.0):
            self.against_motion += 1
        return ff

    def close(self):
        """Release what the mode holds (the node mode's ROS context)."""


class CoulombViscousMode(Mode):
    """c omega + T_c sign(omega) of the fitted baseline."""

    def __init__(self, name, fit):
        """Wrap a CoulombViscous fit."""
        super().__init__(name)
        self.fit = fit

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the fit's torque at the velocity."""
        return self.fit.torque(velocity_rad_s)


class LuGreMode(Mode):
    """The fitted LuGre model, its bristles stepped along the angle of its timing."""

    def __init__(self, name, fit):
        """Wrap a LuGre fit."""
        super().__init__(name)
        self.state = LuGreState(fit)

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return LuGre's torque after moving its state to the angle."""
        return self.state.torque(angle_rad, velocity_rad_s)


class ModelMode(Mode):
    """The product's model run as the node runs it; its safe ``feedforward_nm``."""

    def __init__(self, name, runner):
        """Wrap a ModelRunner (node schedule; terms without inertia)."""
        super().__init__(name)
        self.runner = runner
        self.errors = 0

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the runner's feedforward_nm for the sample."""
        p = self.runner.process(InputSample(t_s, angle_rad, velocity_rad_s, load_n))
        if p is None:
            self.errors += 1
            return 0.0
        return p.feedforward_nm


class PlannedMode(Mode):
    """
    The planned feedforward of the whole reference, computed ahead, played back by time.

    Its gate is the planned motion's: a row moving in the plan carries friction of the
    plan's direction, a standing row only the breakaway of a coming start (``breakaway``),
    in that start's direction, and 0 otherwise.
    """

    def __init__(self, name, t_s, ff, w_ref, breakaway):
        """Hold the plan's rows: times, feedforward, planned velocity, breakaway rows."""
        super().__init__(name)
        self.timing = COMMANDED
        self.t_s, self.ff, self.w_ref, self.breakaway = t_s, ff, w_ref, breakaway
        # the direction of the next planned motion at each row (0: none comes)
        ahead = np.zeros(w_ref.size)
        nxt = 0.0
        for k in range(w_ref.size - 1, -1, -1):
            if w_ref[k] != 0.0:
                nxt = 1.0 if w_ref[k] > 0.0 else -1.0
            ahead[k] = nxt
        self.ahead = ahead

    def value(self, t_s, meas_angle, meas_velocity, ref_angle, ref_velocity, load_n,
              plant_velocity):
        """Return the row's planned feedforward [N m], gated by the plan (class docstring)."""
        k = min(int(np.searchsorted(self.t_s, t_s)), self.t_s.size - 1)
        ff = float(self.ff[k])
        direction = np.sign(self.w_ref[k]) if self.w_ref[k] != 0.0 else \
            (self.ahead[k] if self.breakaway[k] else 0.0)
        return self._gated(ff, direction, plant_velocity)


class TruthMode(Mode):
    """
    The plant's friction, answered at the measured state (0 at standstill).

    Its law (its own instance: its own ball state) and, for a plant with pre-sliding, its
    Dahl state stepped along the measured angle as the plant steps its own (``plant``).
    """

    def __init__(self, name, law, presliding_rad=0.0):
        """Wrap a friction law of the plant's kind and the plant's pre-sliding travel."""
        super().__init__(name)
        self.law = law
        self.phi_d = presliding_rad
        self.f = 0.0                # the Dahl element's friction [N m]
        self.level = 0.0            # the sliding torque's magnitude it relaxes to [N m]
        self.last = None

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the law's torque while moving (its relaxed Dahl element's), 0 at rest."""
        moving = velocity_rad_s != 0.0
        torque = self.law.torque(t_s, angle_rad, velocity_rad_s, load_n) if moving else 0.0
        if self.phi_d <= 0.0:
            return torque
        if moving:
            self.level = abs(torque)
        if self.last is not None and angle_rad != self.last:
            # the plant's element: relaxed over the travel to the sliding torque's magnitude
            d = angle_rad - self.last
            target = math.copysign(self.level, d)
            self.f = target - (target - self.f) * math.exp(-abs(d) / self.phi_d)
        self.last = angle_rad
        return self.f if moving else 0.0


def model_runner(path, settings):
    """Return the node-like ModelRunner of a model file for the ``model`` modes."""
    from bb_friction_ros.ball_screw.whole_screw import WholeScrew
    from bb_friction_ros.model_file import load_model_file, NoPhysics, physics_of
    from bb_friction_ros.servo.plant import friction_terms
    cfg, terms = load_model_file(path)
    terms = friction_terms(terms)
    screw = NoPhysics() if physics_of(path) == "none" else WholeScrew(cfg)
    mean = None
    if settings.b2b_feedforward == B2B_AVERAGED and not isinstance(screw, NoPhysics):
        from bb_friction_ros.ball_screw.arrangement import mean_b2b
        mean = mean_b2b(cfg)
    runner = ModelRunner(screw, settings.model_rate_hz, terms if len(terms) else None,
                         settings.model_step_deg, max(settings.model_step_deg, 14.4),
                         mean_b2b=mean)
    runner.warm_up(cfg.operation.axial_load_n, cfg.operation.nut_velocity_rad_s)
    return runner
