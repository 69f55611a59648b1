"""
The ROS interface of ``friction_node``, written once: topics, message types, QoS, field order.

Used by the node, replay (its output bag), bags (the input topics of a recording), the test
harness, the tests and the benches, so a topic or a field cannot differ between them.  No
rclpy here: QoS is given as plain values that the node turns into a ``QoSProfile``.

Topic names are relative (resolved in the node's namespace, as ``ros2 run ... -r`` remaps
them); ``/diagnostics`` is absolute, as diagnostic_aggregator expects.
"""

import os

# --- topics ---------------------------------------------------------------------------------
# Inputs
NUT_STATE = "nut_state"
AXIAL_LOAD = "axial_load"
# A recording's measured torque (replay, discrepancy); not subscribed by the node.
MEASURED_TORQUE = "measured_torque"
# Outputs
PREDICTION = "friction/prediction"
FEEDFORWARD = "friction/feedforward"
PROFILE = "friction/feedforward_profile"
CONTACT_GROUPS = "friction/contact_groups"
DIAGNOSTICS = "/diagnostics"
# Feedforward along a planned trajectory: in, the plan; out, the same points with the
# predicted friction torque in ``effort`` [N m] (planned.planned_feedforward)
PLANNED_TRAJECTORY = "friction/planned_trajectory"
PLANNED_FEEDFORWARD = "friction/planned_feedforward"

# --- message types (ROS 2 'package/msg/Type' names) ----------------------------------------
JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
MSGS_PACKAGE = "bb_friction_msgs"
TYPES = {
    NUT_STATE: JOINT_STATE,
    AXIAL_LOAD: WRENCH_STAMPED,
    MEASURED_TORQUE: WRENCH_STAMPED,
    PREDICTION: f"{MSGS_PACKAGE}/msg/FrictionPrediction",
    FEEDFORWARD: "std_msgs/msg/Float64MultiArray",
    PROFILE: f"{MSGS_PACKAGE}/msg/FeedforwardProfile",
    CONTACT_GROUPS: f"{MSGS_PACKAGE}/msg/ContactGroupStatus",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
    PLANNED_TRAJECTORY: "trajectory_msgs/msg/JointTrajectory",
    PLANNED_FEEDFORWARD: "trajectory_msgs/msg/JointTrajectory",
}
# What the node publishes (another publisher on one of them is reported: two nodes?).
OUTPUTS = (PREDICTION, FEEDFORWARD, PROFILE, CONTACT_GROUPS, PLANNED_FEEDFORWARD)
# What replay writes into its output bag, in the node's order of publication per input;
# the profile (a wall-clock look-ahead of the model thread) is not reproduced offline.
REPLAYED_OUTPUTS = (PREDICTION, CONTACT_GROUPS, FEEDFORWARD)


def absolute(topic):
    """Return ``topic`` resolved in the root namespace (``nut_state`` -> ``/nut_state``)."""
    return topic if topic.startswith("/") else "/" + topic


# --- QoS -----------------------------------------------------------------------------------
# Inputs: sensor-data semantics (best effort, volatile) unless ``reliable_qos``; their depth
# is the node's ``queue_size`` (the sensor-data profile's depth of 5 dropped ~1 % of inputs
# at 1 kHz while the executor waited).  Outputs: reliable, volatile, rclpy's default depth.
OUTPUT_QOS_DEPTH = 10
# Depth of the harness's reliable collectors: a whole test's answers are never dropped.
COLLECTOR_QOS_DEPTH = 1000

# --- FrictionPrediction: its fields after the header, in the order of the .msg file -------
# Each is the attribute of runner.Prediction of that name, except the two the publisher
# fills: ``model_latency_s`` (wall time, input receipt to publication) and ``n_groups``
# (len(groups)).  test/test_interface.py checks this against FrictionPrediction.msg.
PREDICTION_FIELDS = ("nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_total_nm",
                     "torque_b2g_nm", "torque_b2b_nm", "torque_empirical_nm", "converged",
                     "model_latency_s", "model_age_s", "n_groups", "torque_state_nm",
                     "state_other_direction")
_FROM_PUBLISHER = ("model_latency_s", "n_groups")
PREDICTION_FROM_RUNNER = tuple(f for f in PREDICTION_FIELDS if f not in _FROM_PUBLISHER)


def prediction_values(pred, latency_s):
    """Return the FrictionPrediction fields after the header for ``pred``, in message order."""
    return (pred.nut_angle_rad, pred.nut_velocity_rad_s, pred.axial_load_n,
            pred.torque_total_nm, pred.torque_b2g_nm, pred.torque_b2b_nm,
            pred.torque_empirical_nm, bool(pred.converged), latency_s, pred.model_age_s,
            len(pred.groups), pred.torque_state_nm, bool(pred.state_other_direction))


# --- DDS isolation -------------------------------------------------------------------------
def local_domain_id(pid=None):
    """
    Return a ROS domain id of this process (1..101), away from the default domain 0.

    For tests, the demo and benches, with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: runs
    side by side on one machine do not hear each other, nor a robot on domain 0.
    """
    return 1 + (os.getpid() if pid is None else pid) % 101


# --- ROS's log directory -------------------------------------------------------------------
def ros_log_dir(environ=None):
    """Return the directory rclpy.init logs into: ROS_LOG_DIR, ROS_HOME/log or ~/.ros/log."""
    env = os.environ if environ is None else environ
    if env.get("ROS_LOG_DIR"):
        return os.path.expanduser(env["ROS_LOG_DIR"])
    home = env.get("ROS_HOME") or os.path.join(env.get("HOME") or os.path.expanduser("~"),
                                               ".ros")
    return os.path.join(os.path.expanduser(home), "log")


def ros_log_dir_problem(environ=None):
    """
    Return why rclpy.init cannot create its log directory, or None.

    rclpy.init fails with an RCLError traceback that does not say where it wanted to write
    (an unwritable HOME, a read-only container); the fix is ROS_LOG_DIR.
    """
    path = ros_log_dir(environ)
    probe = path
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            break
        probe = parent
    if os.path.isdir(probe) and os.access(probe, os.W_OK | os.X_OK):
        return None
    return (f"ROS logs go to {path}, and {probe} is not writable: set ROS_LOG_DIR to a "
            "writable directory")
