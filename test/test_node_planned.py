"""
friction_node: a planned trajectory in (JointTrajectory), its friction feedforward out.

The same points come back on friction/planned_feedforward with the predicted friction
torque in ``effort``, equal to what ``bb-friction feedforward`` computes offline.
"""

import numpy as np
import pytest

from bb_friction_ros import interface
from bb_friction_ros.config import bundled_config
from bb_friction_ros.planned import planned_feedforward, PlannedTrajectoryError, \
    trajectory_rows

STAMP_S = 100.0


def _trajectory(n=80, dt=0.002, joints=("x_axis", "nut_joint")):
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    t = np.arange(n) * dt
    w = 2 * np.pi * np.sin(2 * np.pi * t / (n * dt))      # out and back
    phi = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)))
    msg = JointTrajectory(joint_names=list(joints))
    msg.header.stamp.sec = int(STAMP_S)
    j = joints.index("nut_joint")
    for k in range(n):
        pos, vel = [0.0] * len(joints), [0.0] * len(joints)
        pos[j], vel[j] = float(phi[k]), float(w[k])
        sec = int(t[k])
        msg.points.append(JointTrajectoryPoint(
            positions=pos, velocities=vel,
            time_from_start=Duration(sec=sec, nanosec=int(round((t[k] - sec) * 1e9)))))
    return msg, STAMP_S + t, phi, w


def test_planned_trajectory_comes_back_with_the_friction_in_effort():
    from bb_friction_ros.harness import FrictionNodeHarness
    msg, t, phi, w = _trajectory()
    with FrictionNodeHarness() as h:
        out = h.collect(interface.PLANNED_FEEDFORWARD, interface.TYPES[
            interface.PLANNED_FEEDFORWARD])
        h.publish_axial_load(1500.0, stamp_s=STAMP_S - 1.0)
        pub = h.io.create_publisher(type(msg), interface.PLANNED_TRAJECTORY, 10)
        got = None
        for _ in range(50):             # until the subscription has matched
            pub.publish(msg)
            try:
                got = out.wait_for(1, timeout_s=0.2)[0]
                break
            except TimeoutError:
                continue
        assert got is not None, "no planned feedforward"
        assert list(got.joint_names) == ["x_axis", "nut_joint"]
        effort = np.array([p.effort[1] for p in got.points])
        assert all(p.effort[0] == 0.0 for p in got.points)
        offline = planned_feedforward(t, phi, w, 1500.0, bundled_config("ball_screw.yaml"))
        assert np.array_equal(effort, offline.torque_ff_nm)
        assert np.all(effort[w != 0.0] * w[w != 0.0] > 0.0)
        assert h.node.planned["published"] >= 1 and h.node.planned["rejected"] == 0


def test_trajectory_rows_name_what_is_missing():
    with pytest.raises(PlannedTrajectoryError, match="no joint named 'nut_joint'"):
        trajectory_rows(["a"], [0.0], [[0.0]], [[0.0]], "nut_joint", 0.0)
    with pytest.raises(PlannedTrajectoryError, match="point 1: 1 positions for 2 joints"):
        trajectory_rows(["a", "nut_joint"], [0.0, 0.1], [[0.0, 0.0], [0.0]], [], "nut_joint",
                        0.0)
    # points without velocities: differences of the positions in time
    t, phi, w, j = trajectory_rows(["nut_joint"], [0.0, 0.1, 0.2], [[0.0], [0.1], [0.2]], [],
                                   "nut_joint", 5.0)
    assert j == 0 and list(t) == pytest.approx([5.0, 5.1, 5.2]) and w == pytest.approx(1.0)
