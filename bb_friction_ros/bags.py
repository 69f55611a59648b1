"""
rosbag2 recordings (sqlite3 and mcap) read and written with ``rosbags``, without ROS.

Messages are yielded in log order, the order ``ros2 bag play`` publishes them, so a replay
sees what the live node would: including header stamps that jump backwards.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"


@dataclass(frozen=True)
class Topics:
    """Topic names of a recording (leading '/' optional)."""

    nut_state: str = "nut_state"
    axial_load: str = "axial_load"
    measured_torque: str = "measured_torque"


@dataclass(frozen=True)
class Event:
    """One message: kind is 'nut_state', 'axial_load' or 'measured_torque'."""

    kind: str
    stamp_s: float
    names: tuple = ()
    positions: tuple = ()
    velocities: tuple = ()
    value: float = float("nan")        # force.z [N] or torque.z [N m]


def with_measurement(events, measured_nm):
    """Return ``events`` with a measured_torque event after each nut_state (in order)."""
    out, k = [], 0
    for e in events:
        out.append(e)
        if e.kind == "nut_state":
            out.append(Event("measured_torque", e.stamp_s, value=float(measured_nm[k])))
            k += 1
    return out


def measured_torque_at(events, stamps_s):
    """
    Return the measured torque interpolated to ``stamps_s`` [N m], or None if none recorded.

    Linear interpolation over the finite recorded samples; NaN outside their span.  Replay
    and the discrepancy workflow both align the measurement with this, so they agree.
    """
    measured = [(e.stamp_s, e.value) for e in events
                if e.kind == "measured_torque" and np.isfinite(e.value)]
    if not measured:
        return None
    mt, mv = np.array(measured).T
    order = np.argsort(mt, kind="stable")
    return np.interp(np.asarray(stamps_s, dtype=float), mt[order], mv[order], left=np.nan,
                     right=np.nan)


def _typestore():
    return get_typestore(Stores.ROS2_JAZZY)


def _bare(topic):
    return topic.lstrip("/")


def _stamp(header):
    return header.stamp.sec + 1e-9 * header.stamp.nanosec


def iter_events(path, topics=Topics()):
    """
    Return (an iterator of the events in log order, messages per topic) of a rosbag2 directory.

    The bag is read as the iterator is consumed, so a long recording is never in memory as
    events (a 10-minute 1 kHz bag is 1.8 million of them); it is closed when the iterator is
    exhausted.  Topics not in ``topics`` are counted (from the metadata) but not decoded.
    Raises FileNotFoundError or ValueError with the path when the bag cannot be opened.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such bag")
    store = _typestore()
    wanted = {_bare(topics.nut_state): "nut_state", _bare(topics.axial_load): "axial_load",
              _bare(topics.measured_torque): "measured_torque"}
    counts = {}
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:     # rosbags raises its own error types per storage
        raise ValueError(f"{path}: not a readable rosbag2 ({exc})") from exc
    for conn in reader.connections:
        counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
    conns = [c for c in reader.connections if _bare(c.topic) in wanted]

    def events():
        try:
            for conn, _, raw in reader.messages(connections=conns):
                kind = wanted[_bare(conn.topic)]
                msg = store.deserialize_cdr(raw, conn.msgtype)
                if kind == "nut_state":
                    yield Event(kind, _stamp(msg.header), tuple(msg.name),
                                tuple(float(x) for x in msg.position),
                                tuple(float(x) for x in msg.velocity))
                elif kind == "axial_load":
                    yield Event(kind, _stamp(msg.header), value=float(msg.wrench.force.z))
                else:
                    yield Event(kind, _stamp(msg.header), value=float(msg.wrench.torque.z))
        finally:
            reader.close()
    return events(), counts


def read_events(path, topics=Topics()):
    """
    Return (events in log order, messages per topic) of a rosbag2 directory.

    Topics not in ``topics`` are counted but not decoded.  Raises FileNotFoundError or
    ValueError with the path when the bag cannot be read.
    """
    events, counts = iter_events(path, topics)
    return list(events), counts


def _header(store, stamp_s):
    sec = int(np.floor(stamp_s))
    nanosec = int(round((stamp_s - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    t = store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return store.types["std_msgs/msg/Header"](stamp=t, frame_id="")


def _wrench(store, stamp_s, force_z=0.0, torque_z=0.0):
    vec = store.types["geometry_msgs/msg/Vector3"]
    w = store.types["geometry_msgs/msg/Wrench"](force=vec(x=0.0, y=0.0, z=float(force_z)),
                                                torque=vec(x=0.0, y=0.0, z=float(torque_z)))
    return store.types[WRENCH_STAMPED](header=_header(store, stamp_s), wrench=w)


def write_events(path, events, topics=Topics(), storage="sqlite3", log_times_s=None):
    """
    Write events as a rosbag2 (storage 'sqlite3' or 'mcap'); log time = stamp unless given.

    Serialised with rosbags' own CDR (rclpy's serializer may append junk bytes).
    """
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}.get(storage)
    if plugin is None:
        raise ValueError(f"storage: must be 'sqlite3' or 'mcap', got {storage!r}")
    store = _typestore()
    with Writer(Path(path), version=9, storage_plugin=plugin) as writer:
        conns = {
            "nut_state": writer.add_connection("/" + _bare(topics.nut_state), JOINT_STATE,
                                               typestore=store),
            "axial_load": writer.add_connection("/" + _bare(topics.axial_load),
                                                WRENCH_STAMPED, typestore=store),
            "measured_torque": writer.add_connection("/" + _bare(topics.measured_torque),
                                                     WRENCH_STAMPED, typestore=store),
        }
        for i, ev in enumerate(events):
            if ev.kind == "nut_state":
                msg = store.types[JOINT_STATE](
                    header=_header(store, ev.stamp_s), name=list(ev.names),
                    position=np.asarray(ev.positions, float),
                    velocity=np.asarray(ev.velocities, float), effort=np.zeros(0))
                msgtype = JOINT_STATE
            elif ev.kind == "axial_load":
                msg, msgtype = _wrench(store, ev.stamp_s, force_z=ev.value), WRENCH_STAMPED
            else:
                msg, msgtype = _wrench(store, ev.stamp_s, torque_z=ev.value), WRENCH_STAMPED
            log_t = ev.stamp_s if log_times_s is None else log_times_s[i]
            writer.write(conns[ev.kind], int(round(log_t * 1e9)),
                         store.serialize_cdr(msg, msgtype))
