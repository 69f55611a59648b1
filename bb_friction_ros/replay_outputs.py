"""
What replay writes beside prediction.csv: friction_node's output topics in ``bag/``.

The node's messages are packed as CDR directly (``prediction_cdr``, ``feedforward_cdr``,
``groups_cdr``; test_replay checks every byte against rosbags' own serialisation) and
queued with the copied inputs in output order (``_OutputBag``).
"""

import functools
import shutil
import struct

from bb_friction_ros import interface
from bb_friction_ros.bag_types import friction_typestore
from bb_friction_ros.bag_writer import BagWriter
from bb_friction_ros.runner import prediction_values

# Output topics and types, as friction_node publishes them (node.py).
PREDICTION_TOPIC, GROUPS_TOPIC, FEEDFORWARD_TOPIC = OUTPUT_TOPICS = tuple(
    (interface.absolute(t), interface.TYPES[t]) for t in interface.REPLAYED_OUTPUTS)


# CDR (little endian) of the two messages written per prediction, packed directly.
# rosbags builds a message object and walks its type per message: ~70 us of the ~110 us per
# sample that the output bag cost (profiled).  The layouts are fixed (an empty
# frame_id, no sequences but one 1-element array); test/test_replay.py checks every
# byte against rosbags' own serialisation.  Offsets count from the payload after the 4-byte
# encapsulation header; doubles align to 8.
_CDR_LE = b"\x00\x01\x00\x00"
# FrictionPrediction: header (sec, nanosec, frame_id "" = length 1 + NUL, pad to 16), seven
# float64, converged (bool, pad to 80), model_latency_s, model_age_s, n_groups (pad to 104),
# torque_state_nm, state_other_direction, arrangement (pad to 120), arrangement_confidence.
_PREDICTION_CDR = struct.Struct("<4siII1s3x7d?7x2dI4xd?B6xd")
# Float64MultiArray: layout (no dims, data_offset 0), data of length 1 (pad to 16), the value.
_FEEDFORWARD_CDR = struct.Struct("<4sIII4xd")


def prediction_cdr(pred, sec, nanosec, latency_s):
    """Return the CDR of friction_node's FrictionPrediction for ``pred`` (see node.py)."""
    return prediction_values_cdr(prediction_values(pred), sec, nanosec, latency_s)


def prediction_values_cdr(v, sec, nanosec, latency_s):
    """
    Return ``prediction_cdr`` of the Prediction whose fields are the tuple ``v``.

    ``runner.ModelRunner.process_values``' answer, in ``Prediction``'s field order; the
    message fields in ``interface.prediction_values``' order (replay's own answers never
    become a Prediction).
    """
    return _PREDICTION_CDR.pack(_CDR_LE, sec, nanosec, 1, b"\x00", v[1], v[2], v[3], v[4],
                                v[5], v[6], v[7], bool(v[8]), latency_s, v[9], len(v[10]),
                                v[15], bool(v[16]), int(v[17]), v[18])


def feedforward_cdr(value_nm):
    """Return the CDR of the node's feedforward Float64MultiArray: ``[value_nm]``."""
    return _FEEDFORWARD_CDR.pack(_CDR_LE, 0, 0, 1, value_nm)


# ContactGroupStatus: header (as above, pad to 16), nut_angle_rad, n_balls, the number of
# groups; each ContactGroup is a uint32 sequence and a float64 sequence (its doubles aligned
# to 8 when there are any).  rosbags' serialize_cdr took ~40 us per status, written at most
# once per model step (1200 per 6-second bag at 1 rev/s); test_replay checks every byte.
_GROUPS_HEAD_CDR = struct.Struct("<4siII1s3xdII")


def groups_cdr(groups, sec, nanosec, nut_angle_rad, n_balls):
    """Return the CDR of friction_node's ContactGroupStatus for ``groups`` (see node.py)."""
    args = [_CDR_LE, sec, nanosec, 1, b"\x00", nut_angle_rad, n_balls, len(groups)]
    sizes = []
    for ids, forces in groups:
        sizes.append((len(ids), len(forces)))
        args.append(len(ids))
        args += ids
        args.append(len(forces))
        args += forces
    return _status_struct(tuple(sizes)).pack(*args)


@functools.lru_cache(maxsize=1024)
def _status_struct(sizes):
    """
    Return the Struct of a whole ContactGroupStatus whose groups have ``sizes`` (ids, forces).

    One pack per status: the sizes of the groups repeat from step to step, and a pack per
    group was most of the status's cost at 20 rev/s, where every step writes one.
    """
    fmt = [_GROUPS_HEAD_CDR.format]
    pos = _GROUPS_HEAD_CDR.size - 4            # payload offsets, after the encapsulation
    for n, m in sizes:
        pad = -(pos + 8 + 4 * n) % 8 if m else 0
        fmt.append(_group_struct(n, m, pad).format[1:])
        pos += 8 + 4 * n + pad + 8 * m
    return struct.Struct("".join(fmt))


@functools.lru_cache(maxsize=256)
def _group_struct(n_ids, n_forces, pad):
    """
    Return the Struct of one ContactGroup: its ids, then its forces aligned to 8.

    One compiled layout per (size, alignment): a status is packed at every model step with
    a change of groups (each step at 20 rev/s), and building the format strings per group
    was most of its cost.
    """
    forces = f"{pad}x{n_forces}d" if n_forces else ""
    return struct.Struct(f"<I{n_ids}II{forces}")


class _OutputBag:
    """
    friction_node's output topics written beside the copied input.

    The stream appends (connection, log time [ns], CDR) to ``pending`` in output order (the
    copy of each input message, then what the node publishes for it) and ``flush`` es once
    per block: a call per message, and the writer's per-message checks, cost more than the
    packing itself (profiled).
    """

    def __init__(self, path, inputs):
        if path.exists():
            shutil.rmtree(path)   # our own output of an earlier run into the same --out
        self.store = friction_typestore()
        self.bag = BagWriter(path, self.store, storage="mcap")
        self.conns = {topic: self.bag.connection(topic, msgtype)
                      for topic, msgtype in OUTPUT_TOPICS}
        self._prediction, self._feedforward, self._groups = (
            self.conns[PREDICTION_TOPIC[0]], self.conns[FEEDFORWARD_TOPIC[0]],
            self.conns[GROUPS_TOPIC[0]])
        self.copies = {}
        for conn in inputs:
            if conn.topic in self.conns:
                # a recording of a live friction_node: the replay's answers take its place
                self.bag.not_copied[(conn.topic, conn.msgtype)] = "replaced by replay's output"
                self.copies[conn.id] = None
            else:
                self.copies[conn.id] = self.bag.copy_connection(conn)
        self._last_groups = None
        self.pending = []
        self._answers = self._group_changes = 0

    @property
    def written(self):
        """Messages written per output topic."""
        return {PREDICTION_TOPIC[0]: self._answers, GROUPS_TOPIC[0]: self._group_changes,
                FEEDFORWARD_TOPIC[0]: self._answers}

    def copy(self, conn, log_ns, raw):
        """Queue the copy of an input message (``log_ns`` an int, as rosbags reads it)."""
        out = self.copies.get(conn.id)
        if out is not None:
            self.pending.append((out, log_ns, raw))

    def publish(self, pred, stamp, log_ns, latency_s):
        """
        Queue what the node publishes for one prediction.

        ``stamp``: the input's header stamp [ns], which the outputs carry unchanged (before
        1970 too); ``log_ns``: the input's log time, at which they are logged, as a recorder
        beside the live node would log them (its latency aside).  Logged at the header stamp,
        a device-clock recording's outputs would lie decades from its inputs.
        """
        self.publish_values(prediction_values(pred), stamp, log_ns, latency_s)

    def publish_values(self, v, stamp, log_ns, latency_s):
        """``publish`` the Prediction whose fields are the tuple ``v`` (``process_values``)."""
        sec, nanosec = divmod(stamp, 1_000_000_000)
        pending = self.pending
        pending.append((self._prediction, log_ns,
                        prediction_values_cdr(v, sec, nanosec, latency_s)))
        # the runner's safe value (held or 0 after a step that did not converge), as the node
        pending.append((self._feedforward, log_ns, feedforward_cdr(v[13])))
        self._answers += 1
        groups = v[10]
        if groups is not self._last_groups and groups != self._last_groups:
            # The node publishes groups on change (and repeats them on a wall-clock timer,
            # which carries no new information and no input stamp: not reproduced here).
            self._last_groups = groups
            pending.append((self._groups, log_ns, groups_cdr(
                groups, sec, nanosec, v[1], v[11])))
            self._group_changes += 1

    def flush(self):
        """Hand what is queued to the bag writer (taken off the queue even if it fails)."""
        try:
            self.bag.write_many(self.pending)
        finally:
            self.pending.clear()

    def close(self):
        self.flush()
        self.bag.close()

    def abandon(self):
        """Close a bag whose run stopped early: what was queued is kept where it can be."""
        try:
            self.close()
        except Exception:   # the error that stopped the run is the one reported
            pass
