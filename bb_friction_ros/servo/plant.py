"""
The simulated axis: a rigid body in nut-angle coordinates whose friction is the product's model.

Equation of motion, with the nut angle phi [rad] and the torque on the nut u [N m] (the
controller's command, plus the recording's command offset)::

    J phi'' = u - T_f

``T_f`` is a friction law (``ModelFriction``: the model file's physics and fitted terms, as
replay computes them, without the ``inertia`` term, which is J; ``RigidBodyFriction``: the
rigid-body reference's c omega + T_c sign(omega) + T_0).  A law answers the torque while
the axis moves (``torque``) and the breakaway torques at rest (``breakaway``: the model's
torque an instant into the motion in either direction).

Integration (``Plant.advance``): a servo period is cut into ``substeps``; over each the
torques are held, so the motion is exactly a constant acceleration (the update is exact, not
an Euler step).  The friction is re-answered by the model at every sub-step
(``friction_update: substep``, the default: along the simulated motion, every servo sample
included) or held from the servo sample (``sample``).  What remains is the error of holding
the friction over its interval: its change with velocity (c delta-omega, the Stribeck drop
at a breakaway) and angle (the ball-to-ball ripple); it is measured against a finer run
(docs/servo_test.md, test/servo/test_plant.py).

Stick at standstill (stick-slip switch, no chatter): when the velocity crosses zero inside a
sub-step, the crossing time is solved exactly and the axis stops there.  At rest it stays
while B- <= u <= B+ (the two breakaway torques): the friction then equals u, holding the
applied torque up to the breakaway value; beyond it the axis slides, friction opposing the
motion.  There is no velocity threshold to tune and no sign flipping at rest.

Pre-sliding (``presliding_rad`` > 0, a Dahl element): the friction is a state f that relaxes
along the nut travel toward the model's sliding torque T (signed, in the direction of travel,
magnitude M): df/dphi = (M sign(dphi) - f) / phi_d, solved exactly over each sub-step.  After
a reversal the friction builds up over a few phi_d of travel instead of flipping; no switch
is needed: at rest f stays, and the axis rests on the friction like on a soft spring.  For a
constant M this is Dahl's s * M with ds/dphi = (sign(dphi) - s) / phi_d.  When M changes
with the velocity (a Stribeck rise, a viscous drag), f follows it over the travel, not at
once: an element deflected in pre-sliding has not slid, and its friction is a function of
its deflection (docs/servo_test.md, "The plant").  ``presliding_damping_ratio`` > 0 adds
LuGre's micro-damping sigma_1 dz/dt (z the deflection; 0 in steady sliding), sigma_1 set by
its damping ratio of the mode of the element's stiffness M / phi_d and the inertia.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.config import ConfigError
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.model_file import load_model_file, NoPhysics, physics_of
from bb_friction_ros.runner import InputSample, ModelRunner

# Velocity at which the breakaway torque is asked of the model [rad/s]: an instant into the
# motion.  Small against any viscous term (1e-9 rad/s x 10 N m s/rad = 1e-8 N m).
BREAKAWAY_PROBE_RAD_S = 1e-9


def friction_terms(terms, drop=()):
    """
    Return the TermSet without its ``inertia`` terms (J is the plant's, not friction).

    Terms named in ``drop`` go too (``pre_rolling`` where the plant's own Dahl element
    carries the pre-sliding: ``plant_presliding_rad``).
    """
    return TermSet(t for t in terms.terms if t.name != "inertia" and t.name not in drop)


def model_presliding_rad(path):
    """Return the travel [rad] of a model file's ``pre_rolling`` term (0 without one)."""
    _, terms = load_model_file(path)
    return float(max((t.params.travel_rad for t in terms.terms if t.name == "pre_rolling"),
                     default=0.0))


def plant_presliding_rad(settings_presliding_rad, model_path):
    """
    Return the plant's pre-sliding travel [rad]: ``plant.presliding_rad``, else the model's.

    A model file calibrated on a recording with reversals carries its pre-sliding as a
    ``pre_rolling`` term (a Dahl element on T_p).  As a plant it is simulated by the plant's
    Dahl element of that travel on the whole friction (module docstring): the friction then
    holds the axis like a soft spring at rest, as the recorded axis did, where the
    term's own answer is cut to 0 until it opposes the motion again (a feedforward's safety
    rule, not a plant's physics) and the stick switch would flip it at once.
    """
    if settings_presliding_rad > 0.0:
        return float(settings_presliding_rad)
    return model_presliding_rad(model_path)


def model_inertia(path):
    """Return the inertia [kg m^2] of a model file's ``inertia`` terms (0 without one)."""
    _, terms = load_model_file(path)
    return float(sum(t.params.j_kg_m2 for t in terms.terms if t.name == "inertia"))


def plant_inertia(settings_inertia, model_path, loop_source="LOOP.yaml"):
    """
    Return the plant's inertia [kg m^2]: ``plant.inertia_kg_m2``, else the model's term.

    Neither is a ConfigError naming both places: a servo loop cannot be simulated without it.
    """
    if settings_inertia > 0.0:
        return float(settings_inertia)
    j = model_inertia(model_path)
    if j > 0.0:
        return j
    raise ConfigError(f"{loop_source}: plant.inertia_kg_m2: missing, and the model file "
                      f"{model_path} has no inertia term: the plant needs its inertia "
                      "(give plant.inertia_kg_m2 or calibrate the model with an inertia term)")


def lead_of(path):
    """Return the screw lead [m] of a model file (its ball_screw geometry)."""
    cfg, _ = load_model_file(path)
    return float(cfg.geometry.lead_m)


class ModelFriction:
    """
    The product's model of a model file as a friction law, answered by a ModelRunner.

    The runner is the node's and replay's, stepped every ``step_deg`` of nut rotation and at
    least at ``rate_hz`` (steps before their answers: the plant's state is never a step
    behind).  ``physics: none`` files run their terms alone, as replay runs them.
    """

    def __init__(self, path, rate_hz, step_deg, drop=()):
        """Build the runner of model file ``path`` without its inertia terms (and ``drop``)."""
        from bb_friction_ros.ball_screw.whole_screw import WholeScrew
        cfg, terms = load_model_file(path)
        self.terms = friction_terms(terms, drop)
        screw = NoPhysics() if physics_of(path) == "none" else WholeScrew(cfg)
        self.runner = ModelRunner(screw, rate_hz, self.terms if len(self.terms) else None,
                                  step_deg, max(step_deg, 14.4), step_after_answer_fraction=0.0)
        self.runner.warm_up(cfg.operation.axial_load_n, cfg.operation.nut_velocity_rad_s)
        self.errors = 0             # model steps that raised (answered by the last torque)
        self._last = 0.0

    def torque(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the model's friction torque [N m] at a moving sample."""
        p = self.runner.process(InputSample(t_s, angle_rad, velocity_rad_s, load_n))
        if p is None:
            self.errors += 1
            return self._last
        self._last = p.torque_total_nm
        return self._last

    def breakaway(self, t_s, angle_rad, load_n, direction):
        """
        Return the model's torque an instant into a motion of ``direction`` (+1 or -1) [N m].

        A copy of the runner answers it (``ModelRunner.probe``: the runner's own rules, a
        term's live state included), so the runner itself is left as it is: the axis has
        not moved yet.
        """
        w = direction * BREAKAWAY_PROBE_RAD_S
        r = self.runner
        if r.state is None:
            p = r.process(InputSample(t_s, angle_rad, w, load_n))
            return self._last if p is None else float(p.torque_total_nm)
        probe = r.probe()
        stamp = max(t_s, r.schedule.last_stamp)
        p = probe.process(InputSample(stamp, angle_rad, w, load_n))
        if p is None:       # a failed probe: the last moving torque's magnitude, counted
            self.errors += 1
            return direction * abs(self._last)
        return float(p.torque_total_nm)


@dataclasses.dataclass
class RigidBodyFriction:
    """The rigid-body reference's friction: c omega + T_c sign(omega) + T_0 [N m]."""

    c_nm_s_per_rad: float
    coulomb_nm: float
    offset_nm: float
    errors: int = 0

    def torque(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Return the friction torque [N m] of a moving sample."""
        return (self.c_nm_s_per_rad * velocity_rad_s
                + math.copysign(self.coulomb_nm, velocity_rad_s) + self.offset_nm)

    def breakaway(self, t_s, angle_rad, load_n, direction):
        """Return T_0 + direction * T_c [N m]."""
        return self.offset_nm + direction * self.coulomb_nm


class Plant:
    """
    The axis: state (angle, velocity), a friction law, and the integrator of the module doc.

    ``advance`` moves it over one servo period under a held torque and returns the friction
    [N m] it applied at the period's start (the held torque when it stuck).
    """

    def __init__(self, law, inertia_kg_m2, settings, angle0_rad, presliding_rad=None):
        """
        Start at rest at ``angle0_rad``; ``settings`` is a PlantSettings.

        ``presliding_rad``: the Dahl travel (``plant_presliding_rad``); None takes
        ``settings.presliding_rad``.
        """
        self.law = law
        self.j = float(inertia_kg_m2)
        self.n_sub = settings.substeps
        self.every_substep = settings.friction_update == "substep"
        self.phi_d = settings.presliding_rad if presliding_rad is None else presliding_rad
        self.zeta = settings.presliding_damping_ratio
        self.angle = float(angle0_rad)
        self.velocity = 0.0
        self.level = 0.0            # Dahl: the sliding friction it relaxes to [N m], signed
        self.f = 0.0                # Dahl: the element's friction [N m]
        self._probe = None          # (angle, load, B-, B+) of the rest in progress
        self.stick_substeps = 0
        self.breakaways = 0

    def _breakaways(self, t_s, load_n):
        key = (self.angle, load_n)
        if self._probe is None or self._probe[0] != key:
            b_minus = self.law.breakaway(t_s, self.angle, load_n, -1.0)
            b_plus = self.law.breakaway(t_s, self.angle, load_n, 1.0)
            self._probe = (key, b_minus, b_plus)
        return self._probe[1], self._probe[2]

    def advance(self, t_s, period_s, u_nm, load_n):
        """Integrate one servo period under torque ``u_nm``; return the friction at its start."""
        if self.phi_d > 0.0:
            return self._advance_dahl(t_s, period_s, u_nm, load_n)
        h = period_s / self.n_sub
        first = None
        friction = None
        for i in range(self.n_sub):
            t = t_s + i * h
            left = h
            while left > 0.0:
                if self.velocity == 0.0:
                    b_minus, b_plus = self._breakaways(t, load_n)
                    if b_minus <= u_nm <= b_plus:
                        self.stick_substeps += 1
                        if first is None:
                            first = u_nm
                        friction = None
                        break
                    # slides: from rest, friction of the new direction
                    direction = 1.0 if u_nm > b_plus else -1.0
                    f = b_plus if direction > 0.0 else b_minus
                    self.breakaways += 1
                    self._probe = None
                else:
                    if friction is None or self.every_substep or i == 0 and left == h:
                        friction = self.law.torque(t + (h - left), self.angle, self.velocity,
                                                   load_n)
                    f = friction
                    direction = math.copysign(1.0, self.velocity)
                if first is None:
                    first = f
                a = (u_nm - f) / self.j
                w0 = self.velocity
                w1 = w0 + a * left
                if w0 != 0.0 and w1 * w0 <= 0.0 and a != 0.0:
                    tau = -w0 / a                       # the exact crossing time
                    self.angle += w0 * tau + 0.5 * a * tau * tau
                    self.velocity = 0.0
                    left -= tau
                    friction = None
                    if left <= 1e-15 * period_s:
                        break
                    continue
                if w0 == 0.0 and w1 * direction <= 0.0:
                    break                               # no net push out of the rest
                self.angle += w0 * left + 0.5 * a * left * left
                self.velocity = w1
                left = 0.0
        return 0.0 if first is None else first

    @property
    def s(self):
        """Return the Dahl state: the element's friction over its sliding level (0 unknown)."""
        return self.f / abs(self.level) if self.level != 0.0 else 0.0

    def _advance_dahl(self, t_s, period_s, u_nm, load_n):
        """Pre-sliding plant: semi-implicit sub-steps, the element relaxed exactly along each."""
        h = period_s / self.n_sub
        first = None
        for i in range(self.n_sub):
            t = t_s + i * h
            if self.velocity != 0.0 and (i == 0 or self.every_substep):
                self.level = self.law.torque(t, self.angle, self.velocity, load_n)
            elif self.level == 0.0:
                d = 1.0 if u_nm >= 0.0 else -1.0
                self.level = self.law.breakaway(t, self.angle, load_n, d)
            f = self.f
            w = self.velocity
            magnitude = abs(self.level)
            c = 0.0
            if self.zeta > 0.0 and magnitude > 0.0:
                # sigma_1 dz/dt, z the element's deflection: dz/dt = w (1 - f / (+-M)) with M
                # the level in the direction of w, 0 in steady sliding; never negative
                sigma1 = 2.0 * self.zeta * math.sqrt(self.j * magnitude / self.phi_d)
                direction = math.copysign(1.0, w if w != 0.0 else u_nm - f)
                c = sigma1 * max(0.0, 1.0 - direction * f / magnitude)
            if first is None:
                first = f + c * w
            # implicit in the damping: stable at any sigma_1 h / J
            self.velocity = (w + h * (u_nm - f) / self.j) / (1.0 + h * c / self.j)
            d_phi = self.velocity * h
            self.angle += d_phi
            if d_phi != 0.0:
                target = math.copysign(magnitude, d_phi)
                self.f = target - (target - self.f) * math.exp(-abs(d_phi) / self.phi_d)
        return first


def quantise(angle_rad, counts_per_rev):
    """Return the encoder's reading of ``angle_rad``: whole counts (floor), or the angle."""
    if counts_per_rev <= 0:
        return angle_rad
    q = 2.0 * math.pi / counts_per_rev
    return math.floor(angle_rad / q) * q


def quantise_array(angle_rad, counts_per_rev):
    """Vectorised ``quantise``."""
    if counts_per_rev <= 0:
        return np.asarray(angle_rad, dtype=float)
    q = 2.0 * math.pi / counts_per_rev
    return np.floor(np.asarray(angle_rad) / q) * q
