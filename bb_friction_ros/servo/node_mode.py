"""
The ``node`` mode: the real ``friction_node`` over DDS, in real time at the servo rate.

The node runs in this process on a ROS context and domain of its own
(``harness.FrictionNodeHarness``: launch-free, DDS kept on this machine).  At each servo
cycle, paced by the wall clock at the loop's rate, the controller side publishes the
measured state (encoder angle, velocity estimate, the sample's stamp) on ``nut_state``,
takes the newest ``friction/feedforward_profile`` the node has published, and reads the
torque at its measured angle with ``FeedforwardInterpolator``, as a ros2_control controller
would.  The node's answers arrive when they arrive: a cycle whose profile does not cover
its angle gets what the interpolator's rules give (0 N m when empty, stale, reversed or at
standstill; the last point beyond the profile).

The axial load is the recording's first (published once, before the run): a run whose
load varies is not fed its changes.

Coverage: the share of cycles whose measured angle lies inside a valid profile (status
``inside``); the other statuses are counted by name.  Late cycles (the simulation of one
period took longer than the period) are counted too: the run is then slower than real
time and the coverage is optimistic.

The node is given a copy of the model file without its ``inertia`` terms (in a temporary
directory), like the ``model`` mode: J alpha is the loop's acceleration
feedforward, not friction.

The ``node_planned`` mode is the ``planned`` mode through the node: the whole reference is
sent once, before the run, as a ``trajectory_msgs/JointTrajectory`` on
``friction/planned_trajectory`` (positions, velocities, times from its start), as a motion
planner hands it to ``joint_trajectory_controller``; the node's answer on
``friction/planned_feedforward`` (the same points, friction torque in ``effort``) is played
back by time with the ``planned`` mode's gate.  A standing point with a torque is a
breakaway before a planned start (the node sends nothing else at standstill).
"""

from collections import Counter
import time

import numpy as np

from bb_friction_ros import interface
from bb_friction_ros.feedforward import FeedforwardInterpolator, INSIDE
from bb_friction_ros.model_file import physics_of, read_model_file, write_model_file
from bb_friction_ros.servo.modes import Mode, PlannedMode
from bb_friction_ros.servo.plant import friction_terms

# Stamps of the node's inputs: the run's time plus this (a plausible ROS time, > 0).
STAMP_BASE_S = 1000.0
# Wait for the node's planned feedforward [s]: it steps the model along the whole reference
# (about 1 s of CPU per 10 s of reference at 1 kHz on these machines), on a shared core.
PLANNED_TIMEOUT_S = 120.0
TRAJECTORY_TYPE = "trajectory_msgs/msg/JointTrajectory"


class NodeRuns(list):
    """The AxisRuns of the node mode, with its coverage figures."""

    coverage = None


class NodeMode(Mode):
    """The controller side of the node mode (module docstring)."""

    def __init__(self, harness, period_s):
        """Talk to the node of ``harness``; pace cycles at ``period_s`` of wall time."""
        super().__init__("node")
        self.h = harness
        self.period = period_s
        self.interp = FeedforwardInterpolator()
        self.statuses = Counter()
        self.late = 0
        self.cycles = 0
        self._seen = 0
        self._wall0 = None

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Publish the measured state at its cycle's wall time; interpolate the newest profile."""
        now = time.perf_counter()
        if self._wall0 is None:
            self._wall0 = now - t_s
        due = self._wall0 + t_s
        if now < due:
            time.sleep(due - now)
        elif now - due > self.period:
            self.late += 1
        self.cycles += 1
        self.h.publish_nut_state(angle_rad, velocity_rad_s, STAMP_BASE_S + t_s, wait=False)
        profiles = self.h.profiles
        if len(profiles) > self._seen:
            msgs = profiles.messages
            try:
                self.interp.set_profile_msg(msgs[-1])
            except ValueError:
                self.statuses["malformed_profile"] += 1
            self._seen = len(msgs)
        ff = self.interp.torque_at(angle_rad, velocity_rad_s)
        self.statuses[self.interp.status] += 1
        return ff

    def coverage(self):
        """Return the coverage figures (module docstring)."""
        n = max(self.cycles, 1)
        return {"cycles": self.cycles, "coverage": self.statuses[INSIDE] / n,
                "statuses": dict(self.statuses), "late_cycles": self.late,
                "profiles": self._seen}


def friction_only_model(src, dst):
    """Write the model file ``src`` without its inertia terms to ``dst``; return ``dst``."""
    section, terms = read_model_file(src)
    physics = physics_of(src)
    return write_model_file(dst, section, friction_terms(terms),
                            physics=None if physics == "ball_screw" else physics)


def run_node_mode(setup, reference):
    """Run every axis with the node in the loop; return NodeRuns with ``coverage``."""

    def run_axis(h, i, axis):
        mode = NodeMode(h, setup.settings.loop.period_s)
        h.profiles     # subscribe before the first input
        run = setup.simulate_axis(reference, axis, mode, axis_index=i)
        return run, mode.coverage()

    return _with_node(setup, reference, "servo_node_", run_axis)


def _with_node(setup, reference, prefix, run_axis):
    """
    Run ``run_axis(harness, axis index, axis)`` -> (AxisRun, coverage) with a node per axis.

    The node gets the axis's model file without its inertia terms (in a temporary directory)
    and the ``model:`` settings, on a ROS context and domain of its own, and holds the
    recording's first axial load.  Return NodeRuns; each coverage gets the axis's name and
    the node's diagnostics at the end.
    """
    import os
    from pathlib import Path
    import tempfile
    from bb_friction_ros.harness import FrictionNodeHarness
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    runs = NodeRuns()
    cover = []
    ms = setup.settings.model
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        for i, axis in enumerate(reference.axes):
            path = setup.model_path if i == 0 or not setup.model_path_y \
                else setup.model_path_y
            model = friction_only_model(path, Path(tmp) / f"node_model_{axis.name}.yaml")
            params = {"config_file": str(model), "model_rate_hz": ms.model_rate_hz,
                      "model_step_deg": ms.model_step_deg,
                      "b2b_feedforward": ms.b2b_feedforward}
            load = setup.loads(reference, axis)
            with FrictionNodeHarness(parameters=params) as h:
                h.publish_axial_load(float(load[0]), STAMP_BASE_S)
                run, c = run_axis(h, i, axis)
                c["diagnostics"] = {k: v for k, v in h.diagnostics_values().items()
                                    if isinstance(v, (int, float, str))}
            runs.append(run)
            c["axis"] = axis.name
            cover.append(c)
    runs.coverage = cover if len(cover) > 1 else cover[0]
    return runs


def planned_trajectory_msg(t_s, angle_rad, velocity_rad_s, joint, stamp_s):
    """Return the JointTrajectory of one axis's reference (time from its first sample)."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    from bb_friction_ros.harness import stamp_msg
    msg = JointTrajectory(joint_names=[joint])
    msg.header.stamp = stamp_msg(stamp_s)
    t0 = float(t_s[0])
    for t, phi, w in zip(t_s, angle_rad, velocity_rad_s):
        ns = int(round((float(t) - t0) * 1e9))
        msg.points.append(JointTrajectoryPoint(
            positions=[float(phi)], velocities=[float(w)],
            time_from_start=Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
    return msg


def run_node_planned_mode(setup, reference):
    """Run every axis with the node's planned feedforward of its reference (module doc)."""
    from bb_friction_ros.harness import message_class
    t = reference.t_s

    def run_axis(h, i, axis):
        w_ref = axis.ref_velocity(t)
        answers = h.collect(interface.PLANNED_FEEDFORWARD, TRAJECTORY_TYPE)
        joint = h.node.get_parameter("nut_joint").value
        pub = h.io.create_publisher(message_class(TRAJECTORY_TYPE),
                                    interface.PLANNED_TRAJECTORY, 1)
        deadline = time.monotonic() + PLANNED_TIMEOUT_S
        while pub.get_subscription_count() == 0:    # a message before the match is lost
            if time.monotonic() > deadline:
                raise TimeoutError(f"{interface.PLANNED_TRAJECTORY}: the node's "
                                   "subscription was not matched")
            time.sleep(0.01)
        wall0 = time.perf_counter()
        pub.publish(planned_trajectory_msg(t, axis.ref_rad, w_ref, joint,
                                           STAMP_BASE_S + float(t[0])))
        answers.wait_for(1, timeout_s=PLANNED_TIMEOUT_S)
        latency = time.perf_counter() - wall0
        ff = np.array([pt.effort[0] for pt in answers.messages[-1].points], dtype=float)
        if ff.size != t.size:
            raise RuntimeError(f"{interface.PLANNED_FEEDFORWARD}: {ff.size} points for a "
                               f"trajectory of {t.size}")
        breakaway = (w_ref == 0.0) & (ff != 0.0)
        mode = PlannedMode("node_planned", t, ff, w_ref, breakaway)
        run = setup.simulate_axis(reference, axis, mode, axis_index=i)
        return run, {"points": int(ff.size), "answer_latency_s": latency}

    return _with_node(setup, reference, "servo_node_planned_", run_axis)
