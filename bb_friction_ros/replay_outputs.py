"""
What replay writes per answer: prediction.csv's lines, the plotted series, ``bag/``.

The CSV lines are %-formatted from the answers' tuples (``_csv_text``), the plotted columns
spilled to a temporary file (``_Series``).  The node's messages are packed as CDR directly
(``prediction_cdr``, ``feedforward_cdr``, ``groups_cdr``; test_replay checks every byte
against rosbags' own serialisation) and queued with the copied inputs in output order
(``_OutputBag``).
"""

from array import array
import functools
import math
import shutil
import struct

import numpy as np

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
        self._ff_value = self._ff_cdr = None     # the last feedforward packed, and its CDR
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
        # the runner's safe value (held or 0 after a step that did not converge), as the node;
        # the same float object as the answer before's (a held state's) packs the same bytes
        ff = v[13]
        if ff is not self._ff_value:
            self._ff_value, self._ff_cdr = ff, feedforward_cdr(ff)
        pending.append((self._feedforward, log_ns, self._ff_cdr))
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


def _row_formats(measured, empirical):
    """
    Return the %-formats of a prediction.csv line: (before, after) the measured column.

    Byte for byte what csv.writer wrote (floats as repr, which never need quoting, the stamp
    with 9 decimals, CRLF): one %-format per row instead of six repr calls and a writerow.
    """
    head = "%.9f,%r,%r,%r,%r,%r"
    tail = (",%r" if empirical else "") + ",%d\r\n"
    return head + (",%r" if measured else "") + tail


def csv_values(pred, empirical):
    """Return the prediction.csv values of ``pred`` but the measurement (``_row_formats``)."""
    return _csv_values(prediction_values(pred), empirical)


def _csv_values(v, empirical):
    """``csv_values`` of the Prediction whose fields are the tuple ``v``."""
    if empirical:
        return (v[0], v[1], v[2], v[3], v[4], v[6], v[7], int(bool(v[8])))
    return (v[0], v[1], v[2], v[3], v[4], v[6], int(bool(v[8])))


def _write_lines(fh, lines, empirical=False):
    """
    Write the queued prediction.csv rows; taken off the queue first, so never twice.

    ``lines``: (answer, measured torque or None without the column), ``_csv_text``.
    """
    rows = lines[:]
    lines.clear()
    fh.write(_csv_text(rows, empirical))


def _csv_text(rows, empirical):
    """
    Return prediction.csv lines of ``rows`` (answer, measured torque or None).

    An answer: the Prediction's fields as a tuple (``ModelRunner.process_values``); its
    line holds ``_csv_values`` (``_row_formats``), byte for byte.  The speed, the load
    and the model's torques repeat from row to row (the load arrives at a tenth of the
    nut's rate, a state answers every input until the next step): a float equal to the
    row before's, and of the same type, is written with that row's text; repr, which finds
    the shortest exact digits, was half of the CSV's cost.  Zero is always formatted (0.0
    and -0.0 are equal), and anything but a Python float (numpy's repr names its type).
    """
    out = []
    append = out.append
    lw = lf = lt = lb = None
    sw = sf = st = sb = ""
    with_meas = "%.9f,%r,%s,%s,%s,%s,%r" + (",%r,%d\r\n" if empirical else ",%d\r\n")
    without = "%.9f,%r,%s,%s,%s,%s" + (",%r,%d\r\n" if empirical else ",%d\r\n")
    for v, meas in rows:
        w, f, t, b = v[2], v[3], v[4], v[6]
        if w != lw or w == 0.0 or type(w) is not float:
            lw, sw = w if type(w) is float else None, repr(w)
        if f != lf or f == 0.0 or type(f) is not float:
            lf, sf = f if type(f) is float else None, repr(f)
        if t != lt or t == 0.0 or type(t) is not float:
            lt, st = t if type(t) is float else None, repr(t)
        if b != lb or b == 0.0 or type(b) is not float:
            lb, sb = b if type(b) is float else None, repr(b)
        converged = 1 if v[8] else 0       # int(bool(...)), as _csv_values
        if meas is None:
            append(without % ((v[0], v[1], sw, sf, st, sb, v[7], converged) if empirical
                              else (v[0], v[1], sw, sf, st, sb, converged)))
        else:
            append(with_meas % ((v[0], v[1], sw, sf, st, sb, meas, v[7], converged)
                                if empirical else (v[0], v[1], sw, sf, st, sb, meas,
                                                   converged)))
    return "".join(out)


class _Series:
    """
    The plotted columns, spilled to a temporary file as the bag streams (constant memory).

    A 10-minute 1 kHz bag has 600k samples; kept as Python objects they took most of
    replay's 1.2 GB peak, and even packed they would be 38 MB.
    """

    COLUMNS = ("t", "torque", "b2b", "speed", "load", "groups", "largest", "meas")
    BUFFER_ROWS = 8192

    def __init__(self, measured):
        import tempfile
        self.measured = measured
        self._file = tempfile.TemporaryFile()
        self._buf = array("d")
        self.rows = 0
        self._groups, self._group_sizes = None, None

    def add_rows(self, rows, measured=True):
        """
        Append the answer of each (answer, measured torque) of ``rows``, in order.

        An answer: the Prediction's fields as a tuple (``ModelRunner.process_values``).  The
        rows go straight into the buffer, the measured torque last (NaN without
        ``measured``); the group sizes are counted once per groups object (the same groups
        answer every sample until the next step).
        """
        buf, groups, sizes = self._buf, self._groups, self._group_sizes
        nan = math.nan
        for v, meas in rows:
            g = v[10]
            if g is not groups:     # every answer at 20 rev/s: a loop, not max's listcomp
                groups, largest = g, 0
                for x in g:
                    if len(x[0]) > largest:
                        largest = len(x[0])
                sizes = (len(g), largest)
            buf.extend((v[0], v[4], v[6], v[2], v[3]) + sizes)
            buf.append(meas if measured else nan)
        self._groups, self._group_sizes = groups, sizes
        self.rows += len(rows)
        self._spill()

    def _spill(self):
        """Write the buffer to the file once it holds BUFFER_ROWS rows."""
        if len(self._buf) >= self.BUFFER_ROWS * len(self.COLUMNS):
            self._buf.tofile(self._file)
            del self._buf[:]

    def chunks(self):
        """Yield the rows written so far as (n, 8) float64 arrays, a buffer at a time."""
        self._buf.tofile(self._file)
        del self._buf[:]
        self._file.flush()
        self._file.seek(0)
        width = len(self.COLUMNS)
        while True:
            block = np.fromfile(self._file, dtype=np.float64,
                                count=self.BUFFER_ROWS * width)
            if block.size == 0:
                return
            yield block.reshape(-1, width)

    def decimated(self, buckets=2000):
        """
        Return the columns min/max-decimated to ``buckets`` (x repeated twice per bucket).

        At the figure's resolution a min/max envelope draws what every point would, from a
        bounded number of points.
        """
        per = max(1, math.ceil(self.rows / buckets))
        if per == 1:
            data = np.concatenate(list(self.chunks()) or [np.zeros((0, 8))])
            return {k: data[:, i] for i, k in enumerate(self.COLUMNS)}
        lo, hi, xs = [], [], []
        carry = np.zeros((0, len(self.COLUMNS)))
        for block in self.chunks():
            block = np.concatenate([carry, block])
            n = (len(block) // per) * per
            carry = block[n:].copy()
            if n:
                b = block[:n].reshape(-1, per, len(self.COLUMNS))
                lo.append(np.nanmin(b, axis=1) if self.measured else b.min(axis=1))
                hi.append(np.nanmax(b, axis=1) if self.measured else b.max(axis=1))
                xs.append(b[:, 0, 0].copy())     # a view would keep every block alive
        if len(carry):
            lo.append(np.nanmin(carry, axis=0)[None] if self.measured else carry.min(0)[None])
            hi.append(np.nanmax(carry, axis=0)[None] if self.measured else carry.max(0)[None])
            xs.append(carry[:1, 0])
        lo, hi, x = np.concatenate(lo), np.concatenate(hi), np.concatenate(xs)
        out = {k: np.column_stack([lo[:, i], hi[:, i]]).ravel()
               for i, k in enumerate(self.COLUMNS)}
        out["t"] = np.repeat(x, 2)
        return out

    def close(self):
        self._file.close()
