"""
What a recording holds: its topics, its input events, and the messages' types.

The lowest of the bag modules (``bags`` reads, ``bag_writer`` writes, ``alignment`` pairs
predictions with the measured torque).  rosbags is imported on first use: it costs about
0.5 s, and every ``bb-friction`` command builds its parser with ``Topics``.
"""

from dataclasses import dataclass, field
import importlib.util
from pathlib import Path

import numpy as np

from bb_friction_ros import interface
from bb_friction_ros.config import BBFrictionError
from bb_friction_ros.interface import MSGS_PACKAGE, WRENCH_STAMPED

# The message type each input kind must have (a kind is named after its default topic), and
# the CLI flag that names its topic.
KIND_TYPES = {kind: interface.TYPES[kind] for kind in
              (interface.NUT_STATE, interface.AXIAL_LOAD, interface.MEASURED_TORQUE)}
KIND_FLAGS = {"nut_state": "--nut-state-topic", "axial_load": "--axial-load-topic",
              "measured_torque": "--measured-topic"}
# Joint names listed in an error about nut_state: enough to spot a misnamed joint.
MAX_JOINT_NAMES_KEPT = 20


class BagError(BBFrictionError):
    """A recording that cannot be used as asked; the message names the file and the fix."""


@dataclass(frozen=True)
class Topics:
    """
    Topic names of a recording.

    A name without a leading '/' is relative, resolved in the root namespace as the node's
    own topics are (``nut_state`` is ``/nut_state``).  A topic recorded under a namespace
    (``/robot/nut_state``) is used only when named so: it is never guessed.
    """

    nut_state: str = interface.NUT_STATE
    axial_load: str = interface.AXIAL_LOAD
    measured_torque: str = interface.MEASURED_TORQUE

    def absolute(self, kind):
        """Return the absolute topic name of ``kind`` ('nut_state', ...)."""
        return interface.absolute(getattr(self, kind))


@dataclass(frozen=True)
class Event:
    """One message: kind is 'nut_state', 'axial_load' or 'measured_torque'."""

    kind: str
    stamp_s: float
    names: tuple = ()
    positions: tuple = ()
    velocities: tuple = ()
    value: float = float("nan")        # force.z [N] or torque.z [N m]
    # the header stamp as integer ns when read from a bag: float seconds lose ~0.2 us at
    # epoch times, and outputs must carry the input stamp unchanged
    stamp_ns: int = field(default=None, compare=False)


def with_measurement(events, measured_nm):
    """Return ``events`` with a measured_torque event after each nut_state (in order)."""
    out, k = [], 0
    for e in events:
        out.append(e)
        if e.kind == "nut_state":
            out.append(Event("measured_torque", e.stamp_s, value=float(measured_nm[k])))
            k += 1
    return out


def _typestore():
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


def _msg_dirs():
    """Directories that may hold bb_friction_msgs' .msg files, installed one first."""
    dirs = []
    spec = importlib.util.find_spec(MSGS_PACKAGE)
    if spec is not None and spec.origin:
        # <prefix>/lib/python3.X/site-packages/bb_friction_msgs/__init__.py
        prefix = Path(spec.origin).resolve().parents[4]
        dirs.append(prefix / "share" / MSGS_PACKAGE / "msg")
    dirs.append(Path(__file__).resolve().parents[1] / "msg_defs" / MSGS_PACKAGE / "msg")
    return dirs


def friction_typestore():
    """
    Return a Jazzy typestore with bb_friction_msgs registered from its ``.msg`` files.

    Found where rosidl installed them (``<prefix>/share/bb_friction_msgs/msg``), else in the
    source checkout; rosbags computes the same RIHS01 hashes as rosidl.
    """
    from rosbags.typesys import get_types_from_msg
    store = _typestore()
    for d in _msg_dirs():
        files = sorted(d.glob("*.msg"))
        if files:
            types = {}
            for f in files:
                types.update(get_types_from_msg(f.read_text(), f"{MSGS_PACKAGE}/msg/{f.stem}"))
            store.register(types)
            return store
    raise BagError(f"cannot find the {MSGS_PACKAGE} .msg files (looked in "
                   f"{', '.join(str(d) for d in _msg_dirs())})")


def _stamp(header):
    return header.stamp.sec + 1e-9 * header.stamp.nanosec


def _stamp_ns(header):
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def stamp_ns(event):
    """Return the event's header stamp in integer ns (exact when read from a bag)."""
    if event.stamp_ns is not None:
        return event.stamp_ns
    return int(round(event.stamp_s * 1e9))


def _why(exc):
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


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
