"""interface.py is the one home of the node's topics, types and prediction field order."""

import ast
import pathlib
import re

from bb_friction_ros import interface
from bb_friction_ros.runner import Prediction

ROOT = pathlib.Path(__file__).resolve().parent.parent
MSG_DIR = ROOT / "msg_defs" / "bb_friction_msgs" / "msg"


def msg_fields(name):
    """Return [(type, field)] of a .msg file, comments and blank lines skipped."""
    out = []
    for line in (MSG_DIR / f"{name}.msg").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line and "=" not in line:        # constants are no fields
            kind, field = line.split()[:2]
            out.append((kind, field))
    return out


def test_prediction_field_order_is_the_msg_files():
    """PREDICTION_FIELDS lists FrictionPrediction.msg's fields after the header, in order."""
    fields = msg_fields("FrictionPrediction")
    assert fields[0] == ("std_msgs/Header", "header")
    assert interface.PREDICTION_FIELDS == tuple(f for _, f in fields[1:])


def test_prediction_values_follow_the_field_order():
    """Each value comes from the runner's Prediction attribute of the field's name."""
    names = [f.name for f in __import__("dataclasses").fields(Prediction)]
    assert set(interface.PREDICTION_FROM_RUNNER) <= set(names)
    values = {n: float(i + 1) for i, n in enumerate(names)}
    values.update(converged=True, state_other_direction=True, arrangement=1,
                  groups=((1, 2), ((3, 4), (5.0,))))
    pred = Prediction(**values)
    got = dict(zip(interface.PREDICTION_FIELDS, interface.prediction_values(pred, 0.25)))
    for name in interface.PREDICTION_FROM_RUNNER:
        assert got[name] == getattr(pred, name), name
    assert got["model_latency_s"] == 0.25 and got["n_groups"] == 2


def test_replay_cdr_layout_matches_the_field_types():
    """replay's packed CDR: one struct code per field, the .msg's type (float64 d, bool ?...)."""
    from bb_friction_ros import replay
    codes = {"float64": "d", "bool": "?", "uint32": "I", "uint8": "B"}
    fmt = re.sub(r"\d*x", "", replay._PREDICTION_CDR.format)       # padding is no field
    fmt = fmt.replace("<4siII1s", "")                                # encapsulation, header
    expanded = "".join(c * int(n or 1) for n, c in re.findall(r"(\d*)([a-z?A-Z])", fmt))
    assert expanded == "".join(codes[k] for k, _ in msg_fields("FrictionPrediction")[1:])


def test_every_type_named_exists():
    """Each message type in TYPES is importable (the node and the harness import them)."""
    import importlib
    for topic, name in interface.TYPES.items():
        pkg, sub, cls = name.split("/")
        assert hasattr(importlib.import_module(f"{pkg}.{sub}"), cls), (topic, name)


# A topic name or FrictionPrediction field written as a string literal outside interface.py
# would be a second home for it.
TOPIC_LITERALS = {interface.PREDICTION, interface.FEEDFORWARD, interface.PROFILE,
                  interface.CONTACT_GROUPS, "/" + interface.PREDICTION,
                  "/" + interface.FEEDFORWARD, "/" + interface.CONTACT_GROUPS}


def test_no_output_topic_is_written_twice():
    """No module of the package, bench or test spells an output topic but interface.py."""
    found = []
    for base in ("bb_friction_ros", "bench"):
        for path in sorted((ROOT / base).rglob("*.py")):
            if path.name == "interface.py":
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Constant) and node.value in TOPIC_LITERALS:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value!r}")
    assert not found, "\n".join(found)


def test_local_domain_id_is_off_the_default_domain():
    """1..101 from the pid, never the user's default 0, within DDS's domain range."""
    ids = {interface.local_domain_id(pid) for pid in range(0, 5000, 7)}
    assert min(ids) == 1 and max(ids) == 101


def test_the_workers_of_one_parallel_test_run_have_domains_of_their_own():
    """pytest -n N: the workers of one run (one parent) never share a ROS domain."""
    from conftest import session_domain_id
    ids = [session_domain_id({"PYTEST_XDIST_WORKER": f"gw{k}"}) for k in range(8)]
    assert len(set(ids)) == 8 and all(1 <= i <= 101 for i in ids)
    assert session_domain_id({}) == interface.local_domain_id()


def test_the_names_are_the_contract():
    """Topic names and types users script against (README): pinned here, once."""
    assert (interface.NUT_STATE, interface.AXIAL_LOAD, interface.MEASURED_TORQUE) == \
        ("nut_state", "axial_load", "measured_torque")
    assert interface.OUTPUTS == ("friction/prediction", "friction/feedforward",
                                 "friction/feedforward_profile", "friction/contact_groups",
                                 "friction/planned_feedforward")
    assert interface.PLANNED_TRAJECTORY == "friction/planned_trajectory"
    assert interface.TYPES[interface.PLANNED_TRAJECTORY] == \
        interface.TYPES[interface.PLANNED_FEEDFORWARD] == "trajectory_msgs/msg/JointTrajectory"
    assert interface.DIAGNOSTICS == "/diagnostics"
    assert interface.TYPES[interface.FEEDFORWARD] == "std_msgs/msg/Float64MultiArray"
    assert interface.TYPES[interface.NUT_STATE] == "sensor_msgs/msg/JointState"
    assert interface.TYPES[interface.AXIAL_LOAD] == "geometry_msgs/msg/WrenchStamped"
