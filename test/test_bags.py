"""Reading recordings: damaged bags are clear errors naming the file (issue 13 finding 17)."""

import pytest

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
    """Issue 13 finding 6: the same stamps in two passes keep their own measurements."""
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
