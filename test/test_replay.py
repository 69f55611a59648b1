"""Bags in both storage formats and the replay command."""

import csv
import json
import math

import numpy as np
import pytest

from bb_friction_ros.bags import Event, read_events, with_measurement, write_events
from bb_friction_ros.cli import main
from bb_friction_ros.config import bundled_config
from recordings import averaged_feedforward, short_recording


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bag_round_trip_keeps_log_order(tmp_path, storage):
    """Both storage formats give back the events in log order, backwards stamps included."""
    events = [Event("axial_load", 0.0, value=1500.0),
              Event("nut_state", 0.01, ("nut_joint",), (0.1,), (6.0,)),
              Event("measured_torque", 0.01, value=0.2),
              Event("nut_state", 0.005, ("nut_joint",), (0.2,), (6.0,))]
    write_events(tmp_path / "bag", events, storage=storage, log_times_s=[0, 1, 2, 3])
    back, counts = read_events(tmp_path / "bag")
    assert back == events
    assert counts == {"/nut_state": 2, "/axial_load": 1, "/measured_torque": 1}


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_replay_writes_prediction_summary_and_plots(tmp_path, capsys, storage):
    events = short_recording()
    write_events(tmp_path / "bag", events, storage=storage)
    code = main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress"])
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    n_states = sum(e.kind == "nut_state" for e in events)
    assert len(rows) == n_states
    assert list(rows[0]) == ["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                             "torque_pred_nm", "torque_b2b_nm", "torque_meas_nm", "converged"]
    assert {r["converged"] for r in rows} == {"1"}
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["messages"]["/nut_state"] == n_states
    assert summary["rejected"] == {} and summary["nonconverged_steps"] == 0
    assert summary["rmse_nm"] > 0 and summary["speed_vs_realtime"] > 0
    assert (tmp_path / "out" / "replay_torque_and_groups.png").stat().st_size > 10_000
    # friction opposes motion: the predicted torque has the sign of the nut speed
    for r in rows:
        if abs(float(r["nut_velocity_rad_s"])) > 1.0:
            assert float(r["torque_pred_nm"]) * float(r["nut_velocity_rad_s"]) > 0


def test_replay_counts_rejected_inputs(tmp_path):
    """Bad messages in a bag are counted with their reason, and the rest is replayed."""
    events = [Event("nut_state", 0.0, ("nut_joint",), (0.0,), (6.0,)),       # before a load
              Event("axial_load", 0.0, value=1500.0),
              Event("nut_state", 0.01, ("nut_joint",), (0.06,), (6.0,)),
              Event("nut_state", 0.02, ("wrong",), (0.12,), (6.0,)),
              Event("axial_load", 0.02, value=float("nan")),
              Event("nut_state", 0.03, ("nut_joint",), (float("nan"),), (6.0,)),
              Event("nut_state", 0.04, ("nut_joint",), (0.24,), (6.0,))]
    write_events(tmp_path / "bag", events)
    from bb_friction_ros.replay import replay
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    assert summary["samples"] == 2
    assert summary["rejected"] == {"no_load_yet": 1, "wrong_joint": 1, "non_finite": 2}


def test_replay_of_a_missing_bag_is_a_clear_error(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "no such bag" in capsys.readouterr().err


# --- the output bag -----------------------------------------------------------------------

def _replay_short(tmp_path, storage="mcap", extra=()):
    events = short_recording()
    write_events(tmp_path / "bag", events, storage=storage)
    code = main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress", *extra])
    return events, code


def test_replay_bag_read_back_with_rosbags(tmp_path):
    """DIR/bag: inputs copied, one prediction and feedforward per sample, at input stamps."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores
    events, code = _replay_short(tmp_path, storage="sqlite3")
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    store = get_typestore(Stores.ROS2_JAZZY)     # plain Jazzy: our types come from the bag
    got = {}
    assert len(list((tmp_path / "out" / "bag").glob("*.mcap"))) == 1
    with Reader(tmp_path / "out" / "bag") as reader:
        for conn in reader.connections:
            if conn.msgtype not in store.types:
                from rosbags.typesys import get_types_from_msg
                store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, log_ns, raw in reader.messages():
            got.setdefault(conn.topic, []).append((log_ns, store.deserialize_cdr(
                raw, conn.msgtype)))
    from bb_friction_ros.ball_screw.arrangement import mean_b2b
    from bb_friction_ros.model_file import load_ball_screw
    mean = mean_b2b(load_ball_screw(bundled_config("ball_screw.yaml")))
    n_states = sum(e.kind == "nut_state" for e in events)
    assert len(got["/nut_state"]) == n_states and len(got["/axial_load"]) == \
        sum(e.kind == "axial_load" for e in events)
    assert len(got["/measured_torque"]) == n_states
    preds = got["/friction/prediction"]
    assert len(preds) == len(rows) == n_states == len(got["/friction/feedforward"])
    for (log_ns, p), row, (_, ff), (_, state) in zip(preds, rows, got["/friction/feedforward"],
                                                     got["/nut_state"]):
        stamp = p.header.stamp.sec * 1_000_000_000 + p.header.stamp.nanosec
        assert log_ns == stamp == state.header.stamp.sec * 1_000_000_000 \
            + state.header.stamp.nanosec
        assert p.torque_total_nm == float(row["torque_pred_nm"])
        # the feedforward: the physics averaged over arrangements (no fitted terms here)
        assert ff.data[0] == mean.total_at(p.axial_load_n, p.nut_velocity_rad_s)
        assert p.converged
    groups = got["/friction/contact_groups"]
    assert groups and all(g.n_balls == 37 for _, g in groups)
    # n_groups is the size of the contact-group status in force at the prediction's stamp
    # (written on change, at the stamp of the prediction that changed it)
    k = -1
    for log_ns, p in preds:
        while k + 1 < len(groups) and groups[k + 1][0] <= log_ns:
            k += 1
        assert k >= 0 and p.n_groups == len(groups[k][1].groups)


def test_replay_bag_decodes_with_the_mcap_library_alone(tmp_path):
    """An independent reader (mcap-ros2-support) decodes every topic from the embedded schemas."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    events, code = _replay_short(tmp_path)
    assert code == 0
    (mcap_file,) = (tmp_path / "out" / "bag").glob("*.mcap")
    topics = {}
    with open(mcap_file, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            topics.setdefault(channel.topic, []).append((schema.name, message.log_time, msg))
    n_states = sum(e.kind == "nut_state" for e in events)
    preds = topics["/friction/prediction"]
    assert len(preds) == n_states
    name, log_time, first = preds[0]
    assert name == "bb_friction_msgs/msg/FrictionPrediction"
    assert first.converged and first.torque_total_nm > 0
    assert log_time == first.header.stamp.sec * 10**9 + first.header.stamp.nanosec
    assert [m.data[0] for _, _, m in topics["/friction/feedforward"]] == \
        [averaged_feedforward(m) for _, _, m in preds]
    assert topics["/friction/contact_groups"][0][2].n_balls == 37
    assert len(topics["/nut_state"]) == n_states
    assert topics["/nut_state"][0][2].name == ["nut_joint"]


def test_packed_prediction_and_feedforward_are_rosbags_own_cdr():
    """replay packs the two per-sample messages itself: byte for byte what rosbags writes."""
    from bb_friction_ros.bags import friction_typestore
    from bb_friction_ros.replay import (FEEDFORWARD_TOPIC, feedforward_cdr, prediction_cdr,
                                        PREDICTION_TOPIC)
    from bb_friction_ros.runner import Prediction
    store = friction_typestore()
    t = store.types
    rng = np.random.default_rng(3)
    for k in range(50):
        v = rng.normal(0.0, 10.0, 10)
        stamp = int(rng.integers(0, 2**31 - 1)) * 1_000_000_000 + int(rng.integers(0, 10**9))
        groups = tuple(((1, 2), (3.0,)) for _ in range(k % 4))
        pred = Prediction(0.0, *v[:7], bool(k % 3), v[7], groups, 37, False, v[8], False,
                          v[4] + 1.0, bool(k % 2), k % 3, abs(v[5]) / 100.0)
        sec, nanosec = divmod(stamp, 1_000_000_000)
        header = t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id="")
        msg = t[PREDICTION_TOPIC[1]](
            header=header, nut_angle_rad=v[0], nut_velocity_rad_s=v[1], axial_load_n=v[2],
            torque_total_nm=v[3], torque_b2g_nm=v[4], torque_b2b_nm=v[5],
            torque_empirical_nm=v[6], converged=bool(k % 3), model_latency_s=v[9],
            model_age_s=v[7], n_groups=len(groups), torque_state_nm=v[4] + 1.0,
            state_other_direction=bool(k % 2), arrangement=k % 3,
            arrangement_confidence=abs(v[5]) / 100.0)
        assert prediction_cdr(pred, sec, nanosec, v[9]) == \
            bytes(store.serialize_cdr(msg, PREDICTION_TOPIC[1], little_endian=True))
        ff = t[FEEDFORWARD_TOPIC[1]](layout=t["std_msgs/msg/MultiArrayLayout"](
            dim=[], data_offset=0), data=np.array([v[8]]))
        assert feedforward_cdr(v[8]) == \
            bytes(store.serialize_cdr(ff, FEEDFORWARD_TOPIC[1], little_endian=True))


def test_packed_contact_groups_are_rosbags_own_cdr():
    """The contact-group status is packed by replay too: byte for byte rosbags' CDR."""
    from bb_friction_ros.bags import friction_typestore
    from bb_friction_ros.replay import groups_cdr, GROUPS_TOPIC
    store = friction_typestore()
    t = store.types
    rng = np.random.default_rng(1)
    for k in range(200):
        groups = []
        for _ in range(k % 5):       # none to four groups; odd sizes move the alignment
            n = int(rng.integers(0, 6))
            ids = tuple(int(x) for x in rng.integers(0, 2**32 - 1, n))
            n_forces = max(0, n - 1) if k % 7 else int(rng.integers(0, 4))
            groups.append((ids, tuple(float(x) for x in rng.normal(0.0, 5.0, n_forces))))
        sec, nanosec = int(rng.integers(0, 2**31 - 1)), int(rng.integers(0, 10**9))
        angle, n_balls = float(rng.normal()), int(rng.integers(0, 100))
        header = t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id="")
        msg = t[GROUPS_TOPIC[1]](header=header, nut_angle_rad=angle, n_balls=n_balls, groups=[
            t["bb_friction_msgs/msg/ContactGroup"](
                ball_ids=np.array(ids, dtype=np.uint32),
                b2b_forces_n=np.array(forces, dtype=np.float64)) for ids, forces in groups])
        assert groups_cdr(tuple(groups), sec, nanosec, angle, n_balls) == \
            bytes(store.serialize_cdr(msg, GROUPS_TOPIC[1], little_endian=True)), groups


def test_replay_bag_feedforward_is_the_safe_value_of_unconverged_steps(tmp_path):
    """The output bag's feedforward carries the runner's safe value, as the node."""
    from rosbags.rosbag2 import Reader
    from bb_friction_ros.bags import friction_typestore
    from bb_friction_ros.replay import _OutputBag
    from bb_friction_ros.runner import Prediction
    good = Prediction(1.0, 0.0, 6.0, 1500.0, 0.21, 0.2, 0.01, 0.0, True, 0.0, (), 37, True,
                      feedforward_nm=0.21)
    bad = Prediction(1.01, 0.06, 6.0, 2e4, -58.0, -50.0, -8.0, 0.0, False, 0.0, (), 37, True,
                     feedforward_nm=0.21, feedforward_held=True)
    out = _OutputBag(tmp_path / "bag", [])
    for pred in (good, bad):
        stamp = int(round(pred.stamp_s * 1e9))
        out.publish(pred, stamp, stamp, 0.001)
    out.close()
    store = friction_typestore()
    got = {}
    with Reader(tmp_path / "bag") as reader:
        for conn, _, raw in reader.messages():
            got.setdefault(conn.topic, []).append(store.deserialize_cdr(raw, conn.msgtype))
    assert [m.data[0] for m in got["/friction/feedforward"]] == [0.21, 0.21]
    assert [(m.converged, m.torque_total_nm) for m in got["/friction/prediction"]] == \
        [(True, 0.21), (False, -58.0)]


def test_replay_no_bag_writes_only_csv_summary_and_plots(tmp_path):
    _, code = _replay_short(tmp_path, extra=("--no-bag",))
    assert code == 0
    assert not (tmp_path / "out" / "bag").exists()
    assert (tmp_path / "out" / "prediction.csv").exists()
    assert "output_bag" not in json.loads((tmp_path / "out" / "summary.json").read_text())


def test_replay_prints_nonconverged_steps_and_converged_column(tmp_path, capsys):
    """Non-convergence is visible in the CSV and summary."""
    from bb_friction_ros.replay import _row_formats, csv_values
    from bb_friction_ros.runner import Prediction
    _, code = _replay_short(tmp_path, extra=("--no-bag",))
    printed = json.loads(capsys.readouterr().out.splitlines()[0])
    assert code == 0 and printed["nonconverged_steps"] == 0
    bad = Prediction(0.0, 0.0, 6.0, 2e4, -58.0, 0.0, 0.0, 0.0, False, 0.0, (), 37, True)
    assert (_row_formats(False, False) % csv_values(bad, False)).endswith(",0\r\n")


def test_csv_lines_are_what_csv_writer_writes():
    """replay formats its rows with one %-format: byte for byte csv.writer's lines."""
    import io
    from bb_friction_ros.replay import _row_formats
    rng = np.random.default_rng(2)
    odd = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1e-300, 5e-324, 1.7e308, 1e16, 0.1]
    for measured in (False, True):
        for empirical in (False, True):
            fh = io.StringIO()
            w = csv.writer(fh)
            lines = []
            for k in range(300):
                v = [float(x) for x in rng.normal(0.0, 10.0 ** rng.integers(-8, 12), 8)]
                v[k % 8] = odd[k % len(odd)]
                stamp = float(rng.uniform(0.0, 2e9)) if k % 5 else v[0]
                head = [f"{stamp:.9f}"] + [repr(x) for x in v[1:6]]
                meas = [repr(v[6])] if measured else []
                tail = ([repr(v[7])] if empirical else []) + [str(k % 2)]
                w.writerow(head + meas + tail)
                values = (stamp, *v[1:6]) + ((v[7],) if empirical else ()) + (k % 2,)
                if measured:
                    values = values[:6] + (v[6],) + values[6:]
                lines.append(_row_formats(measured, empirical) % values)
            assert "".join(lines) == fh.getvalue()


def test_csv_text_reusing_repeated_values_is_the_row_formats_text():
    """
    The stream writes its rows with _csv_text, which reuses the text of a speed, load or
    torque equal to the row before's: byte for byte _row_formats' lines, through repeats
    of 0.0 and -0.0, NaN, infinities and numpy floats equal to Python ones.
    """
    from bb_friction_ros.replay import _csv_text, _csv_values, _row_formats
    rng = np.random.default_rng(3)
    odd = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1e-300, 5e-324, 0.1, np.float64(0.1),
           np.float64(-0.0), 1.5, np.float64(1.5)]
    for measured in (False, True):
        for empirical in (False, True):
            rows, want, v = [], [], [float(x) for x in rng.normal(size=8)]
            for k in range(2000):
                for i in range(1, 8):   # each column held, changed, or odd
                    r = rng.random()
                    if r < 0.3:
                        v[i] = float(rng.normal(0.0, 10.0 ** rng.integers(-8, 12)))
                    elif r < 0.5:
                        v[i] = odd[int(rng.integers(0, len(odd)))]
                v[0] = float(rng.uniform(0.0, 2e9))
                # the answer (process_values' fields): b2g and the fields past the
                # converged flag are not written; the flag as bool, int or numpy bool
                flag = (k % 2 == 1, k % 3, np.bool_(k % 5))[k % 3]
                answer = (*v[:5], -7.5, v[5], v[7], flag, 0.0, (), 37, True)
                values = _csv_values(answer, empirical)
                assert values[:6] == tuple(v[:6]) and values[-1] == int(bool(flag))
                meas = v[6] if measured else None
                rows.append((answer, meas))
                full = values[:6] + (meas,) + values[6:] if measured else values
                want.append(_row_formats(measured, empirical) % full)
            assert _csv_text(rows, empirical) == "".join(want)


# --- bad input: nothing accepted, missing or wrong topics, namespaces ----------------------

def _run(tmp_path, events, *flags, topics=None, params=None):
    from bb_friction_ros.bags import Topics
    write_events(tmp_path / "bag", events, topics=topics or Topics())
    argv = ["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"), "--no-progress",
            *flags]
    if params:
        (tmp_path / "params.yaml").write_text(params)
        argv += ["--params-file", str(tmp_path / "params.yaml")]
    return main(argv)


def _states(joint="nut_joint", n=20, position=0.1, velocity=6.0):
    return [Event("axial_load", 0.0, value=1500.0)] + [
        Event("nut_state", 0.001 * (k + 1), (joint,) if joint else (),
              (position,) if joint else (), (velocity,) if joint else ()) for k in range(n)]


def test_replay_with_a_misnamed_joint_exits_2_saying_why_and_how(tmp_path, capsys):
    """Zero accepted is an error naming reasons, topics, joints, fix."""
    assert _run(tmp_path, _states(joint="nut")) == 2
    err = capsys.readouterr().err
    assert "no nut_state sample was accepted" in err
    assert "wrong_joint 20" in err
    assert "/nut_state (sensor_msgs/msg/JointState)" in err
    assert "/axial_load (geometry_msgs/msg/WrenchStamped)" in err
    assert "joint names seen on /nut_state: ['nut']" in err
    assert "--nut-joint nut" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["samples"] == 0 and summary["rejected"] == {"wrong_joint": 20}
    assert main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress", "--nut-joint", "nut"]) == 0


@pytest.mark.parametrize("case,events,params,reason", [
    ("zero-length arrays", _states(joint=None), None, "empty 20"),
    ("all NaN", _states(position=float("nan")), None, "non_finite 20"),
    ("no messages", [], None, "/nut_state has no messages"),
    ("only loads", [Event("axial_load", 0.001 * k, value=1500.0) for k in range(5)], None,
     "/nut_state has no messages"),
    ("every load above max_axial_load_n", _states(),
     "friction_node:\n  ros__parameters:\n    max_axial_load_n: 1000.0\n",
     "loads exceed max_axial_load_n = 1000 N"),
])
def test_replay_that_accepts_nothing_exits_2(tmp_path, capsys, case, events, params, reason):
    """Every case of 'nothing accepted' is an error with the reason."""
    assert _run(tmp_path, events, params=params) == 2, case
    err = capsys.readouterr().err
    assert "no nut_state sample was accepted" in err and reason in err
    assert "Traceback" not in err


def test_replay_refuses_a_negative_max_axial_load_as_the_node_does(tmp_path, capsys):
    """A negative max_axial_load_n is refused up front, by name."""
    params = "friction_node:\n  ros__parameters:\n    max_axial_load_n: -5.0\n"
    assert _run(tmp_path, _states(), params=params) == 2
    err = capsys.readouterr().err
    assert "friction_node.max_axial_load_n: must be >= 1.0 N" in err and "Traceback" not in err


def test_namespaced_topics_are_used_only_when_named(tmp_path, capsys):
    """/robot/... gives a hint, not a KeyError; the flags select it."""
    from bb_friction_ros.bags import Topics
    ns = Topics(nut_state="/robot/nut_state", axial_load="/robot/axial_load")
    assert _run(tmp_path, _states(), topics=ns) == 2
    err = capsys.readouterr().err
    assert "no topic /nut_state" in err and "--nut-state-topic /robot/nut_state" in err
    code = main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out2"),
                 "--no-progress", "--nut-state-topic", "/robot/nut_state",
                 "--axial-load-topic", "/robot/axial_load"])
    assert code == 0
    summary = json.loads((tmp_path / "out2" / "summary.json").read_text())
    assert summary["samples"] == 20
    assert summary["messages"] == {"/robot/nut_state": 20, "/robot/axial_load": 1}


def test_discrepancy_on_namespaced_topics_is_a_clear_error(tmp_path, capsys):
    """The same resolution serves the discrepancy workflow (exit 2, no KeyError)."""
    from bb_friction_ros.bags import Topics
    ns = Topics(nut_state="/robot/nut_state", axial_load="/robot/axial_load")
    write_events(tmp_path / "bag", _states(), topics=ns)
    assert main(["discrepancy", str(tmp_path / "bag"), "--out", str(tmp_path / "d"),
                 "--no-progress", "--no-plots"]) == 2
    assert "--nut-state-topic /robot/nut_state" in capsys.readouterr().err


def test_discrepancy_that_accepts_nothing_says_why_and_how(tmp_path, capsys):
    """discrepancy names the reasons, the bag's topics and joints, and the fix."""
    write_events(tmp_path / "bag", with_measurement(_states(joint="nut"), [0.2] * 20))
    assert main(["discrepancy", str(tmp_path / "bag"), "--out", str(tmp_path / "d"),
                 "--no-progress", "--no-plots"]) == 2
    err = capsys.readouterr().err
    for needle in ("no nut_state sample was accepted", "wrong_joint 20",
                   "/nut_state (sensor_msgs/msg/JointState)", "['nut']", "--nut-joint nut"):
        assert needle in err, err


def _bag_with_types(path, types):
    """A bag whose topics have the given types (one message each where we can build one)."""
    from bb_friction_ros.bags import BagWriter, _header, _wrench
    with BagWriter(path, storage="sqlite3") as out:
        store = out.store
        for topic, msgtype in types.items():
            conn = out.connection(topic, msgtype)
            if msgtype.endswith("WrenchStamped"):
                out.write(conn, 1, _wrench(store, 0.0, force_z=1500.0))
            elif msgtype.endswith("JointState"):
                out.write(conn, 2, store.types[msgtype](
                    header=_header(store, 0.001), name=["nut_joint"],
                    position=np.array([0.1]), velocity=np.array([6.0]), effort=np.zeros(0)))


@pytest.mark.parametrize("types,needles", [
    ({"/axial_load": "geometry_msgs/msg/WrenchStamped"},
     ["no topic /nut_state (sensor_msgs/msg/JointState)", "/axial_load (geometry_msgs"]),
    ({"/nut_state": "sensor_msgs/msg/JointState"},
     ["no topic /axial_load (geometry_msgs/msg/WrenchStamped)"]),
    ({"/nut_state": "geometry_msgs/msg/WrenchStamped", "/axial_load":
      "geometry_msgs/msg/WrenchStamped"},
     ["topic /nut_state has type geometry_msgs/msg/WrenchStamped, expected "
      "sensor_msgs/msg/JointState"]),
    ({"/nut_state": "geometry_msgs/msg/WrenchStamped", "/axial_load":
      "sensor_msgs/msg/JointState"},    # swapped topics
     ["topic /nut_state has type geometry_msgs/msg/WrenchStamped",
      "topics of type sensor_msgs/msg/JointState: /axial_load"]),
])
def test_missing_or_mistyped_topics_exit_2_naming_them(tmp_path, capsys, types, needles):
    """No input topic, wrong types, swapped topics: each named, exit 2."""
    _bag_with_types(tmp_path / "bag", types)
    assert main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "bag") in err and "Traceback" not in err
    for needle in needles:
        assert needle in err


def test_summary_counts_messages_read_not_metadata(tmp_path):
    """metadata.yaml claiming 99,999 messages does not fool the summary, and is warned about."""
    import yaml
    events = _states(n=45)
    write_events(tmp_path / "bag", events, storage="mcap")
    meta_path = tmp_path / "bag" / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    info = meta["rosbag2_bagfile_information"]
    info["message_count"] = 99_999
    for t in info["topics_with_message_count"]:
        t["message_count"] = 99_999
    meta_path.write_text(yaml.safe_dump(meta))
    from bb_friction_ros.replay import replay
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    assert summary["messages"]["/nut_state"] == 45
    assert summary["messages"]["/axial_load"] == 1
    # and the disagreement is said, not left for the user to find
    (listed,) = [w for w in summary["warnings"] if str(meta_path) in w]
    assert "99999 on /axial_load (1 read), 99999 on /measured_torque (0 read), " \
        "99999 on /nut_state (45 read)" in listed


def test_looping_bag_aligns_measurement_within_each_run(tmp_path):
    """
    A bag played twice with the same stamps.

    Each pass must be compared with its own measurement (0.1 then 0.3 N m here), not every
    row with the last pass's.
    """
    one = [Event("axial_load", 0.0, value=1500.0)]
    for k in range(10):
        one.append(Event("nut_state", 0.01 * (k + 1), ("nut_joint",), (0.06 * k,), (6.0,)))
    loop = with_measurement(one, [0.1] * 10) + with_measurement(one, [0.3] * 10)
    write_events(tmp_path / "bag", loop, storage="mcap",
                 log_times_s=[0.001 * i for i in range(len(loop))])
    from bb_friction_ros.replay import replay
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False, write_bag=False)
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    assert summary["resets"] == 1 and len(rows) == 20
    assert [float(r["torque_meas_nm"]) for r in rows] == [0.1] * 10 + [0.3] * 10


def test_replay_streams_in_bounded_memory(tmp_path, monkeypatch):
    """
    Replay holds no message or prediction after it is answered.

    Near the end of a 3000-sample bag the Python objects alive are counted: a replay that
    reads the bag into a list first, or keeps its predictions (as replay once did, ~1 kB a
    sample: 1.2 GB for a 10-minute 1 kHz bag), holds thousands.  The plotted series go to a
    temporary file.  bench/bench_replay.py measures the process's peak RSS on that bag.
    """
    import gc
    from bb_friction_ros import bags
    from bb_friction_ros.bags import BagInput
    from bb_friction_ros.replay import replay, _Series
    from bb_friction_ros.runner import Prediction
    n = 3000
    events = [Event("axial_load", 0.0, value=1500.0)]
    events += [Event("nut_state", 0.001 * (k + 1), ("nut_joint",), (0.006 * k,), (6.0,))
               for k in range(n)]
    write_events(tmp_path / "bag", with_measurement(events, [0.2] * n), storage="mcap")
    del events
    alive = {}
    blocks = BagInput.blocks

    def count(kind):     # other tests' parameters hold a few Events too
        gc.collect()
        return sum(isinstance(o, kind) for o in gc.get_objects())

    before = {"events": count(Event), "predictions": count(Prediction)}

    def counting(self, *args, **kwargs):
        read = 0
        for block in blocks(self, *args, **kwargs):
            read += len(block.items)
            if read >= 2 * n - 10 and not alive:   # nut_state and measured_torque: the end
                alive["events"] = count(Event) - before["events"]
                alive["predictions"] = count(Prediction) - before["predictions"]
                alive["series_rows_in_memory"] = sum(
                    len(o._buf) // len(o.COLUMNS) for o in gc.get_objects()
                    if isinstance(o, _Series))
            yield block

    # blocks of messages are read at once: small ones, so that many are behind at the end
    monkeypatch.setattr(bags, "READ_BLOCK", 100)
    monkeypatch.setattr(BagInput, "blocks", counting)
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    assert summary["samples"] == n and alive, alive
    assert alive["events"] < 20 and alive["predictions"] < 20, alive
    assert alive["series_rows_in_memory"] <= _Series.BUFFER_ROWS, alive


def test_plotted_series_decimates_in_bounded_memory():
    """
    The plot's min/max envelope is built a buffer at a time.

    200k rows (12.8 MB of float64) give at most 2 points per bucket, keep every extreme,
    and the decimation holds < 3 MB at its peak (a kept view of each block held them all).
    """
    import tracemalloc
    from bb_friction_ros.replay import _Series
    series = _Series(measured=False)
    n = 200_000
    # answers as process_values gives them: stamp, angle, speed, load, torque, b2g, b2b, ...,
    # groups; the largest group cycles through 0..6 balls
    groups = [((tuple(range(j)), ()),) for j in range(7)]
    for k0 in range(0, n, 1000):
        series.add_rows([((0.001 * k, 0.0, 6.0, 1500.0, math.sin(k / 500.0), 0.0, 0.0, 0.0,
                           True, 0.0, groups[k % 7]), math.nan)
                         for k in range(k0, k0 + 1000)], measured=False)
    tracemalloc.start()
    try:
        c = series.decimated(buckets=2000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        series.close()
    assert len(c["t"]) <= 2 * 2000 + 2 and len(c["torque"]) == len(c["t"])
    assert c["torque"].max() == pytest.approx(1.0, abs=1e-6) and c["largest"].max() == 6.0
    assert c["t"][0] == 0.0 and c["t"][-1] <= 0.001 * (n - 1)
    assert peak < 3_000_000, peak


# --- real bags with a late stamp, a far-future stamp, reruns -------------------------------------

def _late_bag(path, late_index=None, late_by_s=0.0105, segment_s=1.5):
    """A 3 s, 1 kHz recording with measured torque; one nut_state stamp moved (header only).

    Log times stay the true times, as a recorder receiving the messages writes them.
    """
    import dataclasses
    events = short_recording(state_rate_hz=1000.0, segment_s=segment_s)
    log_times = [e.stamp_s for e in events]
    k = -1
    for i, e in enumerate(events):
        if e.kind == "nut_state":
            k += 1
            if k == late_index:
                new = e.stamp_s - late_by_s if late_by_s < 1e6 else late_by_s
                events[i] = dataclasses.replace(e, stamp_s=new)
    write_events(path, events, storage="mcap", log_times_s=log_times)
    return sum(e.kind == "nut_state" for e in events)


def _measured_column(out):
    rows = list(csv.DictReader(open(out / "prediction.csv")))
    return np.array([float(r["torque_meas_nm"]) for r in rows])


def test_one_late_nut_state_stamp_keeps_the_measurement(tmp_path):
    """A stamp 10.5 ms late in a real bag; every row keeps its measured torque.

    It used to cut the prediction stream alone: 3/4 of the rows had no measurement and
    rmse_nm covered the first quarter of the recording."""
    from bb_friction_ros.replay import replay
    n = _late_bag(tmp_path / "late", late_index=750)
    _late_bag(tmp_path / "clean")
    late = replay(tmp_path / "late", tmp_path / "o_late", progress=False, write_bag=False)
    clean = replay(tmp_path / "clean", tmp_path / "o_clean", progress=False, write_bag=False)
    meas_late, meas_clean = _measured_column(tmp_path / "o_late"), \
        _measured_column(tmp_path / "o_clean")
    assert len(meas_late) == n and np.isfinite(meas_late).sum() == np.isfinite(meas_clean).sum()
    assert np.isfinite(meas_late).sum() >= n - 1
    assert late["measured_rows"] == clean["measured_rows"] >= n - 1
    assert late["measured_alignment"]["runs"] == {"prediction": 1, "measured": 1}
    assert late["measured_alignment"]["late_stamps"]["prediction"] == 1
    assert late["warnings"] == []
    # each row is paired with the measurement at its own stamp: the same as without the
    # late stamp but for the late row itself (interpolated 10.5 ms earlier)
    differ = np.flatnonzero(meas_late != meas_clean)
    assert differ.tolist() == [750]
    # rmse_nm covers every row (the runner's reset at the late stamp changes the predictions
    # after it, which is the runner's business, not the alignment's)
    rows = list(csv.DictReader(open(tmp_path / "o_late" / "prediction.csv")))
    err = np.array([float(r["torque_meas_nm"]) - float(r["torque_pred_nm"]) for r in rows])
    assert late["rmse_nm"] == pytest.approx(np.sqrt(np.nanmean(err ** 2)), rel=1e-9)


def test_one_far_future_stamp_does_not_stretch_the_duration(tmp_path):
    """One header stamp at 2e9 s: the summary keeps the recording's 3 s (log time)."""
    from bb_friction_ros.replay import replay
    n = _late_bag(tmp_path / "bag", late_index=1000, late_by_s=2.0e9)
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False, write_bag=False)
    assert summary["duration_s"] == pytest.approx(3.0, abs=0.01)
    assert summary["speed_vs_realtime"] < 1e4
    assert summary["measured_alignment"]["stamps_far_ahead"]["prediction"] == 1
    assert summary["measured_rows"] >= n - 2        # the far one, and at most its neighbour


def test_no_bag_rerun_removes_the_stale_bag_and_summary(tmp_path):
    """replay --no-bag into an earlier --out: the old bag/ (and plot) are removed."""
    write_events(tmp_path / "in", short_recording(), storage="mcap")
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "in"), "--out", str(out), "--no-progress"]) == 0
    assert (out / "bag" / "metadata.yaml").exists()
    first = json.loads((out / "summary.json").read_text())
    assert first["complete"] is True and "output_bag" in first
    assert main(["replay", str(tmp_path / "in"), "--out", str(out), "--no-progress",
                 "--no-bag"]) == 0
    assert not (out / "bag").exists()
    second = json.loads((out / "summary.json").read_text())
    assert second["complete"] is True and "output_bag" not in second


def test_replay_refuses_to_overwrite_its_input_bag(tmp_path, capsys):
    """The input is OUT/bag (an earlier replay's output bag): refused, not deleted."""
    write_events(tmp_path / "in", short_recording(), storage="mcap")
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "in"), "--out", str(out), "--no-progress"]) == 0
    assert main(["replay", str(out / "bag"), "--out", str(out), "--no-progress"]) == 2
    assert "replay's own output bag" in capsys.readouterr().err
    assert (out / "bag" / "metadata.yaml").exists()


def test_ctrl_c_leaves_no_stale_summary_and_exits_130(tmp_path):
    """SIGINT during a replay into an earlier --out: no traceback, exit 130, and no
    summary.json of the earlier run beside the partial outputs (it says complete: false)."""
    import os
    import signal
    import subprocess
    import sys
    import time as clock
    write_events(tmp_path / "small", short_recording(), storage="mcap")
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "small"), "--out", str(out), "--no-progress"]) == 0
    old_rows = len((out / "prediction.csv").read_text().splitlines())
    _late_bag(tmp_path / "big", segment_s=30.0)                  # 60 s at 1 kHz
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([sys.executable, "-m", "bb_friction_ros.cli", "replay",
                             str(tmp_path / "big"), "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        # wait until the new run is writing well past the old file's rows
        deadline = clock.monotonic() + 240.0
        while clock.monotonic() < deadline and proc.poll() is None:
            try:
                if len((out / "prediction.csv").read_text().splitlines()) > old_rows + 500:
                    break
            except OSError:
                pass
            clock.sleep(0.2)
        assert proc.poll() is None, "the replay ended before it could be interrupted"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "interrupted" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["bag"] == str(tmp_path / "big")


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_streamed_replay_gives_run_events_predictions_and_rejections(tmp_path, storage):
    """
    replay decodes blocks with numpy and checks decoded samples inline; the node's
    path is run_events (InputAssembler, feed_event), which the live = replay tests compare
    with the node: both must give the same rows, values and rejection counts, on a recording
    with samples before any load, wrong and extra joints, NaN, absurd and NaN loads, stalls.
    """
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.node_parameters import NodeParameters
    from bb_friction_ros.replay import replay, run_events
    from bb_friction_ros.runner import build_runner, InputAssembler
    p = NodeParameters()
    w = 2.0 * math.pi
    events = [Event("nut_state", 0.0005, ("nut_joint",), (0.0,), (w,))]     # no load yet
    for k in range(600):
        t = 0.001 * (k + 1)
        if k % 10 == 0:
            load = {100: math.nan, 200: 5e9}.get(k, 1500.0 + k)
            events.append(Event("axial_load", t, value=load))
        names, pos, vel = ("nut_joint",), (w * t,), (w,)
        if k % 97 == 5:
            names, pos, vel = ("other",), (w * t,), (w,)
        elif k % 89 == 7:
            pos = (math.nan,)
        elif k % 61 == 3:
            names, pos, vel = ("a", "nut_joint"), (9.0, w * t), (0.0, w)
        elif k % 53 == 11:
            vel = ()
        events.append(Event("nut_state", t if k % 71 != 9 else t - 0.001, names, pos, vel))
    recorded = with_measurement(events, [0.3] * 601)
    # logged in list order (a stamp going back must not reorder the bag)
    write_events(tmp_path / "bag", recorded, storage=storage,
                 log_times_s=[1e-4 * i for i in range(len(recorded))])
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    runner = build_runner(bundled_config("ball_screw.yaml"), p.model_rate_hz)
    ref = run_events(events, runner, InputAssembler(p.nut_joint, p.max_axial_load_n))
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    assert len(rows) == len(ref) > 500 and summary["samples"] == len(ref)
    for row, pred in zip(rows, ref):
        assert float(row["t_s"]) == pytest.approx(pred.stamp_s, abs=1e-9)
        assert (float(row["nut_angle_rad"]), float(row["axial_load_n"]),
                float(row["torque_pred_nm"]), float(row["torque_b2b_nm"])) == \
            (pred.nut_angle_rad, pred.axial_load_n, pred.torque_total_nm, pred.torque_b2b_nm)
    assert summary["rejected"] == dict(runner.stats.rejected)
    assert {"no_load_yet", "wrong_joint", "non_finite", "absurd_load",
            "missing_velocity"} <= set(summary["rejected"]), summary["rejected"]
