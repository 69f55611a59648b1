"""Reading recordings: damaged bags are clear errors naming the file."""

import math

import numpy as np
import pytest

from bb_friction_ros.alignment import MeasuredAligner
from bb_friction_ros.bags import BagError, Event, measured_torque_at, read_events, \
    write_events
from bb_friction_ros.cli import main


def _bag(tmp_path, storage, n=400):
    events = [Event("axial_load", 0.0, value=1500.0)] + [
        Event("nut_state", 0.001 * (k + 1), ("nut_joint",), (0.006 * k,), (6.0,))
        for k in range(n)]
    write_events(tmp_path / "bag", events, storage=storage)
    (data,) = [p for p in (tmp_path / "bag").iterdir() if p.name != "metadata.yaml"]
    return tmp_path / "bag", data


def _truncate(path):
    raw = path.read_bytes()
    path.write_bytes(raw[:len(raw) // 2])


def _corrupt(path):
    raw = bytearray(path.read_bytes())
    for k in range(len(raw) // 3, len(raw) // 3 + 64):
        raw[k] ^= 0x5A
    path.write_bytes(bytes(raw))


DAMAGE = {
    "truncated": _truncate,
    "corrupt bytes": _corrupt,
}
METADATA = {
    "truncated metadata.yaml": lambda p: p.write_text(p.read_text()[:120]),
    "garbage metadata.yaml": lambda p: p.write_bytes(b"\x00\xff{{[: not yaml ]]\x01"),
    "empty metadata.yaml": lambda p: p.write_text(""),
}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damaged_storage_file_is_exit_2_naming_it(tmp_path, capsys, storage, damage):
    bag, data = _bag(tmp_path, storage)
    DAMAGE[damage](data)
    code = main(["replay", str(bag), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    if code == 0:
        # corrupt bytes may land in a float of a message: undetectable, and harmless to read
        assert damage == "corrupt bytes"
        return
    assert code == 2, err
    assert str(bag) in err and "Traceback" not in err
    assert "damaged" in err or "not a readable rosbag2" in err


@pytest.mark.parametrize("damage", sorted(METADATA))
def test_damaged_metadata_is_exit_2_naming_it(tmp_path, capsys, damage):
    bag, _ = _bag(tmp_path, "mcap", n=10)
    METADATA[damage](bag / "metadata.yaml")
    assert main(["replay", str(bag), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(bag / "metadata.yaml") in err and "damaged metadata" in err


def test_a_directory_without_metadata_is_not_a_bag(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(BagError, match="no metadata.yaml"):
        read_events(tmp_path / "bag")


def test_measured_torque_is_aligned_run_by_run():
    """The same stamps in two passes keep their own measurements."""
    meas = [Event("measured_torque", t, value=v) for t, v in
            [(0.0, 1.0), (1.0, 2.0), (0.0, 10.0), (1.0, 20.0)]]
    got = measured_torque_at(meas, [0.0, 0.5, 1.0, 0.25, 0.5, 2.0])
    assert got[:5].tolist() == [1.0, 1.5, 2.0, 12.5, 15.0]
    assert got[5] != got[5]                      # after the pass's last measurement: NaN
    assert measured_torque_at([], [0.0]) is None


def _joint_state_cdr(store, names, positions, velocities, effort, frame_id="", sec=7,
                     nanosec=123_456_789, little_endian=True):
    import numpy as np
    t = store.types
    msg = t["sensor_msgs/msg/JointState"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=nanosec), frame_id=frame_id),
        name=list(names), position=np.array(positions, float),
        velocity=np.array(velocities, float), effort=np.array(effort, float))
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState",
                                     little_endian=little_endian))


def test_fast_input_decoding_equals_rosbags_and_leaves_anything_odd_to_it():
    """
    The struct decoders of the input topics give rosbags' values exactly, and return None
    (rosbags then decodes or names the damage) for what they do not fully accept.
    """
    import numpy as np
    from bb_friction_ros.bags import (_typestore, fast_joint_state, fast_wrench_force_z,
                                      fast_wrench_torque_z)
    store = _typestore()
    rng = np.random.default_rng(5)
    cases = [((), (), (), ()), (("nut_joint",), (0.1,), (6.0,), ()),
             (("a", "nüt", "joint_3"), rng.normal(size=3), rng.normal(size=3), (1.0, 2, 3)),
             (("nut_joint",), (1.5,), (), ()), (("x" * 5, "y"), (1.0,), (2.0, 3.0), (4.0,))]
    for frame_id in ("", "base", "odd_len"):
        for names, pos, vel, eff in cases:
            raw = _joint_state_cdr(store, names, pos, vel, eff, frame_id)
            msg = store.deserialize_cdr(raw, "sensor_msgs/msg/JointState")
            assert fast_joint_state(raw) == (7, 123_456_789, tuple(msg.name),
                                             tuple(float(x) for x in msg.position),
                                             tuple(float(x) for x in msg.velocity))
            assert fast_joint_state(memoryview(raw)) == fast_joint_state(raw)
            # damaged or unusual: the fast path declines
            assert fast_joint_state(raw[:-9]) is None
            assert fast_joint_state(raw + b"\0" * 8) is None
            assert fast_joint_state(_joint_state_cdr(store, names, pos, vel, eff, frame_id,
                                                     little_endian=False)) is None
    raw = bytearray(_joint_state_cdr(store, ("nut_joint",), (0.1,), (6.0,), ()))
    raw[4 + 8 + 8 + 4 + 4 + 9] = ord("X")           # the joint name's terminator
    assert fast_joint_state(bytes(raw)) is None
    with pytest.raises(Exception):
        store.deserialize_cdr(bytes(raw), "sensor_msgs/msg/JointState")
    t = store.types
    for frame_id in ("", "load_cell"):
        vec = t["geometry_msgs/msg/Vector3"]
        msg = t["geometry_msgs/msg/WrenchStamped"](
            header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
                sec=-3, nanosec=999_999_999), frame_id=frame_id),
            wrench=t["geometry_msgs/msg/Wrench"](force=vec(x=1.0, y=2.0, z=-1500.25),
                                                 torque=vec(x=4.0, y=5.0, z=0.125)))
        raw = bytes(store.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))
        assert fast_wrench_force_z(raw) == (-3, 999_999_999, -1500.25)
        assert fast_wrench_torque_z(raw) == (-3, 999_999_999, 0.125)
        assert fast_wrench_force_z(raw[:-1]) is None
        assert fast_wrench_force_z(raw + bytes(4)) is None


# --- a late stamp is not a restart; nothing is held without bound ---------------------------

def _stream(n, rate_hz=1000.0):
    return [k / rate_hz for k in range(n)]


def test_one_late_prediction_stamp_keeps_the_measurement():
    """One nut_state stamp 10.5 ms late in 6 s at 1 kHz: every row keeps its measurement."""
    t = _stream(6000)
    meas = [Event("measured_torque", s, value=math.sin(s)) for s in t]
    stamps = list(t)
    stamps[1500] -= 0.0105                        # late: jitter, not a restart
    got = measured_torque_at(meas, stamps)
    assert np.isfinite(got).all()
    assert np.allclose(got, np.sin(stamps), atol=1e-6)   # aligned by its own stamp


def test_late_samples_in_either_stream_are_aligned_in_their_run():
    from bb_friction_ros.bags import MeasuredAligner
    al = MeasuredAligner()
    out = []
    t = _stream(3000)
    for k, s in enumerate(t):
        ms = s - 0.004 if k == 700 else s          # one late measured stamp too
        out += al.add_measured(ms, 2.0 * ms)
        ps = s - 0.0105 if k == 1500 else s
        out += al.add_prediction(ps, ps)
    out += al.finish()
    assert len(out) == 3000 and all(v == pytest.approx(2.0 * p) for p, v in out[1:])
    assert al.runs == {"prediction": 1, "measured": 1}
    assert al.late == {"prediction": 1, "measured": 1} and al.warnings() == []


def test_a_restart_is_still_a_new_run_even_a_short_step_back():
    """A loop of 0.1 s goes back by only 0.09 s but carries on below: a restart."""
    meas = [Event("measured_torque", 0.01 * (k % 10 + 1), value=float(k // 10))
            for k in range(20)]
    got = measured_torque_at(meas, [0.01 * (k % 10 + 1) for k in range(20)])
    assert got.tolist() == [0.0] * 10 + [1.0] * 10


def test_unmatched_predictions_are_not_held_without_bound():
    """Predictions restart, the measurement never does: released as NaN, counted, warned."""
    from bb_friction_ros.bags import MeasuredAligner
    al = MeasuredAligner(max_held=500)           # above the 0.1 s (100-sample) history kept
    done, longest = [], 0
    for k in range(2000):
        s = k / 1000.0
        done += al.add_measured(s, 1.0)
        done += al.add_prediction(s if k < 1000 else s - 1.0, k)   # restarts at k = 1000
        longest = max(longest, len(al._preds))
    done += al.finish()
    assert longest <= 501 and len(done) == 2000
    assert [k for k, _ in done] == list(range(2000))               # in prediction order
    assert all(v == 1.0 for _, v in done[:1000])
    assert all(math.isnan(v) for _, v in done[1000:])
    assert al.unmatched_predictions == 500 and al.unmatched_measured == 0   # 500 at finish
    text = " ".join(al.warnings())
    assert "prediction stream has 2 run(s) and the measured torque 1" in text
    assert "500 prediction(s) and 0 measured sample(s)" in text


def test_unmatched_measured_samples_are_not_held_without_bound():
    from bb_friction_ros.bags import MeasuredAligner
    al = MeasuredAligner(max_held=100)
    for k in range(5000):                         # a measurement with no prediction at all
        al.add_measured(k / 1000.0, 1.0)
        assert sum(len(m) for m in al._meas) <= 100
    assert al.unmatched_measured == 4900


def test_one_far_future_stamp_is_not_a_restart():
    """One stamp at 2e9 s, then the stream carries on: same run, counted."""
    from bb_friction_ros.bags import MeasuredAligner
    al = MeasuredAligner()
    out = []
    for k in range(3000):
        s = k / 1000.0
        out += al.add_measured(s, 3.0 * s)
        out += al.add_prediction(2.0e9 if k == 1000 else s, k)
    out += al.finish()
    assert [k for k, _ in out] == list(range(3000))
    assert all(v == pytest.approx(3.0 * k / 1000.0) for k, v in out if k != 1000)
    assert math.isnan(dict(out)[1000])
    assert al.runs == {"prediction": 1, "measured": 1}
    assert al.ahead == {"prediction": 1, "measured": 0}


def test_one_far_future_measured_stamp_brackets_nothing():
    from bb_friction_ros.bags import MeasuredAligner
    al = MeasuredAligner()
    out = []
    for k in range(3000):
        s = k / 1000.0
        out += al.add_measured(2.0e9 if k == 1000 else s, 3.0 * s)
        out += al.add_prediction(s + 0.0005, k)           # between two measured samples
    out += al.finish()
    values = dict(out)
    # the prediction at 0.9995 and 1.0005 bracket the missing sample: interpolated across it
    assert values[999] == pytest.approx(3.0 * 0.9995) and values[1000] == pytest.approx(3.0015)
    assert all(v == pytest.approx(3.0 * (k / 1000.0 + 0.0005)) for k, v in out if k < 2999)
    assert al.ahead == {"prediction": 0, "measured": 1} and al.warnings() == []


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_batched_writes_are_the_bag_rosbags_writes_message_by_message(tmp_path, storage):
    """
    BagWriter writes mcap in batches into rosbags' own chunk bookkeeping (15 us a
    message saved): the files must be byte for byte those of rosbags' writer called once per
    message, across chunk boundaries (1 MiB) and batch boundaries, with interleaved topics
    and log times going back.  sqlite3 is written by rosbags itself, message by message.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from bb_friction_ros import bag_writer as bags
    rng = np.random.default_rng(7)
    topics = [("/a", "std_msgs/msg/String"), ("/b", "geometry_msgs/msg/WrenchStamped"),
              ("/c", "sensor_msgs/msg/JointState")]
    # sizes from a few bytes to 200 kB: several chunks, some closed by a single message
    messages = [(int(rng.integers(0, 3)), int(1e9 + rng.integers(-10**6, 10**9)),
                 rng.bytes(int(rng.choice([8, 100, 1000, 200_000],
                                          p=[0.4, 0.3, 0.298, 0.002]))))
                for _ in range(3 * bags.WRITE_BATCH + 17)]
    store = bags._typestore()
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    # the same bag name in both: the mcap file embeds metadata naming its file
    ref = Writer(tmp_path / "ref" / "bag", version=9, storage_plugin=plugin)
    ref.open()
    conns = [ref.add_connection(t, m, typestore=store) for t, m in topics]
    for k, ts, raw in messages:
        ref.write(conns[k], ts, raw)
    ref.close()
    with bags.BagWriter(tmp_path / "batched" / "bag", store, storage=storage) as out:
        assert out._batched == (storage == "mcap")
        conns = [out.connection(t, m) for t, m in topics]
        for k, ts, raw in messages:
            out.write_raw(conns[k], ts, raw)
    names = ["metadata.yaml"] + (["bag.mcap"] if storage == "mcap" else [])
    for name in names:
        assert (tmp_path / "batched" / "bag" / name).read_bytes() == \
            (tmp_path / "ref" / "bag" / name).read_bytes(), name
    if storage == "mcap":
        assert sum(len(raw) for _, _, raw in messages) > 4 * bags._MCAP_CHUNK_BYTES
    from rosbags.rosbag2 import Reader
    with Reader(tmp_path / "batched" / "bag") as reader:
        got = sorted((ts, conn.topic, bytes(raw)) for conn, ts, raw in reader.messages())
    assert got == sorted((ts, topics[k][0], raw) for k, ts, raw in messages)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_blocks_decode_what_messages_decodes(tmp_path, storage):
    """
    BagInput.blocks (replay) decodes messages sharing a layout with numpy: every
    value equals messages()' Event, and anything else (another frame_id or joint list, a
    missing velocity, NaN, big-endian, another joint) is left to Block.event, which gives
    messages()' Event; counts and joint names agree; block boundaries change nothing.
    """
    import math as m
    from rosbags.rosbag2 import StoragePlugin, Writer
    from bb_friction_ros.bags import _typestore, BagInput, Topics
    store = _typestore()
    t = store.types
    rng = np.random.default_rng(11)

    def wrench(sec, nanosec, frame_id, fz, tz, fx):
        vec = t["geometry_msgs/msg/Vector3"]
        msg = t["geometry_msgs/msg/WrenchStamped"](
            header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](
                sec=sec, nanosec=nanosec), frame_id=frame_id),
            wrench=t["geometry_msgs/msg/Wrench"](force=vec(x=fx, y=0.0, z=fz),
                                                 torque=vec(x=0.0, y=fx, z=tz)))
        return bytes(store.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))

    joints = [(("nut_joint",), 1, 1, 0, ""), (("nut_joint",), 1, 1, 0, "base"),
              (("nut_joint",), 1, 1, 0, "odd!"), (("a", "nut_joint"), 2, 2, 2, ""),
              (("nut_joint",), 1, 0, 0, ""), (("other",), 1, 1, 0, "")]
    messages, regular = [], 0
    for k in range(700):
        sec, nanosec = int(rng.integers(-5, 2**31 - 1)), int(rng.integers(0, 10**9))
        r = rng.random()
        if r < 0.6:
            names, n_pos, n_vel, n_eff, frame = joints[0] if r < 0.4 else \
                joints[int(rng.integers(1, len(joints)))]
            pos, vel = rng.normal(size=n_pos), rng.normal(size=n_vel)
            if rng.random() < 0.05:
                pos[-1] = math.nan
            regular += r < 0.4 and m.isfinite(pos[-1])
            raw = _joint_state_cdr(store, names, pos, vel, rng.normal(size=n_eff), frame,
                                   sec=sec, nanosec=nanosec,
                                   little_endian=rng.random() > 0.03)
            messages.append(("/nut_state", "sensor_msgs/msg/JointState", raw))
        elif r < 0.8:
            raw = wrench(sec, nanosec, "load" if rng.random() < 0.9 else "", rng.normal(),
                         rng.normal(), rng.normal())
            messages.append(("/axial_load", "geometry_msgs/msg/WrenchStamped", raw))
        elif r < 0.95:
            raw = wrench(sec, nanosec, "", rng.normal(), rng.normal(), rng.normal())
            messages.append(("/measured_torque", "geometry_msgs/msg/WrenchStamped", raw))
        else:
            msg = t["std_msgs/msg/String"](data="x" * int(rng.integers(0, 9)))
            messages.append(("/other", "std_msgs/msg/String",
                             bytes(store.serialize_cdr(msg, "std_msgs/msg/String"))))
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    with Writer(tmp_path / "bag", version=9, storage_plugin=plugin) as writer:
        conns = {}
        for k, (topic, msgtype, raw) in enumerate(messages):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], 1000 + k, raw)

    def key(ev):        # NaN-safe, exact
        return repr((ev.kind, ev.stamp_s, ev.stamp_ns, ev.names, ev.positions, ev.velocities,
                     ev.value))

    with BagInput(tmp_path / "bag", Topics()) as src:
        want = list(src.messages())
        want_counts, want_names = dict(src.counts), dict(src.joint_names)
    for size in (7, None):
        with BagInput(tmp_path / "bag", Topics()) as src:
            got, fast = [], 0
            for block in src.blocks("nut_joint", size=size):
                stamp_s, stamp_ns = block.stamp_s.tolist(), block.stamp_ns.tolist()
                for i, item in enumerate(block.items):
                    ev = want[len(got)][3]
                    got.append(item)
                    if block.kinds[i] is None:
                        assert ev is None
                    elif block.fast[i]:
                        fast += 1
                        assert (stamp_s[i], stamp_ns[i]) == (ev.stamp_s, ev.stamp_ns)
                        if ev.kind == "nut_state":
                            j = ev.names.index("nut_joint")
                            assert (block.value[i], block.velocity[i]) == \
                                (ev.positions[j], ev.velocities[j])
                        else:
                            assert block.value[i] == ev.value
                    else:
                        assert key(block.event(i)) == key(ev)
            assert [(c.topic, ts, bytes(raw)) for c, ts, raw in got] == \
                [(c.topic, ts, bytes(raw)) for c, ts, raw, _ in want]
            assert dict(src.counts) == want_counts and dict(src.joint_names) == want_names
            # every regular nut_state, and most loads and torques, read with numpy
            assert fast >= regular + 0.3 * len(messages), (fast, regular)


def test_a_damaged_message_is_named_alike_by_blocks_and_messages(tmp_path):
    """Block.event names a message it cannot decode as messages() does: its number on the
    topic and its log time (a block starts mid-topic and holds other topics first)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from bb_friction_ros.bags import _typestore, BagInput
    store = _typestore()
    good = _joint_state_cdr(store, ("nut_joint",), (0.1,), (6.0,), ())
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        nut = writer.add_connection("/nut_state", "sensor_msgs/msg/JointState",
                                    typestore=store)
        load = writer.add_connection("/axial_load", "geometry_msgs/msg/WrenchStamped",
                                     typestore=store)
        for k in range(40):
            writer.write(load, 2 * k, bytes(4))                  # undecodable as well
            writer.write(nut, 2 * k + 1, good if k != 23 else good[:11])
    errors = []
    for read in (lambda src: [ev for *_, ev in src.messages()],
                 lambda src: [b.event(i) for b in src.blocks("nut_joint", size=7)
                              for i in range(len(b.items))
                              if b.kinds[i] == "nut_state" and not b.fast[i]]):
        with BagInput(tmp_path / "bag") as src:
            src.resolved.pop("/axial_load")                 # only the nut_state damage
            with pytest.raises(BagError) as err:
                read(src)
            errors.append(str(err.value))
    assert errors[0] == errors[1] and "damaged message 24 on /nut_state" in errors[0] \
        and "log time 47 ns" in errors[0], errors


@pytest.mark.parametrize("log_ns", [-5, 2 ** 64])
def test_a_log_time_outside_a_bags_range_is_refused_naming_it(tmp_path, log_ns):
    """
    mcap logs in unsigned 64-bit ns since 1970: a log time before 1970 (or past 2^64 ns) is
    a BagError naming the bag, the topic and the time, not an OverflowError from the batched
    writer.
    """
    from bb_friction_ros.bags import BagWriter
    raw = b"\x00\x01\x00\x00\x01\x00\x00\x00\x00"       # std_msgs/String ""
    with pytest.raises(BagError) as err:
        with BagWriter(tmp_path / "bag", storage="mcap") as out:
            conn = out.connection("/x", "std_msgs/msg/String")
            out.write_raw(conn, 5, raw)
            out.write_raw(conn, log_ns, raw)
    assert str(err.value).startswith(f"{tmp_path / 'bag'}: cannot log a message on /x at "
                                     f"{log_ns} ns")


def _aligned(messages, batch=None):
    """Release (payload, value) of interleaved messages, per message or per ``batch``."""
    aligner = MeasuredAligner()
    aligner.deferred_batches = 0
    out = []
    for start in range(0, len(messages), batch or len(messages)):
        part = messages[start:start + batch] if batch else messages
        deferred = batch is not None and aligner.defer(
            [t for kind, t, _ in part if kind == "m"], [t for kind, t, _ in part if kind == "p"])
        for kind, t, v in part:
            out += aligner.add_measured(t, v) if kind == "m" else aligner.add_prediction(t, v)
        if deferred:
            out += aligner.release()
            aligner.deferred_batches += 1
    return out + aligner.finish(), aligner


@pytest.mark.parametrize("batch", [1, 3, 7, 64])
def test_releasing_once_per_batch_gives_what_each_message_gives(batch):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.0005, 0.0015, 600))
    t[100] = t[99]                      # a repeated measured stamp
    t[200] -= 0.004                     # a late measured sample
    t[300:] -= 2.0                      # a restart (a looping recording)
    t[450] += 5.0                       # one stamp far ahead
    p = t + rng.uniform(-0.0004, 0.0004, t.size)
    p[250] -= 0.003                     # a late prediction
    messages = []
    for k in range(t.size):             # the measurement sometimes first, sometimes after
        pair = [("m", float(t[k]), float(np.sin(t[k]))), ("p", float(p[k]), k)]
        messages += pair if rng.random() < 0.5 else pair[::-1]
    each, a1 = _aligned(messages)
    batched, a2 = _aligned(messages, batch)
    assert a2.deferred_batches > 0.25 * len(messages) / batch     # the anomalies aside
    assert [k for k, _ in batched] == [k for k, _ in each] == list(range(t.size))
    np.testing.assert_array_equal([v for _, v in batched], [v for _, v in each])
    assert (a1.runs, a1.late, a1.ahead) == (a2.runs, a2.late, a2.ahead)


def _mcap_bag(path, rng, n, back_s, compression=None):
    """A rosbags-written mcap of ``n`` random messages on three topics, several chunks."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from bb_friction_ros.bags import _typestore
    store = _typestore()
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compression is not None:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    written = []
    with writer:
        conns = [writer.add_connection(t, m, typestore=store) for t, m in (
            ("/nut_state", "sensor_msgs/msg/JointState"),
            ("/axial_load", "geometry_msgs/msg/WrenchStamped"),
            ("/other", "std_msgs/msg/String"))]
        t = 100 * 10**9
        for _ in range(n):
            # log times mostly forward, a few back by up to ``back_s``, ties too
            t += int(rng.choice([0, 1000, 10**6])) - (int(rng.integers(0, back_s * 1e9) + 1)
                                                      if back_s and rng.random() < 0.02 else 0)
            writer.write(conns[int(rng.integers(0, 3))], t,
                         rng.bytes(int(rng.choice([20, 300, 5000, 100_000],
                                                  p=[0.5, 0.3, 0.19, 0.01]))))
            written.append(t)
    return written


@pytest.mark.parametrize("compression", [None, "zstd"])
def test_the_own_mcap_reader_reads_exactly_what_rosbags_reads(tmp_path, compression):
    """
    mcap_messages (replay's reader of single-mcap bags) yields rosbags' messages: the same
    connections, log times and bytes in the same order, across chunks, with log times
    going back inside a chunk and ties, for all topics or some, from the bag directory or
    its .mcap file; chunks whose time ranges overlap are left to rosbags (None).
    """
    from rosbags.rosbag2 import Reader
    from bb_friction_ros.bags import mcap_messages
    rng = np.random.default_rng(5)
    written = _mcap_bag(tmp_path / "bag", rng, 3000, 1e-4, compression)
    assert written != sorted(written) and len(set(written)) < len(written)
    (file,) = (tmp_path / "bag").glob("*.mcap")
    for path in (tmp_path / "bag", file):
        with Reader(path) as reader:
            assert len(reader.storage.storages[0].chunks if path.is_dir()
                       else reader.storage.chunks) >= 3
            for conns in (reader.connections, reader.connections[:1],
                          reader.connections[1:]):
                want = list(reader.messages(connections=conns))
                got = mcap_messages(reader, conns)
                assert got is not None
                got = list(got)
                assert len(got) == len(want) > 0
                assert all(g[0] is w[0] and g[1:] == (w[1], bytes(w[2]))
                           for g, w in zip(got, want))
    # log times back by up to a second: chunks overlap, rosbags merges them
    _mcap_bag(tmp_path / "back", np.random.default_rng(6), 3000, 1.0, compression)
    with Reader(tmp_path / "back") as reader:
        assert mcap_messages(reader, reader.connections) is None


def test_the_own_mcap_reader_reports_a_damaged_chunk_as_rosbags_does(tmp_path):
    """A chunk the own reader cannot parse is read by rosbags: its error, same position."""
    from bb_friction_ros.bags import BagInput, mcap_messages
    _mcap_bag(tmp_path / "bag", np.random.default_rng(8), 3000, 0.0)
    (file,) = (tmp_path / "bag").glob("*.mcap")
    with BagInput(tmp_path / "bag") as src:
        assert mcap_messages(src._reader, src.connections) is not None
        chunk = sorted(src._reader.storage.storages[0].chunks,
                       key=lambda c: c.chunk_start_offset)[1]
    raw = bytearray(file.read_bytes())
    # the second chunk's records: a message record's length made to overrun the chunk
    start = chunk.chunk_start_offset + 9 + 40 + len(chunk.compression)
    raw[start + 1:start + 9] = (10**9).to_bytes(8, "little")
    file.write_bytes(bytes(raw))
    errors = []
    for own in (False, True):
        with BagInput(tmp_path / "bag") as src:
            if not own:
                import bb_friction_ros.bags as bags
                real, bags.mcap_messages = bags.mcap_messages, lambda *a: None
            try:
                with pytest.raises(BagError) as err:
                    sum(len(b.items) for b in src.blocks("nut_joint"))
            finally:
                if not own:
                    bags.mcap_messages = real
            errors.append(str(err.value))
    assert errors[0] == errors[1] and "damaged bag: reading failed after" in errors[0], errors
