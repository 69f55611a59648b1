"""
Launch-free tests against ``friction_node``: the node in-process, on an rclpy context of its own.

For controller developers who test their code against this node without ``launch`` or the
``ros2`` CLI, and for this project's own node tests (so this module cannot rot)::

    from bb_friction_ros.harness import FrictionNodeHarness

    with FrictionNodeHarness(parameters={"model_rate_hz": 200.0}) as node:
        node.publish_axial_load(1500.0, stamp_s=0.0)
        node.publish_nut_state(0.0, 6.0, stamp_s=0.001)
        torque = node.feedforward.wait_for(1)[0].data[0]

With pytest, the ``friction_node`` fixture (``bb_friction_ros.pytest_plugin``, registered
through the ``pytest11`` entry point when bb_friction_ros is installed) yields a started
harness; set its arguments with ``@pytest.mark.friction_node(parameters={...}, ...)``::

    @pytest.mark.friction_node(parameters={"model_rate_hz": 200.0})
    def test_my_controller(friction_node):
        friction_node.publish_axial_load(1500.0, stamp_s=0.0)
        ...

Isolation: the harness's context uses its own ``ROS_DOMAIN_ID`` (``domain_id``, by default
derived from the process id, never the user's domain) and ``ROS_AUTOMATIC_DISCOVERY_RANGE``
is set to ``LOCALHOST`` unless already set, so tests never talk to a robot on the network.

Every wait has a timeout and raises ``TimeoutError`` saying what did not arrive.  rclpy and
the node are imported when a harness starts, so importing this module costs nothing.  No
pytest here: the demo and users' scripts use the harness without it.
"""

import importlib
import os
from pathlib import Path
import shutil
import sys
import threading
import time

from bb_friction_ros import interface
from bb_friction_ros.interface import local_domain_id

DEFAULT_TIMEOUT_S = 10.0
PROFILE_TOPIC = interface.PROFILE
PROFILE_TYPE = interface.TYPES[interface.PROFILE]
# A best-effort input subscription can still drop a message sent right after discovery; the
# first load is re-sent at this interval until the node has it (a held load sent twice
# changes nothing).
RESEND_INTERVAL_S = 0.02


def console_script(name="friction_node"):
    """
    Return the path of one of bb_friction_ros' console scripts, wherever it is installed.

    Looked for as ``ros2 run`` does, in ``lib/bb_friction_ros`` of each prefix on
    ``AMENT_PREFIX_PATH`` (a colcon workspace), then beside the interpreter (a venv or pip
    install), then on ``PATH``.
    """
    candidates = [Path(p) / "lib" / "bb_friction_ros" / name
                  for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    candidates.append(Path(sys.executable).parent / name)
    for path in candidates:
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
    found = shutil.which(name)
    if found:
        return found
    raise FileNotFoundError(f"console script {name!r} not found in "
                            f"{', '.join(str(c.parent) for c in candidates)} or on PATH")


def message_class(msg_type):
    """Return the rclpy message class of ``msg_type`` ('pkg/msg/Type' or a class)."""
    if not isinstance(msg_type, str):
        return msg_type
    parts = msg_type.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3:
        raise ValueError(f"message type {msg_type!r}: expected 'package/msg/Type'")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.{parts[1]}"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {msg_type!r} is not available here ({exc})") from None


class Collector:
    """Messages received on one topic, in arrival order, with waits that time out."""

    def __init__(self, topic, msg_type):
        """Collect ``msg_type`` messages of ``topic`` (subscribed by the harness)."""
        self.topic = topic
        self.msg_type = msg_type
        self._msgs = []
        self._cond = threading.Condition()

    def _on_message(self, msg):
        with self._cond:
            self._msgs.append(msg)
            self._cond.notify_all()

    @property
    def messages(self):
        """Return a copy of the messages received so far."""
        with self._cond:
            return list(self._msgs)

    def __len__(self):
        """Return the number of messages received so far."""
        with self._cond:
            return len(self._msgs)

    def clear(self):
        """Forget the messages received so far."""
        with self._cond:
            self._msgs.clear()

    def wait_for(self, count=1, timeout_s=DEFAULT_TIMEOUT_S):
        """Wait until ``count`` messages have arrived; return all received so far."""
        with self._cond:
            if not self._cond.wait_for(lambda: len(self._msgs) >= count, timeout_s):
                raise TimeoutError(f"{self.topic}: {len(self._msgs)} of {count} message(s) "
                                   f"within {timeout_s:g} s")
            return list(self._msgs)

    def wait_until(self, predicate, timeout_s=DEFAULT_TIMEOUT_S):
        """Wait for the first message with ``predicate(msg)`` true; return it."""
        with self._cond:
            found = []

            def ready():
                found[:] = [m for m in self._msgs if predicate(m)][:1]
                return bool(found)

            if not self._cond.wait_for(ready, timeout_s):
                raise TimeoutError(f"{self.topic}: no matching message among "
                                   f"{len(self._msgs)} within {timeout_s:g} s")
            return found[0]


class FrictionNodeHarness:
    """
    ``friction_node`` running in this process, with publishers for its inputs and collectors.

    Parameters
    ----------
    parameters : dict, optional
        Node parameters (``model_rate_hz``, ``nut_joint``, ...), applied over ``params_file``.
    params_file : path, optional
        A ROS params file (``friction_node: ros__parameters: ...``).
    domain_id : int, optional
        ROS domain of the harness's context (default ``local_domain_id()``); ignored when
        ``context`` is given.
    context : rclpy.Context, optional
        An initialised context to use (not shut down by the harness).
    namespace : str, optional
        Namespace of the node and of the harness's own endpoints.
    ros_args : list of str, optional
        More node arguments after ``--ros-args``, e.g. remappings
        ``["-r", "nut_state:=/robot/nut_state"]``.
    input_topics : (str, str)
        Where the harness publishes nut states and loads (match your remappings).

    Notes
    -----
    Attributes ``predictions``, ``contact_groups``, ``feedforward`` and ``diagnostics`` are
    Collectors; ``collect(topic, type)`` adds one for any other topic.

    """

    def __init__(self, parameters=None, params_file=None, domain_id=None, context=None,
                 namespace=None, ros_args=(),
                 input_topics=(interface.NUT_STATE, interface.AXIAL_LOAD),
                 ros_signal_handlers=True):
        """Keep the settings (``ros_signal_handlers``: ``init_context``'s); start() starts."""
        self.parameters = dict(parameters or {})
        self.params_file = None if params_file is None else str(params_file)
        self.domain_id = local_domain_id() if domain_id is None else int(domain_id)
        self.context = context
        self._own_context = context is None
        self.namespace = namespace
        self.ros_args = list(ros_args)
        self.input_topics = tuple(input_topics)
        self.ros_signal_handlers = bool(ros_signal_handlers)
        self.node = None
        self.io = None
        self._executor = None
        self._spinner = None
        self._collectors = {}
        self._handshake_done = False
        self._spinning = False

    # --- life cycle -----------------------------------------------------------------------
    def start(self):
        """Start the node and the harness's endpoints; wait until the inputs are matched."""
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy

        from bb_friction_ros.node import FrictionNode, GIL_SWITCH_INTERVAL_S
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        if self._own_context:
            self.context = init_context(self.domain_id, self.ros_signal_handlers)
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)       # as FrictionNode.__init__ does
        try:
            cli = []
            if self.params_file:
                cli += ["--params-file", self.params_file]
            cli += self.ros_args
            kwargs = {"namespace": self.namespace} if self.namespace else {}
            self.node = FrictionNode(
                context=self.context, cli_args=(["--ros-args"] + cli) if cli else None,
                parameter_overrides=[Parameter(k, value=v) for k, v in self.parameters.items()],
                **kwargs)
            self.io = Node("friction_node_harness", context=self.context, **kwargs)
            self._reliable = QoSProfile(depth=interface.COLLECTOR_QOS_DEPTH,
                                        reliability=ReliabilityPolicy.RELIABLE)
            in_qos = (self._reliable if self.node.get_parameter("reliable_qos").value
                      else qos_profile_sensor_data)
            from geometry_msgs.msg import WrenchStamped
            from sensor_msgs.msg import JointState
            self._pub_state = self.io.create_publisher(JointState, self.input_topics[0], in_qos)
            self._pub_load = self.io.create_publisher(WrenchStamped, self.input_topics[1],
                                                      in_qos)
            self.predictions, self.contact_groups, self.feedforward, self.diagnostics = (
                self.collect(t, interface.TYPES[t]) for t in (
                    interface.PREDICTION, interface.CONTACT_GROUPS, interface.FEEDFORWARD,
                    interface.DIAGNOSTICS))
            self._executor = SingleThreadedExecutor(context=self.context)
            self._executor.add_node(self.node)
            self._executor.add_node(self.io)
            self._spinning = True
            self._spinner = threading.Thread(target=self._spin, daemon=True,
                                             name="friction_node_harness")
            self._spinner.start()
            self._wait_for_match()
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self):
        """Stop the node and the executor; shut the context down if the harness made it."""
        import rclpy
        self._spinning = False
        if self._spinner is not None:
            self._spinner.join(timeout=5.0)   # stop spinning before the executor goes
            self._spinner = None
        if self._executor is not None:
            self._executor.shutdown()
            self._executor = None
        if self.node is not None:
            self.node.destroy_node()
            self.node = None
        if self.io is not None:
            self.io.destroy_node()
            self.io = None
        if hasattr(self, "_switch_interval"):
            sys.setswitchinterval(self._switch_interval)
        if self._own_context and self.context is not None:
            rclpy.try_shutdown(context=self.context)
            self.context = None

    def __enter__(self):
        """Start; return the harness."""
        return self.start()

    def __exit__(self, *exc):
        """Stop."""
        self.stop()

    def _spin(self):
        while self._spinning and self.context.ok():
            self._executor.spin_once(timeout_sec=0.05)

    def add_node(self, node):
        """Spin another node (your controller) on the harness's executor."""
        self._executor.add_node(node)

    # --- outputs --------------------------------------------------------------------------
    def collect(self, topic, msg_type, qos=None):
        """
        Return a Collector of ``topic`` (``msg_type``: 'pkg/msg/Type' or a class).

        Works for any topic the node publishes, e.g. ``collect(PROFILE_TOPIC,
        PROFILE_TYPE)``; one collector per topic is kept and returned again.
        """
        if topic in self._collectors:
            return self._collectors[topic]
        cls = message_class(msg_type)
        col = Collector(topic, cls)
        self.io.create_subscription(cls, topic, col._on_message, qos or self._reliable)
        self._collectors[topic] = col
        return col

    @property
    def profiles(self):
        """Return the Collector of ``friction/feedforward_profile`` (FeedforwardProfile)."""
        return self.collect(PROFILE_TOPIC, PROFILE_TYPE)

    def diagnostics_values(self):
        """Return the node's diagnostics key/values now (in-process, no wait for /diagnostics)."""
        return self.node.diagnostics_values(advance=False)[0]

    # --- inputs ---------------------------------------------------------------------------
    def publish_axial_load(self, force_n, stamp_s=None, timeout_s=DEFAULT_TIMEOUT_S):
        """
        Publish an axial load [N] (WrenchStamped force.z); return when the node has it.

        Re-sent until the node received it: a held load sent twice changes nothing.
        """
        from geometry_msgs.msg import WrenchStamped
        msg = WrenchStamped()
        msg.header.stamp = stamp_msg(time.time() if stamp_s is None else stamp_s)
        msg.wrench.force.z = float(force_n)
        before = self.diagnostics_values()["received_axial_load"]
        deadline = time.monotonic() + timeout_s
        while True:
            self._pub_load.publish(msg)
            resend = time.monotonic() + RESEND_INTERVAL_S
            while time.monotonic() < resend:
                if self.diagnostics_values()["received_axial_load"] > before:
                    self._handshake_done = True
                    return
                time.sleep(0.0005)
            if time.monotonic() > deadline:
                raise TimeoutError(f"{self.input_topics[1]}: friction_node did not receive "
                                   f"the load within {timeout_s:g} s")

    def publish_nut_state(self, angle_rad, velocity_rad_s, stamp_s=None, joint=None,
                          wait=True, timeout_s=DEFAULT_TIMEOUT_S):
        """
        Publish a nut state (JointState of ``joint``, default the node's ``nut_joint``).

        With ``wait``, return when the node has answered or rejected it (see
        ``diagnostics_values()`` for rejections); the answer itself arrives on the
        collectors.
        """
        from sensor_msgs.msg import JointState
        joint = joint or self.node.get_parameter("nut_joint").value
        msg = JointState(name=[joint], position=[float(angle_rad)],
                         velocity=[float(velocity_rad_s)])
        msg.header.stamp = stamp_msg(time.time() if stamp_s is None else stamp_s)
        self.publish_joint_state(msg, wait=wait, timeout_s=timeout_s)

    def publish_joint_state(self, msg, wait=True, timeout_s=DEFAULT_TIMEOUT_S):
        """Publish a JointState as given (several joints, bad values, ...)."""
        before = _taken(self.diagnostics_values())
        self._pub_state.publish(msg)
        if wait:
            self._wait_until(lambda v: _taken(v) > before, timeout_s,
                             f"{self.input_topics[0]}: friction_node did not take the "
                             "message")

    def play(self, events, speed=1.0, lockstep=False, settle_s=DEFAULT_TIMEOUT_S):
        """
        Publish recorded events (bags.Event) and collect what the node publishes.

        Events go out at their recorded pace divided by ``speed``.  With ``lockstep`` each
        message waits until the node has taken it (and answered or rejected a nut state):
        exact comparisons with replay then never depend on machine load.  Returns
        (predictions as dicts, contact-group messages, the node's diagnostics values,
        DiagnosticArray messages), each for this playback only.
        """
        from geometry_msgs.msg import WrenchStamped
        from sensor_msgs.msg import JointState
        n_preds, n_groups, n_diags = (len(self.predictions), len(self.contact_groups),
                                      len(self.diagnostics))
        first_load = next((e for e in events if e.kind == "axial_load"), None)
        if first_load is not None and not self._handshake_done:
            self.publish_axial_load(first_load.value, first_load.stamp_s)   # the handshake
        v0 = self.diagnostics_values()
        taken0, loads0 = _taken(v0), v0["received_axial_load"]
        t_wall0 = time.monotonic()
        t_rec0 = None
        sent = sent_loads = 0
        for ev in events:
            if ev.kind not in ("nut_state", "axial_load"):
                continue
            t_rec0 = ev.stamp_s if t_rec0 is None else t_rec0
            delay = t_wall0 + (ev.stamp_s - t_rec0) / speed - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if ev.kind == "nut_state":
                msg = JointState(name=list(ev.names), position=list(ev.positions),
                                 velocity=list(ev.velocities))
                msg.header.stamp = stamp_msg(ev.stamp_s)
                self._pub_state.publish(msg)
                sent += 1
            else:
                msg = WrenchStamped()
                msg.header.stamp = stamp_msg(ev.stamp_s)
                msg.wrench.force.z = float(ev.value)
                self._pub_load.publish(msg)
                sent_loads += 1
            if lockstep:
                self._wait_until(lambda v: _taken(v) >= taken0 + sent
                                 and v["received_axial_load"] >= loads0 + sent_loads,
                                 DEFAULT_TIMEOUT_S,
                                 "friction_node did not take a message (lost in transport?)")
        deadline = time.monotonic() + settle_s
        while time.monotonic() < deadline:
            v = self.diagnostics_values()
            if (v["received_nut_state"] >= v0["received_nut_state"] + sent
                    and v["queue_length"] == 0
                    and len(self.predictions) - n_preds >= v["published"] - v0["published"]):
                break
            time.sleep(0.05)
        time.sleep(0.2)
        values = self.node.diagnostics_values()[0]
        preds = [prediction_dict(m) for m in self.predictions.messages[n_preds:]]
        return (preds, self.contact_groups.messages[n_groups:], values,
                self.diagnostics.messages[n_diags:])

    # --- internals ------------------------------------------------------------------------
    def _wait_until(self, condition, timeout_s, what):
        deadline = time.monotonic() + timeout_s
        while not condition(self.diagnostics_values()):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what} within {timeout_s:g} s")
            time.sleep(0.0005)

    def _wait_for_match(self, timeout_s=DEFAULT_TIMEOUT_S):
        """Wait until inputs and outputs see each other; a message sent earlier may be lost."""
        pubs = (self._pub_state, self._pub_load)
        outs = [c.topic for c in self._collectors.values()]
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_subscription_count() > 0 for p in pubs) and \
                    all(self.io.count_publishers(t) > 0 for t in outs):
                time.sleep(0.1)      # the reader side finishes matching shortly after
                return
            time.sleep(0.01)
        raise TimeoutError(f"friction_node did not match the harness's topics within "
                           f"{timeout_s:g} s")


def _taken(values):
    """Nut states the node has dealt with: answered, shed (too old), rejected or dropped."""
    return (values["published"] + values["shed_inputs"] + values["rejected_nut_state"]
            + values["dropped_inputs"])


def stamp_msg(stamp_s):
    """Return a builtin_interfaces/Time for ``stamp_s`` [s]."""
    from builtin_interfaces.msg import Time
    sec = int(stamp_s // 1)
    nanosec = min(int(round((stamp_s - sec) * 1e9)), 999_999_999)
    return Time(sec=sec, nanosec=nanosec)


def prediction_dict(msg):
    """Return a FrictionPrediction message as a dict (stamp as float seconds)."""
    out = {"stamp_s": msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec}
    out.update((name, getattr(msg, name)) for name in interface.PREDICTION_FIELDS)
    return out


def init_context(domain_id, ros_signal_handlers=True):
    """
    Return a new initialised rclpy Context on ``domain_id``.

    ``ros_signal_handlers`` False: without rclpy's SIGINT and SIGTERM handlers, for a command
    line tool that turns Ctrl-C into its own exit: Python's KeyboardInterrupt reaches it with
    no rclpy handler in between (handlers are per process, put in place at the first init).
    """
    import rclpy
    context = rclpy.Context()
    options = {}
    if not ros_signal_handlers:
        from rclpy.signals import SignalHandlerOptions
        options["signal_handler_options"] = SignalHandlerOptions.NO
    rclpy.init(context=context, domain_id=domain_id, **options)
    return context


def play_through_node(events, parameters=None, context=None, speed=1.0,
                      settle_s=DEFAULT_TIMEOUT_S, lockstep=False, ros_signal_handlers=True):
    """
    Play ``events`` through a fresh in-process friction_node (see FrictionNodeHarness.play).

    With ``lockstep`` (exact comparisons, not timing) no answer is too old to publish:
    ``max_answer_age_s`` is 10 s unless ``parameters`` set it.  ``ros_signal_handlers``: as
    FrictionNodeHarness's.
    """
    if lockstep:
        parameters = {"max_answer_age_s": 10.0, **(parameters or {})}
    with FrictionNodeHarness(parameters, context=context,
                             ros_signal_handlers=ros_signal_handlers) as harness:
        return harness.play(events, speed=speed, lockstep=lockstep, settle_s=settle_s)
