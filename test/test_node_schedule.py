"""
friction_node: runtime parameter changes keep what they should.

In-process under rclpy (test_node_servo.Probe), one input at a time.
"""

import math

from rclpy.parameter import Parameter
from test_node_servo import Probe

from bb_friction_ros.config import bundled_config
from bb_friction_ros.empirical_terms import load_terms
from bb_friction_ros.model_file import read_model_file, write_model_file


def _drift_model(tmp_path):
    section, _ = read_model_file(bundled_config("ball_screw.yaml"))
    terms = load_terms([{"name": "thermal_drift",
                         "params": {"delta_torque_nm": 0.5, "time_constant_s": 2.0}}])
    return str(write_model_file(tmp_path / "drift.yaml", section, terms))


def test_runtime_rebuild_keeps_the_terms_clock_and_a_lowered_limit_refuses_the_held_load(
        ros_context, tmp_path):
    """
    A thermal_drift term 5 s into a run keeps its value across a model_rate_hz change (it
    dropped to 0 N m); lowering max_axial_load_n below the held load refuses the next sample
    (it was answered at the old load).
    """
    probe = Probe(ros_context, {"config_file": _drift_model(tmp_path)})
    node = probe.node
    try:
        probe.load(5000.0)
        w = 2 * math.pi
        for k in range(11):
            probe.state(100.0 + 0.5 * k, w * 0.5 * k, w)
        before = probe.preds[-1].torque_empirical_nm
        assert before > 0.4
        assert node.set_parameters([Parameter("model_rate_hz", value=200.0)])[0].successful
        probe.state(105.5, w * 5.5, w)
        assert probe.preds[-1].torque_empirical_nm >= before
        values = node.diagnostics_values(advance=False)[0]
        assert values["term_restarts"] == 0
        assert node.set_parameters([Parameter("max_axial_load_n", value=1000.0)])[0].successful
        n = len(probe.preds)
        msg = probe.JointState(name=["nut_joint"], position=[w * 6.0], velocity=[w])
        msg.header.stamp.sec = 106
        probe.pub_state.publish(msg)
        probe._until(lambda: node.diagnostics_values(advance=False)[0].get(
            "rejected_absurd_load", 0) == 1)
        assert len(probe.preds) == n
    finally:
        probe.close()
