"""
The servo test's settings: the loop, the plant and the product's model, read from LOOP.yaml.

Every value is a validated field with its unit and range, like every config of the project::

    loop:                       # the cascade at rate_hz (docs/servo_test.md)
      rate_hz: 1000.0
      position_gain_per_s: 60.0
      velocity_gain_nm_s_per_rad: 0.25
      velocity_integral_gain_nm_per_rad: 10.0     # default 0
      velocity_estimate_span_samples: 1           # default 1
      compute_delay_samples: 0                    # default 0
      torque_limit_nm: 5.0
      velocity_feedforward: 1.0                   # 0-1, default 0
      acceleration_feedforward: 1.0               # 0-1, default 0
    plant:
      inertia_kg_m2: 2.0e-4     # optional: else the model file's inertia term

The ``loop`` keys without a default (rate, the two gains, the torque limit) must be given:
a servo loop has no sensible default gains.  A key missing or out of range is refused with
its dotted path.
"""

import dataclasses
import math
from typing import Optional

from bb_friction_ros.config import check_choice, ConfigError, field, from_mapping, load_yaml
from bb_friction_ros.node_parameters import B2B_AVERAGED, B2B_FEEDFORWARDS

LOOP = "loop"
PLANT = "plant"
MODEL = "model"
CALIBRATION = "calibration"
SECTIONS = (LOOP, PLANT, MODEL, CALIBRATION)
# plant.friction_update choices: the plant's model answered at every sub-step (the default:
# it costs little, the model steps by nut rotation either way) or once per servo sample
FRICTION_UPDATES = ("sample", "substep")
BALL_STATES = ("fresh", "run_in")


@dataclasses.dataclass(frozen=True)
class LoopSettings:
    """The P position / PI velocity cascade (docs/servo_test.md, "The loop")."""

    rate_hz: float = field(1000.0, "Hz", "servo rate: one command per 1/rate_hz, held until "
                           "the next (zero-order hold)", lo=10.0, hi=100000.0)
    position_gain_per_s: float = field(50.0, "1/s", "P gain of the position loop: velocity "
                                       "command per rad of position error", lo=0.0, hi=1e5)
    velocity_gain_nm_s_per_rad: float = field(0.1, "N m s/rad", "P gain of the velocity loop",
                                              lo=0.0, hi=1e4, lo_open=True)
    velocity_integral_gain_nm_per_rad: float = field(
        0.0, "N m/rad", "I gain of the velocity loop: torque per rad of integrated velocity "
        "error (0: P velocity loop)", lo=0.0, hi=1e7)
    velocity_estimate_span_samples: int = field(
        1, "1", "the velocity is the measured angle's difference over this many samples, "
        "divided by their time", lo=1, hi=1000)
    compute_delay_samples: int = field(
        0, "1", "servo periods between the sample a command is computed from and the start "
        "of its hold", lo=0, hi=1000)
    torque_limit_nm: float = field(1.0, "N m", "symmetric limit of the torque command "
                                   "(the integrator stops while it limits)", lo=0.0,
                                   hi=1e5, lo_open=True)
    velocity_feedforward: float = field(0.0, "1", "share of the reference velocity added to "
                                        "the velocity command", lo=0.0, hi=1.0)
    acceleration_feedforward: float = field(0.0, "1", "share of J times the reference "
                                            "acceleration added to the torque command",
                                            lo=0.0, hi=1.0)
    encoder_counts_per_rev: int = field(0, "1", "the measured angle is quantised to this "
                                        "many counts per revolution (0: not quantised)",
                                        lo=0, hi=2 ** 40)

    REQUIRED = ("rate_hz", "position_gain_per_s", "velocity_gain_nm_s_per_rad",
                "torque_limit_nm")

    @property
    def period_s(self):
        """Servo period [s]."""
        return 1.0 / self.rate_hz


@dataclasses.dataclass(frozen=True)
class PlantSettings:
    """The simulated axis (docs/servo_test.md, "The plant")."""

    inertia_kg_m2: float = field(0.0, "kg m^2", "moment of inertia of the axis reduced to "
                                 "the nut angle (0: take the model file's inertia term)",
                                 lo=0.0, hi=1e3)
    substeps: int = field(8, "1", "integration sub-steps per servo period (each exact for "
                          "its held torques; a velocity zero crossing is found inside one)",
                          lo=1, hi=1000)
    friction_update: str = dataclasses.field(default="substep")
    model_rate_hz: float = field(1000.0, "Hz", "the plant model's time floor: it steps at "
                                 "least this often while the axis moves", lo=1.0, hi=1e6)
    model_step_deg: float = field(0.36, "deg", "nut rotation between the plant model's steps",
                                  lo=1e-4, hi=90.0)
    ball_state: str = dataclasses.field(default="fresh")
    run_in_revolutions: float = field(10.0, "1", "nut revolutions turned (forward, then back "
                                      "to the start) before the test when ball_state is "
                                      "run_in", lo=0.0, hi=1e4)
    run_in_speed_rad_s: float = field(6.283185307179586, "rad/s", "nut speed of the run-in",
                                      lo=0.0, hi=1e4, lo_open=True)
    presliding_rad: float = field(0.0, "rad", "pre-sliding (Dahl) travel of the friction: it "
                                  "builds up over this nut rotation after a reversal (0: the "
                                  "plant model file's pre_rolling travel, else a stick-slip "
                                  "switch)", lo=0.0, hi=1.0)
    presliding_damping_ratio: float = field(
        0.0, "1", "micro-damping of the pre-sliding element (LuGre's sigma_1 on dz/dt), as "
        "the damping ratio of the mode its stiffness forms with the plant's inertia",
        lo=0.0, hi=10.0)
    axial_load_n: float = field(0.0, "N", "axial load when the recording has none "
                                "(axial_load_n column)", lo=-1e6, hi=1e6)

    def check(self, path):
        """Refuse an unknown friction_update or ball_state, naming the key."""
        check_choice(f"{path}.friction_update", self.friction_update, FRICTION_UPDATES)
        check_choice(f"{path}.ball_state", self.ball_state, BALL_STATES)


@dataclasses.dataclass(frozen=True)
class ModelSettings:
    """How the product's model is run for the ``model`` feedforward (as the node runs it)."""

    model_rate_hz: float = field(100.0, "Hz", "the node's model_rate_hz", lo=1.0, hi=1e6)
    model_step_deg: float = field(1.8, "deg", "the node's model_step_deg", lo=1e-4, hi=90.0)
    ball_state: str = dataclasses.field(default="fresh")
    # the node's b2b_feedforward: the B2B torque averaged over arrangements (its default), or
    # the model state's own
    b2b_feedforward: str = dataclasses.field(default=B2B_AVERAGED)

    def check(self, path):
        """Refuse an unknown ball_state or b2b_feedforward, naming the key."""
        check_choice(f"{path}.ball_state", self.ball_state, BALL_STATES)
        check_choice(f"{path}.b2b_feedforward", self.b2b_feedforward, B2B_FEEDFORWARDS)


@dataclasses.dataclass(frozen=True)
class CalibrationSettings:
    """The calibration run the baselines are fitted on when no recording is given."""

    speed_fractions: str = dataclasses.field(default="0.1 0.25 0.5 1.0")
    cruise_s: float = field(0.3, "s", "constant-speed time of each calibration move",
                            lo=0.01, hi=1e4)
    accel_cutoff_hz: float = field(20.0, "Hz", "cut-off of the zero-phase acceleration "
                                   "filter used by the fits", lo=0.1, hi=1e5)
    lugre_max_evaluations: int = field(400, "1", "LuGre fit: largest number of simulations "
                                       "of the calibration run", lo=10, hi=100000)

    def fractions(self):
        """Return the calibration speeds as fractions of the test's largest speed."""
        try:
            out = [float(x) for x in self.speed_fractions.replace(",", " ").split()]
        except ValueError:
            out = []
        return out

    def check(self, path):
        """Refuse speed fractions that are not numbers in (0, 2]."""
        values = self.fractions()
        if not values or not all(0.0 < v <= 2.0 and math.isfinite(v) for v in values):
            raise ConfigError(f"{path}.speed_fractions: expected numbers in (0, 2] separated "
                              f"by spaces, got {self.speed_fractions!r}")


@dataclasses.dataclass(frozen=True)
class ServoSettings:
    """All of LOOP.yaml."""

    loop: LoopSettings
    plant: PlantSettings = PlantSettings()
    model: ModelSettings = ModelSettings()
    calibration: CalibrationSettings = CalibrationSettings()
    source: Optional[str] = None


def settings_from_mapping(raw, source="LOOP.yaml"):
    """Return the ServoSettings of a LOOP.yaml mapping, validated; errors name the key."""
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: expected a mapping with a '{LOOP}' section")
    unknown = sorted(set(raw) - set(SECTIONS))
    if unknown:
        raise ConfigError(f"{source}: {unknown[0]}: unknown section (known: "
                          f"{', '.join(SECTIONS)})")
    loop_raw = raw.get(LOOP)
    if not isinstance(loop_raw, dict):
        raise ConfigError(f"{source}: {LOOP}: missing or not a mapping (needs "
                          f"{', '.join(LoopSettings.REQUIRED)})")
    missing = [k for k in LoopSettings.REQUIRED if k not in loop_raw]
    if missing:
        raise ConfigError(f"{source}: {LOOP}.{missing[0]}: missing (a servo loop has no "
                          f"default {missing[0]})")
    loop = from_mapping(LoopSettings, loop_raw, f"{source}: {LOOP}")
    plant = from_mapping(PlantSettings, raw.get(PLANT) or {}, f"{source}: {PLANT}")
    model = from_mapping(ModelSettings, raw.get(MODEL) or {}, f"{source}: {MODEL}")
    cal = from_mapping(CalibrationSettings, raw.get(CALIBRATION) or {},
                       f"{source}: {CALIBRATION}")
    return ServoSettings(loop, plant, model, cal, source)


def load_settings(path):
    """Read LOOP.yaml (``path``) into ServoSettings."""
    return settings_from_mapping(load_yaml(path), str(path))
