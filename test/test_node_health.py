"""
friction_node's health on /diagnostics and its input path, in-process under rclpy through
the public harness.
"""

from bb_friction_ros import ros_inputs
from bb_friction_ros.harness import FrictionNodeHarness


def _statuses(harness, count, timeout_s=10.0):
    msgs = harness.diagnostics.wait_for(count, timeout_s)
    return [m.status[0] for m in msgs]


def test_diagnostics_error_without_input_then_ok_with_it(ros_context):
    """No nut_state: ERROR naming it; inputs flowing: OK; the status has the full name."""
    params = {"diagnostics_rate_hz": 10.0, "input_timeout_s": 0.5, "max_answer_age_s": 10.0}
    with FrictionNodeHarness(params, context=ros_context, namespace="/axis_x") as h:
        status = h.diagnostics.wait_until(lambda m: m.status[0].level == b"\x02").status[0]
        assert "no nut_state" in status.message
        # the fully qualified name tells namespaced nodes apart
        assert status.name == "/axis_x/friction_node: friction model"
        h.publish_axial_load(1500.0, stamp_s=0.0)
        for k in range(1, 40):
            h.publish_nut_state(0.006 * k, 6.0, stamp_s=0.001 * k)

        def fed(msg):
            values = {kv.key: kv.value for kv in msg.status[0].values}
            return int(values["received_nut_state"]) > 0
        status = h.diagnostics.wait_until(fed).status[0]
        assert status.level == b"\x00" and status.message == "ok", status.message
        values = {kv.key: kv.value for kv in status.values}
        assert values["ready"] == "True" and values["fast_inputs"] == "True"


def test_input_path_falls_back_to_the_executor_loudly(ros_context, monkeypatch):
    """An rclpy without the internals the fast path uses: plain subscriptions, and it says so."""
    monkeypatch.setattr(ros_inputs, "fast_path_missing",
                        lambda node, subs: ["WaitSet.wait (removed for this test)"])
    params = {"diagnostics_rate_hz": 10.0, "max_answer_age_s": 10.0}
    with FrictionNodeHarness(params, context=ros_context) as h:
        assert not h.node._taker.fast
        # the executor now holds the input subscriptions
        assert all(any(s is i for s in h.node.subscriptions) for i in h.node._inputs)
        h.publish_axial_load(1500.0, stamp_s=0.0)
        for k in range(1, 6):
            h.publish_nut_state(0.006 * k, 6.0, stamp_s=0.001 * k)
        preds = h.predictions.wait_for(5)
        assert [round(p.header.stamp.nanosec, -3) for p in preds] == \
            [1000000 * k for k in range(1, 6)]
        status = h.diagnostics.wait_until(
            lambda m: "inputs taken by the executor" in m.status[0].message).status[0]
        assert status.level == b"\x01" and "WaitSet.wait" in status.message
        assert h.diagnostics_values()["fast_inputs"] is False


def test_fast_path_check_finds_what_is_missing(ros_context):
    """The start-up check is real: on this rclpy nothing is missing, on a bare object all is."""
    from types import SimpleNamespace
    with FrictionNodeHarness(context=ros_context) as h:
        assert h.node._taker.missing == [] and h.node._taker.fast   # checked at start-up
    bare = SimpleNamespace(topic_name="/nut_state", handle=None, event_handlers=())
    missing = ros_inputs.fast_path_missing(SimpleNamespace(), [bare])
    assert "Node._subscriptions" in missing and "Node.remove_waitable" in missing
    assert "Subscription.handle.take_message" in missing
