"""
The node's inputs taken off the wire by a thread of their own: the one use of private rclpy.

rclpy's executor spends ~0.3-0.6 ms of Python per message (rebuilding its wait set, tasks,
callback groups; measured with py-spy at 1 kHz, bench/bench_node.py), more than a 1-2 kHz
input leaves on a small machine.  So ``InputTaker`` waits on the two input subscriptions in
a thread of its own and takes their messages itself; the executor keeps timers and
parameter services.  Their QoS event handlers (incompatible QoS or type: warnings) move to
that thread too: left in the executor's wait set, they woke it at every input message (the
middleware signals a subscription's events with its data), ~0.3 ms of Python per input and
the GIL taken from the input and model threads (measured at 1 kHz: 720 empty wake-ups/s;
bench/bench_node.py lost 20-45 % of the answers).

That needs rclpy internals (``Node._subscriptions``, ``Node.remove_waitable``, the C
``WaitSet``, ``take_message``, the event handlers' wait-set methods).  ``fast_path_missing``
checks each at start-up; if any is missing (another rclpy), the subscriptions stay with the
executor, with a logged warning and ``fast_inputs = False`` in diagnostics: slower, never
silently broken.
"""

import threading
import time

# How long the input thread waits before it looks at the stop flag again [ns].
WAIT_TIMEOUT_NS = 50_000_000
_WAIT_SET_METHODS = ("clear_entities", "add_subscription", "wait")
_HANDLER_METHODS = ("add_to_wait_set", "is_ready", "take_data", "callback")


def fast_path_missing(node, subscriptions):
    """Return the rclpy internals the fast path needs and this rclpy lacks (empty: usable)."""
    try:
        from rclpy.impl.implementation_singleton import rclpy_implementation as impl
    except ImportError:
        return ["rclpy.impl.implementation_singleton.rclpy_implementation"]
    missing = [f"WaitSet.{m}" for m in _WAIT_SET_METHODS
               if not hasattr(getattr(impl, "WaitSet", None), m)]
    if not isinstance(getattr(node, "_subscriptions", None), list):
        missing.append("Node._subscriptions")
    if not callable(getattr(node, "remove_waitable", None)):
        missing.append("Node.remove_waitable")
    for sub in subscriptions:
        if sub not in getattr(node, "_subscriptions", ()):
            missing.append(f"{sub.topic_name} in Node._subscriptions")
        if not hasattr(getattr(sub, "handle", None), "take_message"):
            missing.append("Subscription.handle.take_message")
        for handler in getattr(sub, "event_handlers", None) or ():
            missing += [f"event handler .{m}" for m in _HANDLER_METHODS
                        if not hasattr(handler, m)]
    return sorted(set(missing))


class InputTaker:
    """
    Take the input messages in arrival order, in a thread of our own (or leave the executor).

    ``on_load(msg)`` and ``on_state(msg, recv_ns, newest)`` are the node's handlers;
    ``recv_ns`` is the middleware's receive time (``time.time_ns`` scale), ``newest`` the
    newest nut_state taken with it and still to come (None: none; the executor's path, which
    takes one message at a time, never knows).  The subscriptions must have been created
    with callbacks that call the same handlers (the executor's path).  ``idle``: an object
    with ``deferred`` (bool) and ``flush()``, flushed whenever the thread finds no input
    waiting while it has deferred work (the fast path only; ``fast`` tells).
    """

    def __init__(self, node, load_sub, state_sub, on_load, on_state, idle=None):
        """Check the fast path; take it, or warn and leave the subscriptions to rclpy."""
        self._node = node
        self._subs = (load_sub, state_sub)
        self._handlers = (on_load, on_state)
        self._idle = idle
        self._stop = False
        self._thread = None
        self.missing = fast_path_missing(node, self._subs)
        self.fast = not self.missing
        if not self.fast:
            node.get_logger().warning(
                "fast input path unavailable (this rclpy lacks " + ", ".join(self.missing)
                + "): the executor takes the inputs, slower at 1-2 kHz")
            return
        self._events = []
        for sub in self._subs:
            node._subscriptions.remove(sub)
            for handler in sub.event_handlers:
                node.remove_waitable(handler)
                self._events.append(handler)
        self._thread = threading.Thread(target=self._loop, name="friction_input", daemon=True)
        self._thread.start()

    def stop(self, timeout_s=5.0):
        """Stop the input thread; return True if it ended (the subscriptions may go)."""
        self._stop = True
        if self._thread is None:
            return True
        self._thread.join(timeout=timeout_s)
        return not self._thread.is_alive()

    def _loop(self):
        """Wait on both inputs; take everything ready; hand it over in arrival order."""
        from rclpy.impl.implementation_singleton import rclpy_implementation as impl
        load_sub, state_sub = self._subs
        on_load, on_state = self._handlers
        events = self._events
        context = self._node.context
        wait_set = impl.WaitSet(2, 0, 0, 0, 0, len(events), context.handle)
        idle = self._idle
        while not self._stop:
            # deferred work (changed groups, a profile's hand-off): look without waiting
            # first, so an input that came during a step is answered before it
            pending = idle is not None and idle.deferred
            try:
                wait_set.clear_entities()
                wait_set.add_subscription(load_sub.handle)
                wait_set.add_subscription(state_sub.handle)
                for handler in events:
                    handler.add_to_wait_set(wait_set)
                wait_set.wait(0 if pending else WAIT_TIMEOUT_NS)
                for handler in events:
                    if handler.is_ready(wait_set):
                        info = handler.take_data()
                        if info:
                            handler.callback(info)
                batch = []
                for is_state, sub in enumerate(self._subs):
                    while True:
                        with sub.handle:
                            got = sub.handle.take_message(sub.msg_type, False)
                        if got is None:
                            break
                        batch.append((got[1].get("received_timestamp") or 0, is_state, got))
            except Exception:           # context shut down or node destroyed: stop
                if self._stop or not context.ok():
                    return
                raise
            if pending and not batch:
                idle.flush()
                continue
            # arrival order across the two topics, as a recorder (and replay) sees them
            batch.sort(key=lambda item: item[0])
            states = [got[0] for _, is_state, got in batch if is_state]
            newest = states[-1] if states else None
            for recv_ns, is_state, (msg, _) in batch:
                if self._stop:
                    return
                if is_state:
                    # whether inputs wait behind this one: the schedule's hand-off rule
                    on_state(msg, recv_ns or time.time_ns(), newest if msg is not newest
                             else None)
                else:
                    on_load(msg)
