"""
Validated configuration of the ball screw model (paper Sec. 3, Table 4).

Every physical value is a named field with its unit and admissible range.  SI inside; the YAML
file may use the edge units ``*_deg``, ``*_mm``, ``*_um`` (converted by ``config.from_mapping``).
``model_file.load_ball_screw`` reads it from a file.
"""

import dataclasses
import math
from typing import ClassVar

from bb_friction_ros.ball_screw.geometry import b2b_contact_separation
from bb_friction_ros.config import MEMORY_LIMIT_MIB, ConfigError, check_memory, field

_DEG = math.pi / 180.0


@dataclasses.dataclass(frozen=True)
class ScrewGeometry:
    """Nominal geometry of a single-start, right-handed, Gothic-arch ball screw (Table 4)."""

    ball_radius_m: float = field(2.778e-3, "m", "ball radius R_B", lo=0.0, lo_open=True)
    conformity: float = field(0.56, "1", "groove arc radius / ball diameter", lo=0.5, hi=1.0,
                              lo_open=True)
    pitch_radius_m: float = field(16.5e-3, "m", "pitch circle radius R_P", lo=0.0,
                                  lo_open=True)
    lead_m: float = field(20e-3, "m", "lead p of the single-start screw", lo=0.0,
                          lo_open=True)
    nominal_contact_angle_rad: float = field(45.0 * _DEG, "rad", "nominal contact angle "
                                             "beta_0", lo=0.0, hi=math.pi / 2, lo_open=True,
                                             hi_open=True)
    ball_oversize_m: float = field(0.0, "m", "preload: ball diameter minus the diameter that "
                                   "just touches all four arcs", lo=-1e-5, hi=1e-4)

    def check(self, path):
        """Cross-field checks: the ball must fit the pitch circle."""
        if self.ball_radius_m >= self.pitch_radius_m:
            raise ConfigError(f"{path}.ball_radius_m: must be < pitch_radius_m")


@dataclasses.dataclass(frozen=True)
class Material:
    """Elastic and friction properties (balls, screw and nut of the same steel)."""

    youngs_modulus_pa: float = field(210e9, "Pa", "Young's modulus E (Table 4's '210 N/mm^2' "
                                     "is a typo for 210 GPa)", lo=1e9, hi=1e13)
    poisson_ratio: float = field(0.28, "1", "Poisson's ratio", lo=0.0, hi=0.5, hi_open=True)
    friction_coefficient: float = field(0.1, "1", "Coulomb coefficient mu (groove and B2B)",
                                        lo=0.0, hi=1.0, lo_open=True)


@dataclasses.dataclass(frozen=True)
class GeometricErrors:
    """
    Geometric errors of the grooves (paper Figs. 15, 17, 19).

    theta(phi) = offset + amplitude sin(cycles_per_rev phi + phase) is the screw-side
    contact-angle deviation: a rigid rotation of the screw groove profile about the nominal
    ball centre, beta_SL = beta_0 - theta, beta_SR = beta_0 + theta.
    """

    theta_amplitude_rad: float = field(3.44 * _DEG, "rad", "amplitude of the sinusoidal "
                                       "screw contact-angle deviation theta(phi) (Fig. 19; "
                                       "not given in the paper: calibrated to Fig. 21's "
                                       "peak B2B share by the bundled sweep, see docs)",
                                       lo=0.0, hi=10.0 * _DEG)
    theta_cycles_per_rev: float = field(2.0, "1", "cycles of theta per screw revolution "
                                        "(four cycles over the two loaded turns)", lo=0.0,
                                        hi=100.0)
    theta_phase_rad: float = field(0.0, "rad", "phase of theta(phi) at phi = 0",
                                   lo=-2 * math.pi, hi=2 * math.pi)
    theta_offset_rad: float = field(0.0, "rad", "constant part of theta", lo=-10.0 * _DEG,
                                    hi=10.0 * _DEG)
    nut_lead_error_m: float = field(0.0, "m", "nut lead minus screw lead, per revolution "
                                    "(shifts the nut groove along the loaded track)",
                                    lo=-1e-4, hi=1e-4)
    screw_lead_error_amplitude_m: float = field(0.0, "m", "amplitude of a periodic screw "
                                                "lead error (axial groove shift)", lo=0.0,
                                                hi=1e-4)
    screw_lead_error_cycles_per_rev: float = field(1.0, "1", "cycles of the periodic screw "
                                                   "lead error per revolution", lo=0.0,
                                                   hi=100.0)


@dataclasses.dataclass(frozen=True)
class NutTrack:
    """Balls in the nut's loaded track and its recirculation (Sec. 3.4)."""

    n_balls: int = field(37, "1", "balls in the closed recirculation loop", lo=2, hi=100000)
    loaded_turns: float = field(2.0, "1", "turns of the loaded track (loop length, the "
                                "return tube is taken as zero length)", lo=0.1, hi=1000.0)
    track_start_rad: float = field(0.0, "rad", "nut-frame azimuth where the loaded track "
                                   "starts", lo=-2 * math.pi, hi=2 * math.pi)


@dataclasses.dataclass(frozen=True)
class Operation:
    """Operating point of the whole-screw simulation (Sec. 3.4) and of the module (Table 5)."""

    # signed, so a velocity: the old name stays readable (config.current_name)
    RENAMED: ClassVar[dict] = {"nut_speed_rad_s": "nut_velocity_rad_s"}

    nut_velocity_rad_s: float = field(2.0 * math.pi, "rad/s", "nut angular velocity omega_N "
                                      "(signed)", lo=-1e4, hi=1e4)
    axial_load_n: float = field(1500.0, "N", "axial load W: force of the balls on the nut "
                                "along +z; W > 0 opposes omega_N > 0", lo=-1e6, hi=1e6)
    duration_s: float = field(2.0, "s", "simulated time", lo=0.0, lo_open=True)
    n_steps: int = field(200, "1", "time steps", lo=1, hi=10 ** 7)
    module_axial_load_n: float = field(50.0, "N", "axial load on the two-ball module of "
                                       "Table 5, shared by both balls", lo=-1e6, hi=1e6)
    module_theta1_rad: float = field(0.0, "rad", "theta of ball 1 in the two-ball module",
                                     lo=-10.0 * _DEG, hi=10.0 * _DEG)
    module_theta2_rad: float = field(2.0 * _DEG, "rad", "theta of ball 2 in the two-ball "
                                     "module", lo=-10.0 * _DEG, hi=10.0 * _DEG)


@dataclasses.dataclass(frozen=True)
class SolverSettings:
    """Newton / active-set settings; they set accuracy, never the physics."""

    tolerance: float = field(1e-8, "1", "residual tolerance relative to the force scale",
                             lo=1e-15, hi=1e-3)
    substep_tolerance: float = field(1e-5, "1", "residual tolerance of a sub-step: a step "
                                     "between two inputs whose state is never answered, "
                                     "only carried on (docs/model_schedule.md, Sub-steps); "
                                     "at least tolerance", lo=1e-15, hi=1e-3)
    max_iterations: int = field(40, "1", "Newton iterations per active set", lo=1, hi=1000)
    max_active_set_changes: int = field(50, "1", "active-set updates per solve", lo=1,
                                        hi=10000)
    gap_tolerance_rad: float = field(1e-9, "rad", "azimuth gap below which two balls touch",
                                     lo=0.0, hi=1e-3)
    max_step_rate: float = field(1.0, "1", "largest Newton change of an angular rate, in "
                                 "units of |omega_N| (trust region)", lo=0.0, lo_open=True)
    max_step_displacement_m: float = field(1e-6, "m", "largest Newton change of a ball or "
                                           "nut displacement (trust region)", lo=0.0,
                                           lo_open=True)
    cold_start_ball_load_n: float = field(25.0, "N", "axial load per ball at which a cold "
                                          "start is first solved (theta = 0), before "
                                          "continuation to the actual load and errors",
                                          lo=0.0, lo_open=True)
    continuation_load_factor: float = field(1.5, "1", "largest load ratio between two "
                                            "continuation steps", lo=1.0, lo_open=True,
                                            hi=10.0)
    continuation_theta_step_rad: float = field(0.5 * _DEG, "rad", "largest theta change "
                                               "between two continuation steps", lo=0.0,
                                               lo_open=True)
    min_axial_load_n: float = field(1e-6, "N", "with zero preload, below this |W| no ball is "
                                    "loaded: zero friction is returned", lo=0.0)
    realtime_max_iterations: int = field(0, "1", "real-time mode: Newton iterations per "
                                         "warm step at most; when they run out the step "
                                         "returns its last iterate with converged = false. "
                                         "0 = off (iterate to tolerance)", lo=0, hi=1000)
    map_polar_nodes: int = field(160, "1", "polar nodes of the friction map", lo=16,
                                 hi=4096)
    map_azimuth_nodes: int = field(256, "1", "azimuth nodes of the friction map", lo=16,
                                   hi=8192)
    map_memory_limit_mib: float = field(MEMORY_LIMIT_MIB, "MiB", "largest memory the "
                                        "friction map's build may need; more is refused "
                                        "before it starts", lo=0.0, lo_open=True)

    def check(self, path):
        """Cross-field checks: substep_tolerance >= tolerance; the friction map fits memory."""
        if self.substep_tolerance < self.tolerance:
            raise ConfigError(f"{path}.substep_tolerance: {self.substep_tolerance:g} is "
                              f"below {path}.tolerance ({self.tolerance:g}); a sub-step's "
                              "state is never answered, so it needs no tighter solve")
        from bb_friction_ros.contact.friction_maps import sphere_map_bytes
        check_memory(sphere_map_bytes(self.map_polar_nodes, self.map_azimuth_nodes),
                     self.map_memory_limit_mib,
                     f"{path}.map_polar_nodes x map_azimuth_nodes",
                     f"a friction map of {self.map_polar_nodes} x {self.map_azimuth_nodes} "
                     "nodes", f"{path}.map_memory_limit_mib")


@dataclasses.dataclass(frozen=True)
class ValidityRange:
    """
    The loads inside which the model's assumptions hold (docs/assumptions_ball_screw.md).

    The smaller of the two contact loads they allow is the model's limit; a whole-screw step
    whose mean contact load exceeds it is not solved, and a solution with any contact above
    it is flagged (``StepResult.in_load_range``).
    """

    max_contact_semi_axis_ratio: float = field(0.2, "1", "largest Hertz semi-major axis "
                                               "over the ball radius, a / R_B: the planar "
                                               "contact of Sec. 3.1 ('small compared with the "
                                               "ball radius')", lo=0.0, lo_open=True, hi=1.0)
    max_hertz_pressure_pa: float = field(4.2e9, "Pa", "largest Hertz peak pressure: 4.2 GPa "
                                         "is the static load rating's criterion for ball "
                                         "contacts (ISO 76, ISO 3408-5); above it the steel "
                                         "yields and elastic Hertz theory ends", lo=0.0,
                                         lo_open=True)


LOAD_DISTRIBUTIONS = ("rigid", "elastic")
SHAFT_LOAD_ENDS = ("track_start", "track_end")
NUT_SUPPORTS = ("outer_surface", "flange_at_track_start", "flange_at_track_end")


@dataclasses.dataclass(frozen=True)
class ElasticBodies:
    """
    Bulk axial deformation of screw shaft and nut (``load_distribution: elastic``; ref. [19]).

    Shaft and nut are axial bars between neighbouring balls: the stiffness of a segment one
    ball pitch long is E A / (ball pitch), with E A the axial rigidity below.  Defaults:
    Sec. 3.4's set-up (docs/assumptions_ball_screw.md, "Elastic load distribution").
    """

    shaft_axial_rigidity_n: float = field(1.2262e8, "N", "axial rigidity E A of the screw "
                                          "shaft (E = 210 GPa, root diameter 27.27 mm of "
                                          "the Table 4 Gothic-arch groove)", lo=0.0,
                                          lo_open=True)
    nut_axial_rigidity_n: float = field(2.6979e8, "N", "axial rigidity E A of the nut body "
                                        "(E = 210 GPa, outer diameter 56 mm, groove root "
                                        "diameter 38.73 mm; used with a flange support)",
                                        lo=0.0, lo_open=True)
    shaft_load_end: str = dataclasses.field(default="track_start")
    nut_support: str = dataclasses.field(default="outer_surface")

    def check(self, path):
        """Check the two choices by name."""
        if self.shaft_load_end not in SHAFT_LOAD_ENDS:
            raise ConfigError(f"{path}.shaft_load_end: must be one of "
                              f"{', '.join(SHAFT_LOAD_ENDS)}, got {self.shaft_load_end!r}")
        if self.nut_support not in NUT_SUPPORTS:
            raise ConfigError(f"{path}.nut_support: must be one of {', '.join(NUT_SUPPORTS)}"
                              f", got {self.nut_support!r}")


@dataclasses.dataclass(frozen=True)
class BallScrewConfig:
    """Complete ball screw configuration (key ``ball_screw`` of config/ball_screw.yaml)."""

    geometry: ScrewGeometry = dataclasses.field(default_factory=ScrewGeometry)
    material: Material = dataclasses.field(default_factory=Material)
    errors: GeometricErrors = dataclasses.field(default_factory=GeometricErrors)
    track: NutTrack = dataclasses.field(default_factory=NutTrack)
    operation: Operation = dataclasses.field(default_factory=Operation)
    solver: SolverSettings = dataclasses.field(default_factory=SolverSettings)
    elastic: ElasticBodies = dataclasses.field(default_factory=ElasticBodies)
    validity: ValidityRange = dataclasses.field(default_factory=ValidityRange)
    # 'rigid': rigid nut and shaft, all balls share W through one nut displacement;
    # 'elastic': shaft and nut deform axially between balls (ref. [19]), see ElasticBodies.
    load_distribution: str = dataclasses.field(default="rigid")

    def check(self, path):
        """``load_distribution`` is one of the named models; the balls fit on the track."""
        if self.load_distribution not in LOAD_DISTRIBUTIONS:
            raise ConfigError(f"{path}.load_distribution: must be one of "
                              f"{', '.join(LOAD_DISTRIBUTIONS)}, got "
                              f"{self.load_distribution!r}")
        # Touching balls sit one B2B separation apart (Eq. 56 on the exact helix); the
        # closed loop is loaded_turns turns long.  Checked here, not first in the model's
        # constructor, so that every entry point (replay, node, screw-sim) refuses it at
        # load with the key (the node and screw-sim used to crash with a traceback).
        g, tr = self.geometry, self.track
        separation = b2b_contact_separation(g.ball_radius_m, g.lead_m, g.pitch_radius_m)
        loop = 2.0 * math.pi * tr.loaded_turns
        if tr.n_balls * separation >= loop:
            fit = math.ceil(loop / separation) - 1
            raise ConfigError(
                f"{path}.track.n_balls: {tr.n_balls} balls need "
                f"{math.degrees(tr.n_balls * separation):.1f} deg of track, more than the "
                f"{math.degrees(loop):.1f} deg of {path}.track.loaded_turns = "
                f"{tr.loaded_turns:g}; at most {fit} fit")
