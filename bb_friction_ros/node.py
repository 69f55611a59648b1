"""
ROS 2 node ``friction_node``: predicted ball-screw friction torque for a motion controller.

The only module that imports rclpy.  A thin shell: messages -> ``runner`` (pure core) ->
messages.  Callbacks validate and enqueue; a background thread runs the whole-screw model
and publishes, so no callback ever waits for physics.

Subscribes: ``nut_state`` (sensor_msgs/JointState, joint ``nut_joint``), ``axial_load``
(geometry_msgs/WrenchStamped, force.z).  Publishes: ``friction/prediction``
(bb_friction_msgs/FrictionPrediction, stamped with the input stamp it answers),
``friction/contact_groups`` (bb_friction_msgs/ContactGroupStatus, on change and at
``groups_rate_hz``), ``friction/feedforward`` (std_msgs/Float64MultiArray [torque], the
ros2_control forward-command convention) and ``/diagnostics``.
"""

import collections
import dataclasses
import sys
import threading
import time

from bb_friction_msgs.msg import ContactGroup, ContactGroupStatus, FrictionPrediction
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from bb_friction_ros.config import bundled_config, ConfigError
from bb_friction_ros.node_parameters import (MODEL_PARAMETERS, NODE_NAME, node_parameters,
                                             NodeParameters, ros_type, RUNTIME)
from bb_friction_ros.runner import build_runner, InputAssembler, InputError

GIL_SWITCH_INTERVAL_S = 2.5e-4


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


class FrictionNode(Node):
    """Live friction prediction; see the module docstring for topics."""

    def __init__(self, **kwargs):
        """Declare parameters, build the model (refuse a bad config), start the model thread."""
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, desc) in PARAMETERS.items():
            try:
                self.declare_parameter(name, default, desc)
            except Exception as exc:   # rclpy raises several types for a bad override
                raise ConfigError(f"{NODE_NAME}.{name}: {exc}") from exc
        p = node_parameters({name: self.get_parameter(name).value for name in PARAMETERS})
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue = collections.deque(maxlen=p.queue_size)
        self._runner = build_runner(_model_file(p), p.model_rate_hz)
        self._assembler = InputAssembler(p.nut_joint, p.max_axial_load_n)
        self._pending = None    # (parameters, runner, names) validated, applied after the set
        self._dropped = 0
        self._received = collections.Counter()
        self._published = 0
        self._latest = None
        self._latest_stamp = None
        self._last_groups = None
        self._reset_note = ""
        self._t_start = time.monotonic()
        self._steps_at_diag = (0, self._t_start)
        self._stop = False

        # Sensor-data semantics (best effort, volatile) with the depth of our own queue: the
        # profile's depth of 5 dropped ~1 % of inputs at 1 kHz while the executor waited.
        qos = QoSProfile(depth=p.queue_size, durability=DurabilityPolicy.VOLATILE,
                         reliability=(ReliabilityPolicy.RELIABLE if p.reliable_qos
                                      else ReliabilityPolicy.BEST_EFFORT))
        self._pub_pred = self.create_publisher(FrictionPrediction, "friction/prediction", 10)
        self._pub_groups = self.create_publisher(ContactGroupStatus, "friction/contact_groups",
                                                 10)
        self._pub_ff = self.create_publisher(Float64MultiArray, "friction/feedforward", 10)
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # Load first: when both are ready in one wait, the executor serves subscriptions in
        # creation order, and a state must see the load of its own stamp (as replay does).
        self.create_subscription(WrenchStamped, "axial_load", self._on_axial_load, qos)
        self.create_subscription(JointState, "nut_state", self._on_nut_state, qos)
        self._groups_timer = self.create_timer(1.0 / p.groups_rate_hz, self._publish_groups)
        self.create_timer(1.0 / p.diagnostics_rate_hz, self._publish_diagnostics)
        # rclpy's pattern: validate in the on-set callback, apply in the post-set one
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._thread = threading.Thread(target=self._model_loop, name="friction_model",
                                        daemon=True)
        self._thread.start()

    # --- callbacks: validate and enqueue, nothing else ------------------------------------
    def _on_nut_state(self, msg):
        t_recv = time.perf_counter()
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        with self._lock:
            self._received["nut_state"] += 1
            try:
                sample = self._assembler.on_nut_state(stamp, msg.name, msg.position,
                                                      msg.velocity)
            except InputError as err:
                self._runner.reject(err.reason, nut_state=True)
                return
            if len(self._queue) == self._queue.maxlen:
                self._dropped += 1      # deque drops the oldest: the newest input wins
            # the original stamp goes out unchanged: float seconds lose ~0.2 us at epoch times
            self._queue.append((sample, t_recv, msg.header.stamp))
            self._wake.notify()

    def _on_axial_load(self, msg):
        with self._lock:
            self._received["axial_load"] += 1
            try:
                self._assembler.on_axial_load(msg.wrench.force.z)
            except InputError as err:
                self._runner.reject(err.reason)

    # --- model thread ---------------------------------------------------------------------
    def _model_loop(self):
        while True:
            with self._lock:
                while not self._queue and not self._stop:
                    self._wake.wait(timeout=0.5)
                if self._stop:
                    return
                backlog = list(self._queue)
                self._queue.clear()
                runner = self._runner
            # Every input is answered; only the newest may step the model (newest wins).
            for k, (sample, t_recv, stamp) in enumerate(backlog):
                resets = runner.stats.resets
                pred = runner.process(sample, allow_step=k == len(backlog) - 1)
                if pred is None:             # counted by the runner as model_error
                    self.get_logger().error(f"model step failed: {runner.stats.last_error}; "
                                            "state reset")
                    continue
                if runner.stats.resets != resets:
                    note = (f"input stamps went backwards at {sample.stamp_s:.6f} s: model "
                            "state reset")
                    with self._lock:
                        self._reset_note = note
                    self.get_logger().warning(note)
                self._publish_prediction(pred, t_recv, stamp)

    def _publish_prediction(self, pred, t_recv, stamp):
        msg = FrictionPrediction()
        msg.header.stamp = stamp
        msg.nut_angle_rad = pred.nut_angle_rad
        msg.nut_velocity_rad_s = pred.nut_velocity_rad_s
        msg.axial_load_n = pred.axial_load_n
        msg.torque_total_nm = pred.torque_total_nm
        msg.torque_b2g_nm = pred.torque_b2g_nm
        msg.torque_b2b_nm = pred.torque_b2b_nm
        msg.torque_empirical_nm = pred.torque_empirical_nm
        msg.converged = pred.converged
        msg.model_age_s = pred.model_age_s
        msg.n_groups = len(pred.groups)
        msg.model_latency_s = time.perf_counter() - t_recv
        self._pub_pred.publish(msg)
        self._pub_ff.publish(Float64MultiArray(data=[pred.torque_total_nm]))
        with self._lock:
            self._published += 1
            self._latest = pred
            self._latest_stamp = stamp
            changed = pred.groups != self._last_groups
        if changed:
            self._publish_groups()

    def _publish_groups(self):
        with self._lock:
            pred, stamp = self._latest, self._latest_stamp
            if pred is None:
                return
            self._last_groups = pred.groups
        msg = ContactGroupStatus()
        msg.header.stamp = stamp
        msg.nut_angle_rad = pred.nut_angle_rad
        msg.n_balls = pred.n_balls
        msg.groups = [ContactGroup(ball_ids=[int(i) for i in ids],
                                   b2b_forces_n=[float(f) for f in forces])
                      for ids, forces in pred.groups]
        self._pub_groups.publish(msg)

    def diagnostics_values(self, advance=True):
        """Return the diagnostics key/values; ``advance`` starts a new rate window."""
        with self._lock:
            stats = self._runner.stats
            now = time.monotonic()
            steps0, t0 = self._steps_at_diag
            rate = (stats.model_steps - steps0) / max(now - t0, 1e-9)
            if advance:
                self._steps_at_diag = (stats.model_steps, now)
            latest = self._latest
            values = {
                "model_rate_hz": rate,
                "model_steps": stats.model_steps,
                "last_step_s": stats.last_step_wall_s,
                "nonconverged_steps": stats.nonconverged_steps,
                "queue_length": len(self._queue),
                "skipped_inputs": self._dropped + stats.skipped_steps,
                "dropped_inputs": self._dropped,
                "published": self._published,
                "resets": stats.resets,
                "lag_s": 0.0 if latest is None else latest.model_age_s,
                "received_nut_state": self._received["nut_state"],
                "received_axial_load": self._received["axial_load"],
                "rejected_total": sum(stats.rejected.values()),
                "rejected_nut_state": stats.rejected_nut_state,
            }
            for reason, n in sorted(stats.rejected.items()):
                values[f"rejected_{reason}"] = n
            converged = latest is None or latest.converged
        return values, converged

    def _publish_diagnostics(self):
        values, converged = self.diagnostics_values()
        status = DiagnosticStatus(name=f"{self.get_name()}: friction model",
                                  hardware_id="ball_screw")
        if not converged:
            status.level, status.message = DiagnosticStatus.WARN, "solver did not converge"
        elif values["rejected_total"] or values["skipped_inputs"]:
            status.level = DiagnosticStatus.WARN
            status.message = (f"{values['rejected_total']} inputs rejected, "
                              f"{values['skipped_inputs']} skipped")
        else:
            status.level, status.message = DiagnosticStatus.OK, "ok"
        with self._lock:     # a reset is reported in the one status after it, then cleared
            note, self._reset_note = self._reset_note, ""
        if note:
            status.message += "; " + note
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
                runner = build_runner(_model_file(new), new.model_rate_hz)
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
        with self._lock:
            if runner is not None:
                # counters go on across the swap: diagnostics stay cumulative and the model
                # rate window keeps its base (a new runner's zero gave one negative rate)
                runner.stats = self._runner.stats
                self._runner = runner
            self._assembler.nut_joint = new.nut_joint
            self._assembler.max_axial_load_n = new.max_axial_load_n
        if "groups_rate_hz" in changed:
            self._groups_timer.timer_period_ns = int(1e9 / new.groups_rate_hz)

    def destroy_node(self):
        """Stop the model thread, then destroy the node."""
        with self._lock:
            self._stop = True
            self._wake.notify_all()
        self._thread.join(timeout=5.0)
        return super().destroy_node()


def _stamp_msg(stamp_s):
    from builtin_interfaces.msg import Time
    sec = int(stamp_s // 1)
    nanosec = min(int(round((stamp_s - sec) * 1e9)), 999_999_999)
    return Time(sec=sec, nanosec=nanosec)


def play_through_node(events, parameters=None, context=None, speed=1.0, settle_s=10.0,
                      lockstep=False):
    """
    Publish recorded events to an in-process FrictionNode and collect what it publishes.

    Events go out at their recorded pace divided by ``speed`` (publisher -> node ->
    subscriber, all in this process).  With ``lockstep`` each message waits until the node
    has taken it (and answered or rejected a nut state) before the next goes out: exact
    comparisons with replay then never depend on machine load.  Returns (predictions as
    Prediction-like dicts, contact-group messages, the node's diagnostics values,
    DiagnosticArray messages).
    """
    from rclpy.parameter import Parameter
    from rclpy.executors import SingleThreadedExecutor
    own = context is None
    if own:
        context = rclpy.Context()
        rclpy.init(context=context)
    switch_interval = sys.getswitchinterval()
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)      # as friction_node's main() does
    overrides = [Parameter(k, value=v) for k, v in (parameters or {}).items()]
    node = FrictionNode(context=context, parameter_overrides=overrides)
    io = Node("friction_player", context=context)
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    in_qos = reliable if node.get_parameter("reliable_qos").value else qos_profile_sensor_data
    pub_state = io.create_publisher(JointState, "nut_state", in_qos)
    pub_load = io.create_publisher(WrenchStamped, "axial_load", in_qos)
    preds, groups, diags = [], [], []
    io.create_subscription(DiagnosticArray, "/diagnostics", diags.append, reliable)
    io.create_subscription(FrictionPrediction, "friction/prediction",
                           lambda m: preds.append(_prediction_dict(m)), reliable)
    io.create_subscription(ContactGroupStatus, "friction/contact_groups", groups.append,
                           reliable)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(io)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        _wait_for_match(node, pub_state, pub_load)
        _handshake(node, pub_load, next(e for e in events if e.kind == "axial_load"))
        handshakes = node.diagnostics_values(advance=False)[0]["received_axial_load"]
        t_wall0 = time.monotonic()
        t_rec0 = None
        sent = sent_loads = 0
        for ev in events:
            if ev.kind == "measured_torque":
                continue
            t_rec0 = ev.stamp_s if t_rec0 is None else t_rec0
            delay = t_wall0 + (ev.stamp_s - t_rec0) / speed - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if ev.kind == "nut_state":
                msg = JointState(name=list(ev.names), position=list(ev.positions),
                                 velocity=list(ev.velocities))
                msg.header.stamp = _stamp_msg(ev.stamp_s)
                pub_state.publish(msg)
                sent += 1
            else:
                msg = WrenchStamped()
                msg.header.stamp = _stamp_msg(ev.stamp_s)
                msg.wrench.force.z = float(ev.value)
                pub_load.publish(msg)
                sent_loads += 1
            if lockstep:
                _wait_until(node, lambda v: v["published"] + v["rejected_nut_state"] >= sent
                            and v["received_axial_load"] >= sent_loads + handshakes)
        deadline = time.monotonic() + settle_s
        while time.monotonic() < deadline:
            values, _ = node.diagnostics_values()
            done = values["received_nut_state"] >= sent and values["queue_length"] == 0 \
                and len(preds) >= values["published"]
            if done:
                break
            time.sleep(0.05)
        time.sleep(0.2)
        values, _ = node.diagnostics_values()
    finally:
        executor.shutdown()
        node.destroy_node()
        io.destroy_node()
        sys.setswitchinterval(switch_interval)
        if own:
            rclpy.try_shutdown(context=context)
    return preds, groups, values, diags


def _wait_for_match(node, *publishers, timeout_s=5.0):
    """Wait until both ends see each other; a message sent earlier may be lost."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if all(p.get_subscription_count() > 0 and node.count_publishers(p.topic_name) > 0
               for p in publishers):
            time.sleep(0.1)      # the reader side finishes matching shortly after
            return
        time.sleep(0.01)
    raise RuntimeError("friction_node did not subscribe to the inputs in time")


def _handshake(node, pub_load, first_load, timeout_s=5.0):
    """
    Re-send the first load until the node has one: the inputs are then truly matched.

    A message sent before the reader has matched the writer is lost even with reliable
    QoS; a held load sent twice changes nothing.
    """
    msg = WrenchStamped()
    msg.header.stamp = _stamp_msg(first_load.stamp_s)
    msg.wrench.force.z = float(first_load.value)
    deadline = time.monotonic() + timeout_s
    while node.diagnostics_values(advance=False)[0]["received_axial_load"] == 0:
        if time.monotonic() > deadline:
            raise RuntimeError("friction_node received no input within "
                               f"{timeout_s} s")
        pub_load.publish(msg)
        time.sleep(0.02)


def _wait_until(node, condition, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not condition(node.diagnostics_values(advance=False)[0]):
        if time.monotonic() > deadline:
            raise RuntimeError("friction_node did not take a message within "
                               f"{timeout_s} s (lost in transport?)")
        time.sleep(0.0005)


def _prediction_dict(msg):
    return {"stamp_s": msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec,
            "nut_angle_rad": msg.nut_angle_rad, "nut_velocity_rad_s": msg.nut_velocity_rad_s,
            "axial_load_n": msg.axial_load_n, "torque_total_nm": msg.torque_total_nm,
            "torque_b2g_nm": msg.torque_b2g_nm, "torque_b2b_nm": msg.torque_b2b_nm,
            "torque_empirical_nm": msg.torque_empirical_nm,
            "converged": msg.converged, "model_latency_s": msg.model_latency_s,
            "model_age_s": msg.model_age_s, "n_groups": msg.n_groups}


def main(args=None):
    """Console script ``friction_node`` (also ``bb-friction node``)."""
    # Two Python threads (executor, model) trade the GIL for every input; at CPython's default
    # 5 ms switch interval each handoff can wait up to 5 ms (measured: bench/bench_node.py).
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    try:
        rclpy.init(args=args)
    except Exception as exc:       # e.g. an unreadable --params-file
        print(f"{NODE_NAME}: cannot start: {exc}", file=sys.stderr)
        return 2
    try:
        node = FrictionNode()
    except ConfigError as exc:
        print(f"{NODE_NAME}: config error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
