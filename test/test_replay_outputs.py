"""
Replay's outputs as a user reads them.

The output bag keeps the recorder's time line whatever clock the driver stamped with; a run
that stops early leaves its outputs marked as partial, never unmarked; messages a bag holds
but no reader returns are counted and warned about.
"""

import csv
import errno
import json
import sqlite3
import subprocess
import sys

import numpy as np
import pytest

from bb_friction_ros.bags import _typestore, _wrench, Event, write_events
from bb_friction_ros.cli import main
from recordings import short_recording

# 2023-11-14 22:13:20 UTC: a recorder's log times.
EPOCH_LOG_S = 1.7e9
YEAR_S = 365.25 * 86400.0


def _read_bag(path):
    """Return [(topic, log time [ns], header stamp [ns] or None)] of a bag, in log order."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_types_from_msg
    store = _typestore()
    got = []
    with Reader(path) as reader:
        for conn in reader.connections:
            if conn.msgtype not in store.types:
                store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, log_ns, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            header = getattr(msg, "header", None)
            stamp = None if header is None else \
                header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
            got.append((conn.topic, log_ns, stamp))
    return got


def _shifted(events, by_s):
    return [Event(e.kind, e.stamp_s + by_s, e.names, e.positions, e.velocities, e.value)
            for e in events]


def _outputs_answer_their_inputs(got):
    """Assert each output is logged at its input's log time and carries its header stamp."""
    log_of_stamp = {stamp: log for topic, log, stamp in got if topic == "/nut_state"}
    outputs = [(topic, log, stamp) for topic, log, stamp in got
               if topic in ("/friction/prediction", "/friction/contact_groups")]
    assert outputs
    for topic, log, stamp in outputs:
        assert log == log_of_stamp[stamp], (topic, log, stamp)
    logs = [log for _, log, _ in got]
    assert logs == sorted(logs)            # one time line, in order: ros2 bag play, Foxglove


def test_device_clock_outputs_are_logged_at_their_inputs_log_time(tmp_path):
    """
    Header stamps from a device clock (0-0.5 s), log times in 2023: the output bag spans the
    recording's half second (it spanned 54 years: outputs were logged at header stamps).
    """
    events = short_recording()
    # a recorder's latency that varies: log time is not header stamp + a constant
    logs = [EPOCH_LOG_S + e.stamp_s + 1e-4 * (k % 7) for k, e in enumerate(events)]
    write_events(tmp_path / "bag", events, storage="mcap", log_times_s=logs)
    assert main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 0
    got = _read_bag(tmp_path / "out" / "bag")
    span_s = (max(log for _, log, _ in got) - min(log for _, log, _ in got)) * 1e-9
    assert span_s == pytest.approx(max(logs) - min(logs), abs=1e-6)
    assert span_s < 1.0 < 50 * YEAR_S
    _outputs_answer_their_inputs(got)
    # the outputs' header stamps are the device clock's, as the node stamps them
    preds = [stamp for topic, _, stamp in got if topic == "/friction/prediction"]
    assert 0 <= min(preds) and max(preds) < 1e9
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    assert [round(float(r["t_s"]) * 1e9) for r in rows] == preds


def test_header_stamps_before_1970_are_replayed_with_the_bag(tmp_path):
    """
    Header stamps in December 1969 (sec < 0), logged in 2023: exit 0, every output written
    with the input's stamp, at the input's log time (the output bag crashed with an
    OverflowError: outputs were logged at the header stamp, before a bag's time 0).
    """
    events = _shifted(short_recording(), -1.0e6)
    write_events(tmp_path / "bag", events, storage="mcap",
                 log_times_s=[EPOCH_LOG_S + 1.0e6 + e.stamp_s for e in events])
    assert main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    n_states = sum(e.kind == "nut_state" for e in events)
    assert summary["complete"] is True and summary["samples"] == n_states
    got = _read_bag(tmp_path / "out" / "bag")
    preds = [stamp for topic, _, stamp in got if topic == "/friction/prediction"]
    assert len(preds) == n_states and max(preds) < 0
    _outputs_answer_their_inputs(got)
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    assert [round(float(r["t_s"]) * 1e9) for r in rows] == preds


# --- a run that stops early ------------------------------------------------------------------

def _joint_state(store, k):
    msg = store.types["sensor_msgs/msg/JointState"](
        header=store.types["std_msgs/msg/Header"](
            stamp=store.types["builtin_interfaces/msg/Time"](sec=0, nanosec=1_000_000 * k),
            frame_id=""),
        name=["nut_joint"], position=np.array([0.006 * k]), velocity=np.array([6.0]),
        effort=np.zeros(0))
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


def _bag_damaged_at(path, damaged, n=400):
    """A 1 kHz bag of ``n`` nut states whose message number ``damaged`` is cut short."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    store = _typestore()
    load = bytes(store.serialize_cdr(_wrench(store, 0.0, force_z=1500.0),
                                     "geometry_msgs/msg/WrenchStamped"))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        nut = writer.add_connection("/nut_state", "sensor_msgs/msg/JointState", typestore=store)
        axial = writer.add_connection("/axial_load", "geometry_msgs/msg/WrenchStamped",
                                      typestore=store)
        writer.write(axial, 0, load)
        for k in range(1, n + 1):
            raw = _joint_state(store, k)
            writer.write(nut, 1_000_000 * k, raw if k != damaged else raw[:11])


def test_a_damaged_message_mid_bag_leaves_the_outputs_marked_partial(tmp_path, capsys):
    """
    Message 301 of 400 cannot be decoded, replayed into an --out used before: exit 2 naming
    the message and saying the outputs are partial; summary.json says "complete": false with
    the error; prediction.csv and bag/ hold exactly the 300 answers before it (the run left
    them with no summary at all, and the last block's rows unwritten).
    """
    write_events(tmp_path / "good", short_recording(), storage="mcap")
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "good"), "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    _bag_damaged_at(tmp_path / "bag", damaged=301)
    assert main(["replay", str(tmp_path / "bag"), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert str(tmp_path / "bag") in err and "damaged message 301 on /nut_state" in err
    assert f"the outputs in {out} are partial" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["bag"] == str(tmp_path / "bag")
    assert "damaged message 301 on /nut_state" in summary["error"]
    rows = list(csv.DictReader(open(out / "prediction.csv")))
    assert len(rows) == 300 and float(rows[-1]["t_s"]) == pytest.approx(0.300)
    got = _read_bag(out / "bag")
    assert sum(t == "/friction/prediction" for t, _, _ in got) == 300
    assert sum(t == "/nut_state" for t, _, _ in got) == 300      # not the damaged one


# Runs the CLI in a child whose file-size limit makes a write fail mid-run as a full disk does
# (EFBIG from write()); SIGXFSZ ignored so the write returns the error.
_LIMITED_CLI = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
from bb_friction_ros.cli import main
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[1]), resource.RLIM_INFINITY))
sys.exit(main(sys.argv[2:]))
"""


def test_a_run_stopped_by_a_full_disk_says_complete_false(tmp_path):
    """
    prediction.csv cannot grow past 16 KiB (a file-size limit, as a full disk): exit 2, and
    the small summary.json says "complete": false with the error beside the partial outputs.
    """
    write_events(tmp_path / "bag", short_recording(state_rate_hz=1000.0, segment_s=0.5))
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-c", _LIMITED_CLI, str(16 * 1024), "replay",
                          str(tmp_path / "bag"), "--out", str(out), "--no-progress",
                          "--no-bag"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "File too large" in run.stderr, run.stderr
    assert (out / "prediction.csv").stat().st_size <= 16 * 1024
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and "File too large" in summary["error"]


def test_outputs_that_cannot_be_marked_partial_are_removed(tmp_path, monkeypatch, capsys):
    """The disk is full when summary.json is written: no output is left to be taken whole."""
    from bb_friction_ros import replay as replay_module
    write_events(tmp_path / "bag", short_recording(), storage="mcap")

    def full_disk(out, summary):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(replay_module, "_write_summary", full_disk)
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "bag"), "--out", str(out), "--no-progress"]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == []


# --- messages no reader returns ----------------------------------------------------------------

def _orphan_rows(bag, n):
    """Give ``n`` nut_state rows of a sqlite3 bag a topic id its topics table lacks."""
    (db,) = bag.glob("*.db3")
    con = sqlite3.connect(db)
    (nut,) = con.execute("SELECT id FROM topics WHERE name = '/nut_state'").fetchone()
    con.execute("UPDATE messages SET topic_id = 99 WHERE id IN (SELECT id FROM messages "
                "WHERE topic_id = ? ORDER BY id LIMIT ? OFFSET 5)", (nut, n))
    con.commit()
    con.close()
    return db


@pytest.mark.parametrize("extra", [(), ("--no-bag",)], ids=["bag", "no-bag"])
def test_sqlite3_rows_of_an_unknown_topic_are_counted_and_warned(tmp_path, capsys, extra):
    """
    99 nut_state rows carry a topic id with no row in the topics table: rosbags never
    returns them.  The summary counts them (messages_of_unknown_topics) and warns, on
    stderr too, naming the file, and says metadata.yaml lists 99 more than were read (the
    rows were dropped without a word).
    """
    events = short_recording(state_rate_hz=1000.0, segment_s=0.1)
    write_events(tmp_path / "bag", events, storage="sqlite3")
    db = _orphan_rows(tmp_path / "bag", 99)
    out = tmp_path / "out"
    assert main(["replay", str(tmp_path / "bag"), "--out", str(out), "--no-progress",
                 *extra]) == 0
    err = capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    n_states = sum(e.kind == "nut_state" for e in events)
    assert summary["messages"]["/nut_state"] == n_states - 99
    assert summary["messages_of_unknown_topics"] == 99
    unknown = [w for w in summary["warnings"] if str(db) in w]
    assert len(unknown) == 1 and "99 messages" in unknown[0] and "id 99" in unknown[0]
    listed = [w for w in summary["warnings"] if "metadata.yaml" in w]
    assert len(listed) == 1 and f"{n_states} on /nut_state ({n_states - 99} read)" in listed[0]
    for warning in unknown + listed:
        assert f"warning: {warning}" in err


def test_a_bag_read_whole_has_no_unread_messages(tmp_path):
    """Control: the same bag untouched counts 0 unknown-topic messages and warns nothing."""
    write_events(tmp_path / "bag", short_recording(state_rate_hz=1000.0, segment_s=0.1),
                 storage="sqlite3")
    from bb_friction_ros.replay import replay
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    assert summary["messages_of_unknown_topics"] == 0
    assert summary["warnings"] == []


def test_an_output_bag_that_is_a_symlink_is_unlinked_not_followed(tmp_path):
    """OUT/bag a symlink to a directory of the user's: replay removes the link, never the
    directory it points to (its files stay)."""
    keep = tmp_path / "precious"
    keep.mkdir()
    (keep / "data.txt").write_text("mine")
    out = tmp_path / "out"
    out.mkdir()
    (out / "bag").symlink_to(keep, target_is_directory=True)
    write_events(tmp_path / "in", short_recording(), storage="mcap")
    assert main(["replay", str(tmp_path / "in"), "--out", str(out), "--no-progress"]) == 0
    assert (keep / "data.txt").read_text() == "mine"
    assert not (out / "bag").is_symlink() and (out / "bag" / "metadata.yaml").exists()


def test_discrepancy_says_so_too(tmp_path):
    """The discrepancy workflow reads bags through the same reader: the same warning."""
    from recordings import model_friction
    events = short_recording(state_rate_hz=1000.0, segment_s=1.0, measured=model_friction)
    write_events(tmp_path / "bag", events, storage="sqlite3")
    db = _orphan_rows(tmp_path / "bag", 99)
    out = tmp_path / "out"
    assert main(["discrepancy", str(tmp_path / "bag"), "--out", str(out), "--no-progress",
                 "--no-plots", "--no-physical"]) in (0, 2)
    summary = json.loads((out / "summary.json").read_text())
    warnings = summary.get("warnings", []) + summary.get("input", {}).get("notes", [])
    assert any(str(db) in w and "99 messages" in w for w in warnings)


def _messages(path):
    """Return [(topic, log time [ns], CDR)] of a bag, the prediction's model latency zeroed."""
    from rosbags.rosbag2 import Reader
    got = []
    with Reader(path) as reader:
        for conn, log_ns, raw in reader.messages():
            raw = bytes(raw)
            if conn.topic == "/friction/prediction":
                # model_latency_s (payload bytes 80-88 after the 4-byte CDR header): wall time
                raw = raw[:84] + bytes(8) + raw[92:]
            got.append((conn.topic, log_ns, raw))
    return got


def _recording_damaged_at(src, path, kind_topic, damaged):
    """Copy bag ``src`` to ``path``, message number ``damaged`` of ``kind_topic`` cut short."""
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    store = _typestore()
    seen = 0
    with Reader(src) as reader, \
            Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {c.id: writer.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        for conn, log_ns, raw in reader.messages():
            if conn.topic == kind_topic:
                seen += 1
                if seen == damaged:
                    raw = raw[:11]
            writer.write(conns[conn.id], log_ns, bytes(raw))


@pytest.mark.parametrize("measured", [True, False])
@pytest.mark.parametrize("damaged", [None, "/axial_load", "/measured_torque", "/nut_state"])
def test_a_block_at_a_time_writes_what_message_by_message_writes(
        tmp_path, monkeypatch, measured, damaged):
    """
    The stream hands a block's answers and measured torques over at the block's end where
    the aligner defers (or without a measured torque): prediction.csv, the plotted series,
    the output bag and the RMSE are those of the stream answering message by message, byte
    for byte, of a whole run and of one stopped by a damaged message in a block.
    """
    import bb_friction_ros.replay as replay
    # the loads 0.2 ms and the measured torque 0.4 ms after the nut states: an answer's
    # measurement needs the measured sample after it, which a damaged load between them
    # keeps from a run cut short there
    after = {"axial_load": 2e-4, "measured_torque": 4e-4}
    events = [e if e.kind not in after else Event(e.kind, e.stamp_s + after[e.kind],
                                                  value=e.value)
              for e in short_recording(state_rate_hz=1000.0)
              if measured or e.kind != "measured_torque"]
    events.sort(key=lambda e: e.stamp_s)
    write_events(tmp_path / "good", events, storage="mcap")
    bag = tmp_path / "good"
    if damaged is not None:
        if damaged == "/measured_torque" and not measured:
            pytest.skip("no measured torque to damage")
        bag = tmp_path / "bag"
        # in the middle of the one block (loads at 20 Hz, the rest at 1 kHz, 0.5 s)
        _recording_damaged_at(tmp_path / "good", bag, damaged,
                              6 if damaged == "/axial_load" else 223)
    outs = {}
    for way in ("block", "message"):
        if way == "message":    # nothing deferred: every answer and measurement as it comes
            monkeypatch.setattr(replay._Sink, "defer", lambda self, *args: None)
        out = tmp_path / way
        code = main(["replay", str(bag), "--out", str(out), "--no-progress"])
        assert code == (0 if damaged is None else 2)
        summary = json.loads((out / "summary.json").read_text())
        outs[way] = ((out / "prediction.csv").read_bytes(), _messages(out / "bag"),
                     (out / "replay_torque_and_groups.png").read_bytes()
                     if damaged is None else None,
                     [summary.get(k) for k in ("samples", "rmse_nm", "measured_rows")])
    assert outs["block"][0].count(b"\n") > (100 if damaged else 400)
    assert outs["block"] == outs["message"]
