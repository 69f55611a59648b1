"""
The parameters of ``friction_node``: one definition for the node and for replay.

Each parameter is a ``config.field`` with its default, unit, meaning and range.  The node
derives its ROS parameter descriptors from them (``node.PARAMETERS``); ``bb-friction replay``
and the discrepancy workflow take the same dataclass, so a value the node refuses is refused
offline too, with the same message.  Types are checked as ROS checks them: a ``double``
parameter refuses the integer ``100``, an ``integer`` one refuses ``256.0``.  No rclpy here.
"""

import dataclasses

from bb_friction_ros.config import check_choice, ConfigError, field, load_yaml, validate

NODE_NAME = "friction_node"

_ROS_TYPES = {bool: "a bool", int: "an integer", float: "a double", str: "a string"}
# The B2B torque the feedforward carries: the model state's own ("model"), or its mean over
# the balls' arrangements ("averaged", ball_screw/arrangement.py: the machine never sees the
# arrangement, and a ripple of the wrong phase made tracking worse than no model of it).
B2B_MODEL, B2B_AVERAGED = "model", "averaged"
B2B_FEEDFORWARDS = (B2B_AVERAGED, B2B_MODEL)


@dataclasses.dataclass(frozen=True)
class NodeParameters:
    """ROS parameters of friction_node (validated on construction)."""

    config_file: str = field("", None, "model file: ball-screw YAML, optionally with "
                             "empirical_terms (empty: the bundled config/ball_screw.yaml)")
    nut_joint: str = field("nut_joint", None, "name of the nut joint in nut_state")
    model_rate_hz: float = field(100.0, "Hz", "least whole-screw model steps per second of "
                                 "input time (the floor when the nut creeps or stands)",
                                 lo=1.0, hi=2000.0)
    model_step_deg: float = field(1.8, "deg", "nut rotation between whole-screw model steps "
                                  "(bench/bench_convergence.py)", lo=0.05, hi=90.0)
    max_model_step_deg: float = field(14.4, "deg", "coarsest step the live model takes when "
                                      "it cannot keep up (counted in diagnostics)", lo=0.05,
                                      hi=360.0)
    step_after_answer_fraction: float = field(0.5, "1", "a step due at an input at most "
                                              "this fraction of a model step of nut rotation "
                                              "past the input before is taken after that "
                                              "input is answered, from the state before the "
                                              "step (lower latency; 0: every due step before "
                                              "its answer; docs/model_schedule.md)",
                                              lo=0.0, hi=1.0)
    queue_size: int = field(256, "1", "inputs waiting for the model thread, and the depth "
                            "of the input subscriptions; when full the oldest is dropped "
                            "(newest wins)", lo=1, hi=100000)
    groups_rate_hz: float = field(10.0, "Hz", "contact-group status rate", lo=0.1, hi=1000.0)
    diagnostics_rate_hz: float = field(1.0, "Hz", "diagnostics rate", lo=0.1, hi=100.0)
    input_timeout_s: float = field(1.0, "s", "diagnostics go to ERROR when no nut_state "
                                   "arrived for this long", lo=0.01, hi=3600.0)
    model_rate_tolerance: float = field(0.1, "1", "diagnostics WARN when the model stepped "
                                        "less than (1 - this) times its configured floor "
                                        "(diagnostic_updater's FrequencyStatus tolerance)",
                                        lo=0.0, hi=0.9)
    max_axial_load_n: float = field(1.0e5, "N", "loads above this are rejected as absurd",
                                    lo=1.0, hi=1.0e7)
    reliable_qos: bool = field(False, None, "inputs with reliable QoS instead of the "
                               "sensor-data profile")
    max_answer_age_s: float = field(0.02, "s", "largest age of an answer, from the input's "
                                    "arrival to publication; older answers are shed and "
                                    "counted", lo=1e-4, hi=10.0)
    max_backlog_s: float = field(0.005, "s", "age of the oldest input waiting for the "
                                 "model thread beyond which it skips that input's step "
                                 "(the schedule turns coarser, counted); younger, it works "
                                 "through the queue at the configured step, so a step "
                                 "pipelined behind one input is no backlog (0: skip "
                                 "whenever the newest waiting input would be due again; "
                                 "never more than max_answer_age_s)",
                                 lo=0.0, hi=10.0)
    profile_horizon_periods: float = field(2.0, "1", "look-ahead profile length in model "
                                           "periods of motion", lo=2.0, hi=20.0)
    profile_points: int = field(3, "1", "points of the look-ahead profile (the first is the "
                                "step's own angle)", lo=2, hi=64)
    b2b_feedforward: str = field(B2B_AVERAGED, None, "the B2B torque in the feedforward: "
                                 "'averaged', its mean over the balls' arrangements (the "
                                 "machine never sees theirs), or 'model', the model "
                                 "state's own (a ripple tied to the arrangement the model "
                                 "assumed at its reset); the prediction keeps the state's")
    gil_switch_interval_s: float = field(2.5e-4, "s", "how long a Python thread of the node "
                                         "runs before another may take the interpreter "
                                         "(sys.setswitchinterval; CPython's default 5 ms lets "
                                         "the model thread hold an answer that long)",
                                         lo=1e-5, hi=0.1)

    def __post_init__(self):
        """Refuse a wrong type or an out-of-range value, naming the parameter."""
        for f in dataclasses.fields(self):
            check_type(f"{NODE_NAME}.{f.name}", f, getattr(self, f.name))
        validate(self, NODE_NAME)

    def schedule(self, answer_first=True):
        """
        Return the runner's schedule settings, in ``runner.build_runner``'s order.

        (model_rate_hz, model_step_deg, max_model_step_deg, step_after_answer_fraction): one
        list for the node, replay and the discrepancy workflow.  ``answer_first`` False sets
        the last to 0 (every due step before its answer): the discrepancy workflow's trials
        of physical parameters, which compare a parameter's effect between runs at the
        same angles and at a 4x coarser step, where the rule's lag (up to that fraction of
        the coarse step in nut angle) would blur the comparison.  The lag is the live
        node's latency trade, not physics to fit.
        """
        return (float(self.model_rate_hz), float(self.model_step_deg),
                float(self.max_model_step_deg),
                float(self.step_after_answer_fraction) if answer_first else 0.0)

    def check(self, path):
        """Refuse an empty ``nut_joint``: it matches no joint, so every input is rejected."""
        if not self.nut_joint.strip():
            raise ConfigError(f"{path}.nut_joint: must be a non-empty joint name, got "
                              f"{self.nut_joint!r}")
        check_choice(f"{path}.b2b_feedforward", self.b2b_feedforward, B2B_FEEDFORWARDS)
        if self.max_model_step_deg < self.model_step_deg:
            raise ConfigError(f"{path}.max_model_step_deg: must be >= model_step_deg = "
                              f"{self.model_step_deg:g} deg, got {self.max_model_step_deg:g}")


# Changeable while the node runs; a change of a MODEL_PARAMETERS one rebuilds the model.
RUNTIME = frozenset({"nut_joint", "model_rate_hz", "groups_rate_hz", "max_axial_load_n",
                     "config_file", "max_answer_age_s", "max_backlog_s",
                     "profile_horizon_periods", "profile_points", "model_step_deg",
                     "max_model_step_deg", "input_timeout_s", "model_rate_tolerance",
                     "gil_switch_interval_s", "step_after_answer_fraction",
                     "b2b_feedforward"})
MODEL_PARAMETERS = frozenset({"config_file", "model_rate_hz", "model_step_deg",
                              "max_model_step_deg", "step_after_answer_fraction",
                              "b2b_feedforward"})
FIELDS = {f.name: f for f in dataclasses.fields(NodeParameters)}
# declared by rclpy itself for every node: in a params file, neither ours nor unknown
ROS_BUILTIN_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service"})


def unknown_parameters(names):
    """Return, sorted, the names that are neither the node's parameters nor ROS's own."""
    return sorted(set(names) - set(FIELDS) - ROS_BUILTIN_PARAMETERS)


def ros_type(f):
    """Return the Python type of a parameter's ROS type (bool, int, float or str)."""
    return type(f.default)


def check_type(path, f, value):
    """Refuse ``value`` unless it has the parameter's ROS type (bool is not an integer)."""
    want = ros_type(f)
    if type(value) is not want:
        raise ConfigError(f"{path}: expected {_ROS_TYPES[want]} ({f.metadata['doc']}), "
                          f"got {value!r}")


def node_parameters(values, base=NodeParameters()):
    """
    Return ``base`` with the parameters in mapping ``values`` changed (validated).

    Names that are not parameters of the node are refused.
    """
    for name in values:
        if name not in FIELDS:
            raise ConfigError(f"{NODE_NAME}.{name}: not a parameter of {NODE_NAME} (known: "
                              f"{', '.join(FIELDS)})")
    return dataclasses.replace(base, **values)


def load_params_file(path, on_unknown=None):
    """
    Return the NodeParameters of a ROS params file (``friction_node: ros__parameters:``).

    Other nodes' sections and ROS's own parameters (``use_sim_time``...) are ignored, as
    the node ignores them; a value of the node is checked exactly as the node checks it.
    ``on_unknown(name)`` is called for each other name in the node's section (a misspelt
    parameter; the node warns about it too).
    """
    data = load_yaml(path)
    params = {}
    for key, section in data.items():
        if isinstance(key, str) and key.lstrip("/").endswith(NODE_NAME) \
                and isinstance(section, dict):
            params = section.get("ros__parameters") or {}
            if not isinstance(params, dict):
                raise ConfigError(f"{path}: {key}.ros__parameters: expected a mapping, got "
                                  f"{type(params).__name__}")
    if on_unknown is not None:
        for name in unknown_parameters(params):
            on_unknown(name)
    return node_parameters({k: v for k, v in params.items() if k in FIELDS})
