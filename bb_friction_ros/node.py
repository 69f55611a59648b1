"""
ROS 2 node ``friction_node``: predicted ball-screw friction torque for a motion controller.

A thin shell: parameters, subscriptions, publishers, diagnostics.  Who answers an input and
when (steps, falling behind, shedding, the look-ahead profile, counters, health) is
``live.LiveSchedule``, ROS-free; ``ros_inputs.InputTaker`` takes the inputs off the wire.
Every sample reaches the ``runner.ModelRunner`` replay uses, in arrival order, so live
equals replay.  Topics, types and QoS: ``interface.py``; subscribes ``nut_state``,
``axial_load``; publishes ``friction/prediction`` (the input's stamp),
``friction/feedforward`` (Float64MultiArray [torque], the ros2_control forward-command
convention; the runner's safe value), ``friction/feedforward_profile`` (once per model
period), ``friction/contact_groups`` (on change, at ``groups_rate_hz``), ``/diagnostics``.
"""

import concurrent.futures
import dataclasses
import sys
import time

from bb_friction_msgs.msg import (ContactGroup, ContactGroupStatus, FeedforwardProfile,
                                  FrictionPrediction)
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from bb_friction_ros import interface
from bb_friction_ros.config import BBFrictionError, bundled_config, ConfigError
from bb_friction_ros.live import LiveSchedule, Outputs, process_age_s, process_cpu_s
from bb_friction_ros.node_parameters import (MODEL_PARAMETERS, NODE_NAME, node_parameters,
                                             NodeParameters, ros_type, RUNTIME,
                                             unknown_parameters)
from bb_friction_ros.planned import planned_feedforward, PlannedSettings, \
    PlannedTrajectoryError, trajectory_rows
from bb_friction_ros.ros_inputs import InputTaker
from bb_friction_ros.runner import build_runner, InputAssembler

GIL_SWITCH_INTERVAL_S = NodeParameters().gil_switch_interval_s


def _descriptor(f):
    """ROS descriptor of a NodeParameters field: its meaning, unit and range."""
    meta = f.metadata
    unit = "" if meta["unit"] in (None, "1") else f" [{meta['unit']}]"
    desc = ParameterDescriptor(description=meta["doc"] + unit)
    kind = ros_type(f)
    if kind is float:
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(meta["lo"]), to_value=float(meta["hi"]), step=0.0)]
    elif kind is int:
        desc.integer_range = [IntegerRange(from_value=int(meta["lo"]), to_value=int(meta["hi"]),
                                           step=1)]
    return desc


PARAMETERS = {f.name: (f.default, _descriptor(f))     # name: (default, descriptor)
              for f in dataclasses.fields(NodeParameters)}


def _model_file(params):
    return params.config_file or bundled_config("ball_screw.yaml")


def _joint_state(msg):
    s = msg.header.stamp        # (stamp [s], names, positions, velocities)
    return s.sec + 1e-9 * s.nanosec, msg.name, msg.position, msg.velocity


class FrictionNode(Node):
    """Live friction prediction; see the module docstring for topics."""

    def __init__(self, **kwargs):
        """Declare parameters, build the model (refuse a bad config), start the threads."""
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, desc) in PARAMETERS.items():
            try:
                self.declare_parameter(name, default, desc)
            except Exception as exc:   # rclpy raises several types for a bad override
                raise ConfigError(f"{NODE_NAME}.{name}: {exc}") from exc
        p = node_parameters({name: self.get_parameter(name).value for name in PARAMETERS})
        sys.setswitchinterval(p.gil_switch_interval_s)    # process-wide (parameter's doc)
        # rclpy keeps the overrides it was given (params file, -p) here; no public getter
        self.unknown_parameters = unknown_parameters(getattr(self, "_parameter_overrides", {}))
        for name in self.unknown_parameters:
            self.get_logger().warning(f"unknown parameter {name!r} ignored (known: "
                                      f"{', '.join(PARAMETERS)})")
        self._pending = None    # (parameters, runner, names) validated, applied after the set
        self._other_publishers = {}
        # our own values are floats: no per-field checks; a pair per answering thread
        self._out = [(FrictionPrediction(check_fields=False),
                      Float64MultiArray(data=[0.0], check_fields=False)) for _ in range(2)]
        depth = interface.OUTPUT_QOS_DEPTH
        self._pub_pred = self.create_publisher(FrictionPrediction, interface.PREDICTION, depth)
        self._pub_groups = self.create_publisher(ContactGroupStatus, interface.CONTACT_GROUPS,
                                                 depth)
        self._pub_ff = self.create_publisher(Float64MultiArray, interface.FEEDFORWARD, depth)
        self._pub_profile = self.create_publisher(FeedforwardProfile, interface.PROFILE, depth)
        self._pub_diag = self.create_publisher(DiagnosticArray, interface.DIAGNOSTICS, depth)
        self._pub_planned = self.create_publisher(JointTrajectory,
                                                  interface.PLANNED_FEEDFORWARD, depth)
        # a plan is computed in a thread of its own: the executor keeps serving meanwhile
        self._planner = concurrent.futures.ThreadPoolExecutor(1, "friction_planner")
        self.planned = {"received": 0, "published": 0, "rejected": 0, "last_error": ""}
        self.live = LiveSchedule(
            build_runner(_model_file(p), *p.schedule(),
                         b2b_feedforward=p.b2b_feedforward),
            InputAssembler(p.nut_joint, p.max_axial_load_n), p,
            Outputs(answer=self._answer, groups=self._publish_groups,
                    profile=self._publish_profile,    # log: level "info", "warning", ...
                    log=lambda level, text: getattr(self.get_logger(), level)(text)))
        # sensor-data semantics (best effort, volatile); inputs wait here while we step
        qos = QoSProfile(depth=p.queue_size, durability=DurabilityPolicy.VOLATILE,
                         reliability=(ReliabilityPolicy.RELIABLE if p.reliable_qos
                                      else ReliabilityPolicy.BEST_EFFORT))
        self._inputs = (   # the executor's callbacks serve only if InputTaker falls back
            self.create_subscription(WrenchStamped, interface.AXIAL_LOAD, self._on_axial_load,
                                     qos),
            self.create_subscription(JointState, interface.NUT_STATE,
                                     lambda msg: self._on_nut_state(msg, time.time_ns()), qos))
        self.create_subscription(JointTrajectory, interface.PLANNED_TRAJECTORY,
                                 self._on_planned_trajectory, depth)
        self._groups_timer = self.create_timer(1.0 / p.groups_rate_hz, self.live.publish_groups)
        self.create_timer(1.0 / p.diagnostics_rate_hz, self._publish_diagnostics)
        # rclpy's pattern: validate in the on-set callback, apply in the post-set one
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.live.start()
        self._taker = InputTaker(self, *self._inputs, self._on_axial_load, self._on_nut_state,
                                 self.live)
        self.live.defer_to_idle = self._taker.fast      # it flushes only on the fast path
        age = process_age_s()
        self.get_logger().info("ready: model built and warm" + (
            f", {age:.2f} s after launch" if age is not None else "")
            + f" ({process_cpu_s():.2f} s of CPU)")

    # --- inputs and outputs (the schedule is live.LiveSchedule) ----------------------------
    def _on_nut_state(self, msg, recv_ns, newest=None):
        # newest: a later nut_state already taken (InputTaker), for the hand-off rule
        self.live.on_nut_state(*_joint_state(msg), recv_ns, msg.header.stamp,
                               False if newest is None else _joint_state(newest))

    def _on_axial_load(self, msg):
        self.live.on_axial_load(msg.wrench.force.z)

    def _on_planned_trajectory(self, msg):
        self.planned["received"] += 1
        self._planner.submit(self._plan, msg)

    def _plan(self, msg):
        """Publish the plan's points with the friction torque in ``effort`` (planned.py)."""
        try:
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            if stamp == 0.0:        # joint_trajectory_controller: a stamp of 0 starts now
                stamp = self.get_clock().now().nanoseconds * 1e-9
            p = self.live.params
            t, phi, w, j = trajectory_rows(
                msg.joint_names, [pt.time_from_start.sec + 1e-9 * pt.time_from_start.nanosec
                                  for pt in msg.points],
                [pt.positions for pt in msg.points], [pt.velocities for pt in msg.points],
                p.nut_joint, stamp)
            load = self.live.held_load_n
            if load is None:
                raise PlannedTrajectoryError("no axial_load received yet")
            ff = planned_feedforward(t, phi, w, load, _model_file(p), PlannedSettings(
                model_step_deg=p.model_step_deg, b2b_feedforward=p.b2b_feedforward))
        except (BBFrictionError, ValueError) as exc:
            self.planned["rejected"] += 1
            self.planned["last_error"] = str(exc)
            self.get_logger().warning(f"{interface.PLANNED_TRAJECTORY}: refused: {exc}")
            return
        out = JointTrajectory(header=msg.header, joint_names=list(msg.joint_names))
        for k, pt in enumerate(msg.points):
            effort = [0.0] * len(msg.joint_names)
            effort[j] = float(ff.torque_ff_nm[k])
            out.points.append(JointTrajectoryPoint(
                positions=list(pt.positions), velocities=list(pt.velocities),
                accelerations=list(pt.accelerations), effort=effort,
                time_from_start=pt.time_from_start))
        self._pub_planned.publish(out)
        self.planned["published"] += 1

    def _answer(self, pred, stamp, latency_s, thread):
        """Publish prediction and feedforward in the thread's own reused pair (~60 us saved)."""
        msg, ff = self._out[thread]
        msg.header.stamp = stamp
        for name, value in zip(interface.PREDICTION_FIELDS,
                               interface.prediction_values(pred, latency_s)):
            setattr(msg, name, value)
        ff.data[0] = pred.feedforward_nm
        self._pub_pred.publish(msg)
        self._pub_ff.publish(ff)

    def _publish_profile(self, sample, stamp, angles, torques, converged):
        self._pub_profile.publish(FeedforwardProfile(
            header=Header(stamp=stamp), nut_angle_rad=angles, torque_total_nm=torques,
            nut_velocity_rad_s=sample.nut_velocity_rad_s, axial_load_n=sample.axial_load_n,
            converged=converged))

    def _publish_groups(self, pred, stamp):
        msg = ContactGroupStatus()
        msg.header.stamp = stamp
        msg.nut_angle_rad = pred.nut_angle_rad
        msg.n_balls = pred.n_balls
        msg.groups = [ContactGroup(ball_ids=[int(i) for i in ids],
                                   b2b_forces_n=[float(f) for f in forces])
                      for ids, forces in pred.groups]
        self._pub_groups.publish(msg)

    def diagnostics_values(self, advance=True):
        """Return (the diagnostics key/values, converged); ``advance`` starts a new window."""
        values, _, converged = self.live.values(advance)
        for topic, n in sorted(self._other_publishers.items()):
            values[f"publishers_{topic}"] = n
        if self.unknown_parameters:
            values["unknown_parameters"] = ",".join(self.unknown_parameters)
        values["fast_inputs"] = self._taker.fast
        for key, value in self.planned.items():     # friction/planned_trajectory's counts
            values[f"planned_{key}"] = value
        return values, converged

    def check_other_publishers(self):
        """Return {output topic: publishers} where not only us; warn once per change."""
        found = {}
        for pub in (self._pub_pred, self._pub_ff, self._pub_profile, self._pub_groups):
            n = self.count_publishers(pub.topic_name)
            if n > 1:
                found[pub.topic_name] = n
        if found != self._other_publishers:
            for topic, n in sorted(found.items()):
                # two nodes on one domain: a controller gets two answers per input
                self.get_logger().warning(
                    f"{n} publishers on {topic}: another friction_node on this domain? "
                    "A controller would get two answers per input.")
        self._other_publishers = found
        return found

    def _publish_diagnostics(self):
        notes = [f"{n} publishers on {topic} (another friction_node?)"
                 for topic, n in sorted(self.check_other_publishers().items())]
        if self.unknown_parameters:
            notes.append("unknown parameters ignored: " + ", ".join(self.unknown_parameters))
        if not self._taker.fast:
            notes.append("inputs taken by the executor (slower): rclpy lacks "
                         + ", ".join(self._taker.missing))
        level, message, values = self.live.status(notes)
        values["fast_inputs"] = self._taker.fast
        # the fully qualified name: namespaced nodes stay apart
        status = DiagnosticStatus(name=f"{self.get_fully_qualified_name()}: friction model",
                                  hardware_id="ball_screw", level=bytes([level]),
                                  message=message)
        status.values = [KeyValue(key=k, value=f"{v:.6g}" if isinstance(v, float) else str(v))
                         for k, v in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._pub_diag.publish(msg)

    # --- parameters -----------------------------------------------------------------------
    def _on_set_parameters(self, params):
        """Validate a parameter change (types, ranges, the model file); change nothing."""
        self._pending = None
        for prm in params:
            if prm.name not in RUNTIME:
                return SetParametersResult(successful=False,
                                           reason=f"{prm.name}: not changeable at runtime")
        updates = {prm.name: prm.value for prm in params}
        current = {name: self.get_parameter(name).value for name in PARAMETERS}
        try:
            new = node_parameters(updates, node_parameters(current))
            runner = None
            if MODEL_PARAMETERS & updates.keys():
                runner = build_runner(_model_file(new), *new.schedule(),
                                      b2b_feedforward=new.b2b_feedforward)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        except Exception as exc:     # a model that cannot be built: refused, node lives
            return SetParametersResult(successful=False,
                                       reason=f"config_file: cannot build the model ({exc!r})")
        self._pending = (new, runner, set(updates))
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params):
        """Apply the change validated by _on_set_parameters."""
        if self._pending is None:
            return
        new, runner, changed = self._pending
        self._pending = None
        self.live.apply(new, runner)
        if "gil_switch_interval_s" in changed:
            sys.setswitchinterval(new.gil_switch_interval_s)
        if "groups_rate_hz" in changed:
            self._groups_timer.timer_period_ns = int(1e9 / new.groups_rate_hz)

    def destroy_node(self):
        """Stop the input and model threads, then destroy the node."""
        taken = self._taker.stop()
        self.live.stop()
        self._planner.shutdown(wait=True, cancel_futures=True)
        if taken:
            for sub in self._inputs:
                sub.destroy()
        return super().destroy_node()


def main(args=None, on_spin=None):
    """Run friction_node (entered through ``node_entry.main``: console script and CLI)."""
    # A signal may come at any moment of start-up (loading numba and the friction maps takes
    # ~1 s): before rclpy.init its handlers do not exist, and after it they shut the context
    # down under a half-built node (RCLError "context is invalid").  The entry point
    # (node_entry.main) turns SIGTERM into a KeyboardInterrupt before importing this module;
    # both end here, cleanly.
    node = None
    try:
        try:
            rclpy.init(args=args)
        except KeyboardInterrupt:
            raise
        except Exception as exc:       # e.g. an unreadable --params-file
            hint = interface.ros_log_dir_problem()
            print(f"{NODE_NAME}: cannot start: {exc}" + (f" ({hint})" if hint else ""),
                  file=sys.stderr)
            return 2
        try:
            node = FrictionNode()
        except ConfigError as exc:
            print(f"{NODE_NAME}: config error: {exc}", file=sys.stderr)
            return 2
        except Exception:
            if rclpy.ok():
                raise
            return 0            # the context was shut down by a signal during start-up
        if on_spin is not None:
            on_spin()           # node_entry: from here a signal shuts down in order
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        try:
            if node is not None:
                node.destroy_node()
        finally:
            rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
