"""
The thinnest rclpy node with friction_node's interface: the baseline of bench/bench_node.py.

It subscribes to ``nut_state`` (same QoS as friction_node) and answers every sample with a
``bb_friction_msgs/FrictionPrediction`` that carries the input stamp, and does nothing else
(no model, no validation, no feedforward).  Whatever friction_node costs beyond this node is
what the friction model and its bookkeeping cost.

Run: .venv/bin/python bench/thin_node.py   (Ctrl-C or SIGTERM stops it)
"""

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from bb_friction_msgs.msg import FrictionPrediction
from sensor_msgs.msg import JointState

from bb_friction_ros import interface


class ThinNode(Node):
    """Answer each nut_state with a FrictionPrediction of the same stamp."""

    def __init__(self):
        """Publisher and subscription only."""
        super().__init__("thin_friction_node")
        qos = QoSProfile(depth=256, durability=DurabilityPolicy.VOLATILE,
                         reliability=ReliabilityPolicy.BEST_EFFORT)
        self._pub = self.create_publisher(FrictionPrediction, interface.PREDICTION,
                                          interface.OUTPUT_QOS_DEPTH)
        self.create_subscription(JointState, interface.NUT_STATE, self._on_state, qos)

    def _on_state(self, msg):
        out = FrictionPrediction()
        out.header.stamp = msg.header.stamp
        self._pub.publish(out)


def main():
    """Spin until SIGINT/SIGTERM (rclpy's own signal handlers shut the context down)."""
    rclpy.init()
    node = None
    try:        # a signal may come as soon as the subscription exists (bench_startup)
        node = ThinNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
