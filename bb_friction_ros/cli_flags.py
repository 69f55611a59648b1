"""Command-line flags shared by several ``bb-friction`` sub-commands (replay, discrepancy)."""

from bb_friction_ros import interface
from bb_friction_ros.bag_types import Topics


def add_topic_arguments(parser):
    """Add the flags naming a recording's topics to ``parser`` (``topics_from_args``)."""
    parser.add_argument("--nut-state-topic", default=interface.NUT_STATE,
                        help="nut state topic (sensor_msgs/JointState); a bag recorded "
                        "under a namespace needs its full name, e.g. /robot/nut_state")
    parser.add_argument("--axial-load-topic", default=interface.AXIAL_LOAD,
                        help="axial load topic (geometry_msgs/WrenchStamped force.z), "
                        "e.g. /robot/axial_load")
    parser.add_argument("--measured-topic", default=interface.MEASURED_TORQUE,
                        help="measured torque topic (geometry_msgs/WrenchStamped "
                        "torque.z)")


def topics_from_args(args):
    """Return the Topics named by ``add_topic_arguments``' flags."""
    return Topics(nut_state=args.nut_state_topic, axial_load=args.axial_load_topic,
                  measured_torque=args.measured_topic)
