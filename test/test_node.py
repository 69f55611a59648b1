"""
The live friction_node, in-process under rclpy executors (no launch, no ros2 CLI).

Driven through the public harness ``bb_friction_ros.harness`` (so it cannot rot).  Inputs are
paced so that the model keeps up; then the node must give exactly the replay's predictions
(same runner, same schedule).
"""

import dataclasses
import math

import pytest
from rclpy.parameter import Parameter

from bb_friction_ros import interface
from bb_friction_ros.bags import Event
from bb_friction_ros.config import bundled_config, ConfigError
from bb_friction_ros.node import FrictionNode, main
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay import run_events
from bb_friction_ros.runner import build_runner, InputAssembler
from bb_friction_ros.harness import console_script, play_through_node
from invariants import check_prediction
from recordings import averaged_feedforward, short_recording


def replay_predictions(events):
    runner = build_runner(bundled_config("ball_screw.yaml"), NodeParameters().model_rate_hz)
    asm = InputAssembler(NodeParameters().nut_joint, NodeParameters().max_axial_load_n)
    return run_events(events, runner, asm), runner


def test_live_node_equals_replay(ros_context):
    """Same bag, same predictions: stamps match, values equal the core model's exactly."""
    events = short_recording()
    preds, groups, diag, diags = play_through_node(events, {"reliable_qos": True},
                                                   context=ros_context, speed=0.5,
                                                   lockstep=True)
    assert diag["dropped_inputs"] == 0 and diag["skipped_inputs"] == 0
    ref, _ = replay_predictions(events)
    assert len(preds) == len(ref)
    for live, core in zip(sorted(preds, key=lambda p: p["stamp_s"]), ref):
        assert live["stamp_s"] == pytest.approx(core.stamp_s, abs=1e-9)
        assert live["torque_total_nm"] == core.torque_total_nm
        assert live["torque_b2b_nm"] == core.torque_b2b_nm
        check_prediction(live)
        check_prediction(core)
        assert live["n_groups"] == len(core.groups) and live["converged"]
    # contact groups: ball ids in order, one force between consecutive balls, forces >= 0
    assert groups, "contact groups are published at a rate and on change"
    for msg in groups:
        assert msg.n_balls == 37
        for g in msg.groups:
            assert len(g.b2b_forces_n) == len(g.ball_ids) - 1
            assert all(f >= 0 for f in g.b2b_forces_n)
    # the feedforward-relevant numbers are reported in /diagnostics
    keys = {kv.key for d in diags for s in d.status for kv in s.values}
    assert {"model_rate_hz", "lag_s", "nonconverged_steps", "rejected_total"} <= keys


def test_bad_input_is_counted_never_fatal(ros_context):
    """
    NaN, empty, wrong joint, absurd or NaN load, backwards stamps: counted, node lives.

    (A state before any load is covered by the runner's tests: the playback handshake
    gives the node its first load before anything else.)
    """
    j = ("nut_joint",)
    events = [
        Event("axial_load", 0.00, value=1500.0),
        Event("nut_state", 0.01, j, (0.06,), (6.0,)),
        Event("nut_state", 0.02, (), (), ()),                             # empty
        Event("nut_state", 0.03, ("elbow",), (0.1,), (6.0,)),             # wrong joint
        Event("nut_state", 0.04, j, (math.nan,), (6.0,)),                 # NaN
        Event("axial_load", 0.05, value=1e9),                             # absurd
        Event("axial_load", 0.05, value=math.inf),                        # non-finite
        Event("nut_state", 0.30, j, (0.36,), (6.0,)),
        Event("nut_state", 0.005, j, (0.40,), (6.0,)),        # bag loop (not a late stamp)
        Event("nut_state", 0.015, j, (0.46,), (6.0,)),
    ]
    preds, _, diag, _ = play_through_node(events, {"reliable_qos": True},
                                          context=ros_context, speed=0.2, lockstep=True)
    assert diag["rejected_empty"] == 1
    assert diag["rejected_wrong_joint"] == 1
    assert diag["rejected_non_finite"] == 2
    assert diag["rejected_absurd_load"] == 1
    assert diag["resets"] == 1
    assert len(preds) == 4 and diag["published"] == 4
    assert all(p["axial_load_n"] == 1500.0 for p in preds)   # bad loads never got through


def test_flood_is_survived_and_accounted(ros_context):
    """Inputs far faster than the model: every accepted input is answered or counted."""
    j = ("nut_joint",)
    events = [Event("axial_load", 0.0, value=1500.0)] + [
        Event("nut_state", 1e-4 * k, j, (6.0 * 1e-4 * k,), (6.0,)) for k in range(3000)]
    preds, _, diag, _ = play_through_node(events, {"queue_size": 32}, context=ros_context,
                                          speed=1e9)
    assert diag["published"] + diag["dropped_inputs"] + diag["shed_inputs"] \
        == diag["received_nut_state"]
    assert diag["published"] == len(preds) > 0
    # after the flood the node still answers
    more, _, _, _ = play_through_node(events[:3], {"reliable_qos": True}, context=ros_context,
                                      speed=0.5, lockstep=True)
    assert len(more) == 2


def test_parameters_are_validated_at_runtime(ros_context, tmp_path):
    node = FrictionNode(context=ros_context)
    try:
        ok = node.set_parameters([Parameter("nut_joint", value="screw_nut")])[0]
        assert ok.successful
        assert not node.set_parameters([Parameter("model_rate_hz", value=-5.0)])[0].successful
        res = node.set_parameters([Parameter("queue_size", value=10)])[0]
        assert not res.successful and "runtime" in res.reason
        res = node.set_parameters([Parameter("config_file", value=str(tmp_path / "x.yaml"))])
        assert not res[0].successful and "cannot read" in res[0].reason
        assert node.get_parameter("config_file").value == ""
    finally:
        node.destroy_node()


@pytest.mark.parametrize("name,value,needle", [
    ("model_rate_hz", 0.0, "model_rate_hz"),
    ("config_file", "/nonexistent/ball_screw.yaml", "cannot read"),
])
def test_bad_config_refuses_to_start(ros_context, name, value, needle):
    with pytest.raises(ConfigError, match=needle):
        FrictionNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_bad_ball_screw_yaml_refuses_to_start_naming_the_key(tmp_path, capsys):
    """friction_node --params-file with a bad model config exits 2 naming the key."""
    bad = tmp_path / "screw.yaml"
    bad.write_text("ball_screw:\n  geometry:\n    ball_radius_mm: -3\n")
    params = tmp_path / "params.yaml"
    params.write_text(f"friction_node:\n  ros__parameters:\n    config_file: '{bad}'\n")
    assert main(["friction_node", "--ros-args", "--params-file", str(params)]) == 2
    assert "ball_radius" in capsys.readouterr().err


def test_console_script_with_bundled_params_file(ros_context, repo_root):
    """
    friction_node --ros-args --params-file config/friction_node.yaml answers inputs.

    The script is found wherever the package is installed: beside the venv's python, or in
    lib/bb_friction_ros of a colcon workspace (colcon test).
    """
    import subprocess
    import time
    from bb_friction_msgs.msg import FrictionPrediction
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    proc = subprocess.Popen([console_script("friction_node"), "--ros-args", "--params-file",
                             str(repo_root / "config" / "friction_node.yaml")])
    io = Node("script_probe", context=ros_context)
    got = []
    io.create_subscription(FrictionPrediction, interface.PREDICTION, got.append, 10)
    pub_s = io.create_publisher(JointState, interface.NUT_STATE, 10)
    pub_l = io.create_publisher(WrenchStamped, interface.AXIAL_LOAD, 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(io)
    try:
        # generous: a fresh install (colcon test) compiles the model kernels on a loaded machine
        deadline = time.monotonic() + 180.0
        k = 0
        while not got and time.monotonic() < deadline and proc.poll() is None:
            load = WrenchStamped()
            load.wrench.force.z = 1500.0
            pub_l.publish(load)
            msg = JointState(name=["nut_joint"], position=[0.01 * k], velocity=[6.0])
            msg.header.stamp.sec, msg.header.stamp.nanosec = 100, 1_000_000 * k
            pub_s.publish(msg)
            k += 1
            ex.spin_once(timeout_sec=0.05)
        assert proc.poll() is None, "friction_node exited"
        assert got and got[0].converged and got[0].torque_total_nm > 0
        assert got[0].header.stamp.sec == 100
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        ex.shutdown()
        io.destroy_node()


def test_harness_publishes_inputs_and_collects_outputs(tmp_path):
    """The public harness: a params file, publish helpers, every collector, its own domain."""
    from bb_friction_ros.harness import FrictionNodeHarness
    params = tmp_path / "params.yaml"
    params.write_text("friction_node:\n  ros__parameters:\n    nut_joint: screw_nut\n"
                      "    diagnostics_rate_hz: 20.0\n")
    with FrictionNodeHarness(params_file=params, parameters={"model_rate_hz": 200.0},
                             domain_id=77) as h:
        assert h.node.get_parameter("nut_joint").value == "screw_nut"
        assert h.node.get_parameter("model_rate_hz").value == 200.0
        assert h.context.get_domain_id() == 77
        h.publish_axial_load(1500.0, stamp_s=10.0)
        h.publish_nut_state(0.0, 6.0, stamp_s=10.001)
        h.publish_nut_state(0.01, 6.0, stamp_s=10.002, joint="elbow")     # rejected
        pred = h.predictions.wait_for(1)[0]
        assert (pred.header.stamp.sec, pred.header.stamp.nanosec) == (10, 1_000_000)
        assert pred.converged and pred.axial_load_n == 1500.0
        ff = h.feedforward.wait_for(1)[0]
        assert list(ff.data) == [averaged_feedforward(pred)]
        assert h.contact_groups.wait_for(1)[0].n_balls == 37
        diag = h.diagnostics.wait_until(lambda m: any(
            kv.key == "rejected_wrong_joint" for s in m.status for kv in s.values))
        assert diag.status[0].level != 0           # a rejection makes it a warning
        assert h.diagnostics_values()["rejected_wrong_joint"] == 1
        # generic collectors: one per topic, any type; a missing one times out, named
        assert h.collect("friction/feedforward", "std_msgs/msg/Float64MultiArray") \
            is h.feedforward
        with pytest.raises(TimeoutError, match="friction/prediction: 1 of 2"):
            h.predictions.wait_for(2, timeout_s=0.3)
        with pytest.raises(ValueError, match="not available"):
            h.collect("nowhere", "bb_friction_msgs/msg/NoSuchMessage")


def test_harness_follows_remapped_inputs():
    """The node's inputs are ordinary names: remapping moves them (a namespaced robot)."""
    from bb_friction_ros.harness import FrictionNodeHarness
    remap = ["-r", "nut_state:=/robot/nut_state", "-r", "axial_load:=/robot/axial_load"]
    with FrictionNodeHarness(ros_args=remap,
                             input_topics=("/robot/nut_state", "/robot/axial_load")) as h:
        h.publish_axial_load(1500.0, stamp_s=1.0)
        h.publish_nut_state(0.0, -6.0, stamp_s=1.001)
        assert h.predictions.wait_for(1)[0].torque_total_nm < 0


def test_readme_pytest_example_runs_with_the_plugin_fixture(tmp_path, repo_root):
    """The README's ten-line controller test runs as written, via the pytest11 entry point."""
    import re
    import subprocess
    import sys
    text = (repo_root / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    example = next(b for b in blocks if "def test_" in b and "friction_node" in b)
    (tmp_path / "test_readme_example.py").write_text(example)
    import os
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           str(tmp_path / "test_readme_example.py")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout


BAD_MODEL_FILES = {   # each used to kill the node or give a traceback
    "int_key.yaml": ("1: 2\n", "ball_screw: key 1 is not a name"),
    "float_balls.yaml": ("ball_screw:\n  track: {n_balls: 37.7}\n",
                         "ball_screw.track.n_balls: must be an integer"),
    "list_section.yaml": ("ball_screw: [1]\n", "ball_screw: expected a mapping, got list"),
    "top_list.yaml": ("- 1\n", "expected a mapping of keys at top level, got list"),
    "duplicate.yaml": ("ball_screw:\n  track: {n_balls: 30}\n  track: {n_balls: 31}\n",
                       "key 'track' given twice"),
    "binary.yaml": (bytes(range(256)), "not a text file"),
}


def _write(path, content):
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


def test_bad_config_file_at_runtime_is_refused_and_the_node_lives(ros_context, tmp_path):
    node = FrictionNode(context=ros_context)
    try:
        runner = node.live.runner
        for name, (content, needle) in BAD_MODEL_FILES.items():
            path = _write(tmp_path / name, content)
            res = node.set_parameters([Parameter("config_file", value=str(path))])[0]
            assert not res.successful and needle in res.reason, (name, res.reason)
            assert node.get_parameter("config_file").value == ""
            assert node.live.runner is runner         # nothing applied
        good = _write(tmp_path / "good.yaml", "ball_screw:\n  track: {n_balls: 30}\n")
        assert node.set_parameters([Parameter("config_file", value=str(good))])[0].successful
        assert node.live.runner is not runner         # applied after validation
    finally:
        node.destroy_node()


@pytest.mark.parametrize("name", sorted(BAD_MODEL_FILES))
def test_bad_config_file_at_start_up_is_a_clean_refusal(tmp_path, capsys, name):
    content, needle = BAD_MODEL_FILES[name]
    path = _write(tmp_path / name, content)
    params = tmp_path / "params.yaml"
    params.write_text(f"friction_node:\n  ros__parameters:\n    config_file: '{path}'\n")
    assert main(["friction_node", "--ros-args", "--params-file", str(params)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_node_refuses_what_replay_refuses(ros_context):
    """The node's descriptors come from NodeParameters: same defaults, same refusals."""
    from test_node_parameters import BAD_VALUES
    from bb_friction_ros.node import PARAMETERS
    assert {k: d for k, (d, _) in PARAMETERS.items()} == dataclasses.asdict(NodeParameters())
    for name, value, _ in BAD_VALUES:
        with pytest.raises(ConfigError, match=name):
            FrictionNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_model_rate_is_not_negative_after_a_runtime_rebuild(ros_context):
    """The rate window used to keep the old runner's step count, giving one negative rate."""
    from bb_friction_ros.runner import InputSample
    node = FrictionNode(context=ros_context)
    try:
        for k in range(20):
            node.live.runner.process(InputSample(0.01 * k, 0.06 * k, 6.0, 1500.0))
        steps = node.live.runner.stats.model_steps
        node.diagnostics_values()              # the rate window starts with these steps
        assert node.set_parameters([Parameter("model_rate_hz", value=50.0)])[0].successful
        values, _ = node.diagnostics_values()
        assert values["model_rate_hz"] >= 0.0 and values["model_steps"] == steps >= 20
    finally:
        node.destroy_node()


def test_reset_note_is_reported_once(ros_context):
    """The diagnostics status names a reset in the one status after it, then clears."""
    j = ("nut_joint",)
    events = [Event("axial_load", 0.0, value=1500.0)]
    events += [Event("nut_state", 0.01 * k, j, (0.06 * k,), (6.0,)) for k in range(1, 20)]
    events += [Event("nut_state", 0.005 + 0.01 * k, j, (0.06 * k,), (6.0,))     # loop
               for k in range(60)]
    _, _, diag, diags = play_through_node(events, {"diagnostics_rate_hz": 20.0},
                                          context=ros_context, speed=1.0)
    messages = [s.message for d in diags for s in d.status]
    noted = [k for k, m in enumerate(messages) if "went backwards" in m]
    assert diag["resets"] == 1 and len(noted) == 1
    assert noted[0] < len(messages) - 1       # later statuses no longer carry it
