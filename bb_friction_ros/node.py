"""
ROS 2 node ``friction_node``: predicted ball-screw friction torque for a motion controller.

The only module that imports rclpy.  A thin shell: messages -> ``runner`` (pure core) ->
messages.

Per-input path: the nut-state callback validates the sample and, when no model step is due
(most inputs: the model runs at ``model_rate_hz``, the inputs at the controller's rate),
answers it at once from the latest model state, in the executor thread.  A sample that is
due a step (or arrives while one is running) goes to the model thread, which steps the
whole-screw model (a numba kernel that releases the GIL, so the executor keeps taking
inputs), answers it and everything queued behind it in order, and then steps a copy of the
state ahead for the look-ahead profile.  Every sample reaches the runner in arrival order, so
the answers equal replay's exactly (the runner is the same).

Answer age is bounded: an answer older than ``max_answer_age_s`` since the input was received
by the middleware (``received_timestamp``) is not published but counted (``shed_inputs``);
its sample still goes through the runner, so the model is not disturbed.  When the model
itself falls behind (its queue spans a model period), a step due on a queued sample moves to
the newest one (``skipped_steps``; answers then differ from replay's, and diagnostics say so).

Subscribes: ``nut_state`` (sensor_msgs/JointState, joint ``nut_joint``), ``axial_load``
(geometry_msgs/WrenchStamped, force.z).  Publishes: ``friction/prediction``
(bb_friction_msgs/FrictionPrediction, stamped with the input stamp it answers),
``friction/feedforward`` (std_msgs/Float64MultiArray [torque], the ros2_control
forward-command convention; the runner's safe value when a step did not converge),
``friction/feedforward_profile`` (bb_friction_msgs/FeedforwardProfile, at every model step),
``friction/contact_groups`` (bb_friction_msgs/ContactGroupStatus, on change and at
``groups_rate_hz``) and ``/diagnostics``.
"""

import collections
import dataclasses
import math
import sys
import threading
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
from std_msgs.msg import Float64MultiArray

from bb_friction_ros import interface
from bb_friction_ros.config import bundled_config, ConfigError
from bb_friction_ros.node_parameters import (MODEL_PARAMETERS, NODE_NAME, node_parameters,
                                             NodeParameters, ros_type, RUNTIME,
                                             unknown_parameters)
from bb_friction_ros.runner import (build_runner, InputAssembler, InputError,
                                    look_ahead_profile)

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
        self.unknown_parameters = unknown_parameters(getattr(self, "_parameter_overrides",
                                                             {}))
        for name in self.unknown_parameters:
            self.get_logger().warning(f"unknown parameter {name!r} ignored (known: "
                                      f"{', '.join(PARAMETERS)})")
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue = collections.deque(maxlen=p.queue_size)
        self._busy = False          # the model thread owns the runner until it clears this
        self._profile_seed = None
        self._runner = build_runner(_model_file(p), p.model_rate_hz, p.model_step_deg,
                                    p.max_model_step_deg)
        self._assembler = InputAssembler(p.nut_joint, p.max_axial_load_n)
        self._pending = None    # (parameters, runner, names) validated, applied after the set
        self._max_age_ns = int(p.max_answer_age_s * 1e9)
        self._profile_shape = (p.profile_horizon_periods, p.profile_points)
        self._dropped = 0
        self._shed = 0
        self._shed_at_diag = 0
        self._stalls_at_diag = 0
        self._received = collections.Counter()
        self._published = 0
        self._inline = 0
        self._profiles = 0
        self._profiles_abandoned = 0
        self._profile_errors = 0
        self._ff_held = 0
        self._latest = None
        self._latest_stamp = None
        self._last_groups = None
        self._reset_note = ""
        self._other_publishers = {}
        self._t_start = time.monotonic()
        self._steps_at_diag = (0, self._t_start)
        self._stop = False

        # Sensor-data semantics (best effort, volatile) with the depth of our own queue: the
        # profile's depth of 5 dropped ~1 % of inputs at 1 kHz while the executor waited.
        qos = QoSProfile(depth=p.queue_size, durability=DurabilityPolicy.VOLATILE,
                         reliability=(ReliabilityPolicy.RELIABLE if p.reliable_qos
                                      else ReliabilityPolicy.BEST_EFFORT))
        # our own values are floats by construction: no per-field checks (see _answer)
        self._out_input, self._out_model = (
            (FrictionPrediction(check_fields=False),
             Float64MultiArray(data=[0.0], check_fields=False)) for _ in range(2))
        depth = interface.OUTPUT_QOS_DEPTH
        self._pub_pred = self.create_publisher(FrictionPrediction, interface.PREDICTION, depth)
        self._pub_groups = self.create_publisher(ContactGroupStatus, interface.CONTACT_GROUPS,
                                                 depth)
        self._pub_ff = self.create_publisher(Float64MultiArray, interface.FEEDFORWARD, depth)
        self._pub_profile = self.create_publisher(FeedforwardProfile, interface.PROFILE, depth)
        self._pub_diag = self.create_publisher(DiagnosticArray, interface.DIAGNOSTICS, depth)
        self._inputs = (
            self.create_subscription(WrenchStamped, interface.AXIAL_LOAD, self._on_axial_load,
                                     qos),
            self.create_subscription(JointState, interface.NUT_STATE, self._on_nut_state, qos))
        # The inputs are taken by our own thread, not by the executor: rclpy's executor
        # spends ~0.3-0.6 ms of Python per message (rebuilding its wait set, tasks,
        # callback groups; measured with py-spy at 1 kHz, bench/bench_node.py), more than
        # a 1-2 kHz input leaves on a small machine.  The executor keeps timers and
        # parameter services.
        #
        # Their QoS event handlers (incompatible QoS or type: warnings) move to that thread
        # too.  Left in the executor's wait set, they woke it at every input message (the
        # middleware signals a subscription's events with its data): the executor then found
        # nothing to do and rebuilt its wait set in Python, ~0.3 ms per input, and took the
        # GIL from the input and model threads (measured at 1 kHz: 720 empty wake-ups/s, the
        # executor thread 20 % of a core; bench/bench_node.py lost 20-45 % of the answers).
        self._input_events = []
        for sub in self._inputs:
            if sub in getattr(self, "_subscriptions", ()):
                self._subscriptions.remove(sub)
            for handler in sub.event_handlers:
                self.remove_waitable(handler)
                self._input_events.append(handler)
        self._groups_timer = self.create_timer(1.0 / p.groups_rate_hz, self._publish_groups)
        self.create_timer(1.0 / p.diagnostics_rate_hz, self._publish_diagnostics)
        # rclpy's pattern: validate in the on-set callback, apply in the post-set one
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._thread = threading.Thread(target=self._model_loop, name="friction_model",
                                        daemon=True)
        self._thread.start()
        self._input_thread = threading.Thread(target=self._input_loop, name="friction_input",
                                              daemon=True)
        self._input_thread.start()

    # --- input thread ---------------------------------------------------------------------
    def _input_loop(self):
        """Wait on both inputs; take everything ready; handle it in arrival order."""
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        load_sub, state_sub = self._inputs
        events = self._input_events
        wait_set = _rclpy.WaitSet(2, 0, 0, 0, 0, len(events), self.context.handle)
        while not self._stop:
            try:
                wait_set.clear_entities()
                wait_set.add_subscription(load_sub.handle)
                wait_set.add_subscription(state_sub.handle)
                for handler in events:
                    handler.add_to_wait_set(wait_set)
                wait_set.wait(50_000_000)       # 50 ms: how soon a stop is noticed
                for handler in events:
                    if handler.is_ready(wait_set):
                        info = handler.take_data()
                        if info:
                            handler.callback(info)
                batch = []
                for is_state, sub in enumerate((load_sub, state_sub)):
                    while True:
                        with sub.handle:
                            got = sub.handle.take_message(sub.msg_type, False)
                        if got is None:
                            break
                        batch.append((got[1].get("received_timestamp") or 0, is_state, got))
            except Exception:           # context shut down or node destroyed: stop
                if self._stop or not self.context.ok():
                    return
                raise
            # arrival order across the two topics, as a recorder (and replay) sees them
            batch.sort(key=lambda item: item[0])
            for _, is_state, (msg, info) in batch:
                if self._stop:
                    return
                if is_state:
                    self._on_nut_state(msg, info)
                else:
                    self._on_axial_load(msg)

    # --- per-input path (executor thread) -------------------------------------------------
    def _on_nut_state(self, msg, info):
        recv_ns = info.get("received_timestamp") or time.time_ns()
        stamp = msg.header.stamp
        with self._lock:
            self._received["nut_state"] += 1
            try:
                sample = self._assembler.on_nut_state(stamp.sec + 1e-9 * stamp.nanosec,
                                                      msg.name, msg.position, msg.velocity)
            except InputError as err:
                self._runner.reject(err.reason, nut_state=True)
                return
            runner = self._runner
            if self._busy or runner.step_due(sample):
                # the model thread answers it, in order, after the step it waits for
                if len(self._queue) == self._queue.maxlen:
                    self._dropped += 1      # deque drops the oldest: the newest input wins
                # the original stamp goes out unchanged: float seconds lose ~0.2 us at
                # epoch times
                self._queue.append((sample, recv_ns, stamp))
                self._busy = True
                self._wake.notify()
                return
        # No step due and the model thread idle (only this thread makes it busy): answer
        # from the latest state at once.
        self._inline += 1
        pred = runner.process(sample)
        if pred is None:        # counted by the runner as model_error
            self._model_error(runner)
            return
        self._answer(pred, recv_ns, stamp, self._out_input)

    def _on_axial_load(self, msg):
        with self._lock:
            self._received["axial_load"] += 1
            try:
                self._assembler.on_axial_load(msg.wrench.force.z)
            except InputError as err:
                self._runner.reject(err.reason)

    def _answer(self, pred, recv_ns, stamp, out):
        """
        Publish the prediction and the feedforward, unless the answer is too old.

        ``out`` is the calling thread's own (FrictionPrediction, Float64MultiArray) pair,
        reused: publish serializes at once, and building messages (their constructors
        import and validate every field) cost ~60 us per input (profiled).
        """
        msg, ff = out
        ff.data[0] = pred.feedforward_nm
        age_ns = time.time_ns() - recv_ns
        if age_ns > self._max_age_ns:
            with self._lock:
                self._shed += 1
            return False
        msg.header.stamp = stamp
        for name, value in zip(interface.PREDICTION_FIELDS,
                               interface.prediction_values(pred, 1e-9 * age_ns)):
            setattr(msg, name, value)
        self._pub_pred.publish(msg)
        self._pub_ff.publish(ff)
        with self._lock:
            self._published += 1
            self._ff_held += pred.feedforward_held
            self._latest = pred
            self._latest_stamp = stamp
            changed = pred.groups is not self._last_groups and pred.groups != self._last_groups
        if changed:
            self._publish_groups()
        return True

    # --- model thread ---------------------------------------------------------------------
    def _model_loop(self):
        while True:
            with self._lock:
                while not self._queue and not self._stop:
                    if self._profile_seed is not None:
                        break
                    self._busy = False
                    self._wake.wait(timeout=0.5)
                if self._stop:
                    return
                if not self._queue:
                    # queue drained, a profile to compute: inputs are answered inline
                    # meanwhile; a step falling due abandons the profile
                    seed, self._profile_seed = self._profile_seed, None
                    self._busy = False
                    item = None
                else:
                    item = self._queue.popleft()
                    newest_stamp = self._queue[-1][0].stamp_s if self._queue else None
                    runner = self._runner
            if item is None:
                self._publish_profile(seed)
                continue
            sample, recv_ns, stamp = item
            # The model fell behind when its queue spans a model period or more: a step due
            # now would be followed at once by another.  It is left to the newest sample (the
            # model tracks the present, not its backlog).
            behind = newest_stamp is not None \
                and newest_stamp - sample.stamp_s >= runner.period_s
            resets = runner.stats.resets
            pred = runner.process(sample, allow_step=not behind)
            if pred is None:             # counted by the runner as model_error
                self._model_error(runner)
                continue
            if runner.stats.resets != resets:
                note = (f"input stamps went backwards at {sample.stamp_s:.6f} s: model "
                        "state reset")
                with self._lock:
                    self._reset_note = note
                self.get_logger().warning(note)
            if pred.stepped:
                self._profile_seed = (runner.profile_seed(sample), stamp)
            self._answer(pred, recv_ns, stamp, self._out_model)

    def _model_error(self, runner):
        self.get_logger().error(f"model step failed: {runner.stats.last_error}; state reset")

    def _publish_profile(self, seed_stamp):
        seed, stamp = seed_stamp
        horizon, points = self._profile_shape
        try:
            out = look_ahead_profile(seed, horizon, points, should_stop=lambda: self._busy)
        except Exception as exc:     # a failed look-ahead must not stop the answers
            with self._lock:
                self._profile_errors += 1
            self.get_logger().error(f"look-ahead profile failed: {exc!r}")
            return
        if out is None:
            with self._lock:
                self._profiles_abandoned += 1
            return
        angles, torques, converged = out
        msg = FeedforwardProfile()
        msg.header.stamp = stamp
        msg.nut_angle_rad = angles
        msg.torque_total_nm = torques
        msg.nut_velocity_rad_s = seed.sample.nut_velocity_rad_s
        msg.axial_load_n = seed.sample.axial_load_n
        msg.converged = converged
        self._pub_profile.publish(msg)
        with self._lock:
            self._profiles += 1

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
            shed_window = self._shed - self._shed_at_diag
            if advance:
                self._steps_at_diag = (stats.model_steps, now)
                self._shed_at_diag = self._shed
            latest = self._latest
            values = {
                "model_rate_hz": rate,
                "model_steps": stats.model_steps,
                "last_step_s": stats.last_step_wall_s,
                "nonconverged_steps": stats.nonconverged_steps,
                "feedforward_held": self._ff_held,
                "feedforward_zeroed": stats.feedforward_zeroed,
                "model_step_deg": math.degrees(self._runner.model_step_rad),
                "coarse_steps": stats.coarse_steps,
                "stamp_stalls": stats.stamp_stalls,
                "term_restarts": stats.term_restarts,
                "queue_length": len(self._queue),
                "skipped_inputs": self._dropped + stats.skipped_steps,
                "skipped_steps": stats.skipped_steps,
                "dropped_inputs": self._dropped,
                "shed_inputs": self._shed,
                "shed_since_last_report": shed_window,
                "max_answer_age_s": 1e-9 * self._max_age_ns,
                "published": self._published,
                "answered_inline": self._inline,
                "profiles": self._profiles,
                "profiles_abandoned": self._profiles_abandoned,
                "profile_errors": self._profile_errors,
                "resets": stats.resets,
                "lag_s": 0.0 if latest is None else latest.model_age_s,
                "received_nut_state": self._received["nut_state"],
                "received_axial_load": self._received["axial_load"],
                "rejected_total": sum(stats.rejected.values()),
                "rejected_nut_state": stats.rejected_nut_state,
            }
            for reason, n in sorted(stats.rejected.items()):
                values[f"rejected_{reason}"] = n
            for topic, n in sorted(self._other_publishers.items()):
                values[f"publishers_{topic}"] = n
            if self.unknown_parameters:
                values["unknown_parameters"] = ",".join(self.unknown_parameters)
            converged = latest is None or latest.converged
        return values, converged

    def check_other_publishers(self):
        """
        Count the publishers on our output topics; warn (once per change) if not only us.

        Two friction_nodes on one domain would both answer every input: a controller would
        get two feedforward commands per cycle.  Returns {topic: publisher count} of the
        topics with more than one.
        """
        found = {}
        for pub in (self._pub_pred, self._pub_ff, self._pub_profile, self._pub_groups):
            n = self.count_publishers(pub.topic_name)
            if n > 1:
                found[pub.topic_name] = n
        if found != self._other_publishers:
            for topic, n in sorted(found.items()):
                self.get_logger().warning(
                    f"{n} publishers on {topic}: another friction_node on this domain? "
                    "A controller would get two answers per input.")
        with self._lock:
            self._other_publishers = found
        return found

    def _publish_diagnostics(self):
        others = self.check_other_publishers()
        values, converged = self.diagnostics_values()
        status = DiagnosticStatus(name=f"{self.get_name()}: friction model",
                                  hardware_id="ball_screw")
        notes = []
        if not converged:
            notes.append("solver did not converge: feedforward holds the last converged "
                         "value (0 after a reversal or at standstill)")
        if values["shed_since_last_report"]:
            notes.append(f"shedding load: {values['shed_since_last_report']} answers older "
                         f"than max_answer_age_s = {values['max_answer_age_s']:.6g} s not "
                         "published")
        if values["stamp_stalls"] > self._stalls_at_diag:
            notes.append(f"input stamps do not advance ({values['stamp_stalls']} samples with "
                         "the previous sample's stamp): the model steps on nut angle, "
                         "direction and load only, and model_age_s is 0 for those")
        self._stalls_at_diag = values["stamp_stalls"]
        if values["coarse_steps"]:
            notes.append(f"model could not keep up: {values['coarse_steps']} coarser steps, "
                         f"now {values['model_step_deg']:.3g} deg per step")
        if values["skipped_steps"]:
            notes.append(f"model fell behind: {values['skipped_steps']} steps skipped "
                         "(answers differ from replay from then on)")
        if values["rejected_total"] or values["dropped_inputs"]:
            notes.append(f"{values['rejected_total']} inputs rejected, "
                         f"{values['dropped_inputs']} dropped")
        if values["profile_errors"]:
            notes.append(f"{values['profile_errors']} look-ahead profiles failed")
        for topic, n in sorted(others.items()):
            notes.append(f"{n} publishers on {topic} (another friction_node?)")
        if self.unknown_parameters:
            notes.append("unknown parameters ignored: " + ", ".join(self.unknown_parameters))
        with self._lock:     # a reset is reported in the one status after it, then cleared
            note, self._reset_note = self._reset_note, ""
        if note:
            notes.append(note)
        status.level = DiagnosticStatus.WARN if notes else DiagnosticStatus.OK
        status.message = "; ".join(notes) if notes else "ok"
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
                runner = build_runner(_model_file(new), new.model_rate_hz,
                                      new.model_step_deg, new.max_model_step_deg)
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
                # rate window keeps its base (a new runner's zero gave one negative rate);
                # the same empirical terms keep their clock and filter
                if not runner.continue_from(self._runner) and runner.terms is not None:
                    self._reset_note = "empirical terms restarted (model rebuilt)"
                self._runner = runner
            self._assembler.nut_joint = new.nut_joint
            self._assembler.max_axial_load_n = new.max_axial_load_n
            self._max_age_ns = int(new.max_answer_age_s * 1e9)
            self._profile_shape = (new.profile_horizon_periods, new.profile_points)
        if "groups_rate_hz" in changed:
            self._groups_timer.timer_period_ns = int(1e9 / new.groups_rate_hz)

    def destroy_node(self):
        """Stop the input and model threads, then destroy the node."""
        with self._lock:
            self._stop = True
            self._wake.notify_all()
        self._input_thread.join(timeout=5.0)
        self._thread.join(timeout=5.0)
        if not self._input_thread.is_alive():
            for sub in self._inputs:
                sub.destroy()
        return super().destroy_node()


def main(args=None, on_spin=None):
    """Run friction_node (entered through ``node_entry.main``: console script and CLI)."""
    # Two Python threads (executor, model) trade the GIL; at CPython's default 5 ms switch
    # interval each handoff can wait up to 5 ms (measured: bench/bench_node.py).
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
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
            print(f"{NODE_NAME}: cannot start: {exc}", file=sys.stderr)
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
