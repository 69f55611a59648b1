"""
rosbag2 recordings (sqlite3 and mcap) read with ``rosbags``, without ROS.

Messages are yielded in log order, the order ``ros2 bag play`` publishes them, so a replay
sees what the live node would: including header stamps that jump backwards.

``BagInput`` streams a bag: the topics the node subscribes to are resolved and type-checked
before the first message is read, every message is counted as it is read, and a damaged bag
is a ``BagError`` naming the file, never a traceback from the storage library.  Its
``blocks`` decode the input messages a block at a time with numpy.

rosbags is imported on first use: it costs about 0.5 s.  The names of ``bag_types``,
``bag_writer`` and ``alignment`` are importable from here too, where callers found them.
"""

from bisect import bisect_left
from collections import Counter
from operator import itemgetter
from pathlib import Path
import struct

import numpy as np
import yaml

from bb_friction_ros.alignment import (measured_torque_at, MAX_HELD,  # noqa: F401
                                       MeasuredAligner)
from bb_friction_ros.bag_types import (_header, _stamp, _stamp_ns, _typestore,  # noqa: F401
                                       _why, _wrench, BagError, Event, friction_typestore,
                                       KIND_FLAGS, KIND_TYPES, MAX_JOINT_NAMES_KEPT,
                                       Topics, with_measurement)
from bb_friction_ros.bag_writer import BagWriter, STORAGES, write_events  # noqa: F401
from bb_friction_ros.schedule import LATE_SAMPLES_MAX, LATE_STAMP_TOLERANCE_S  # noqa: F401


def _unknown_topic_rows(reader):
    """
    Return {sqlite3 file: {topic id: rows}} for rows whose topic id is not in ``topics``.

    rosbags reads messages joined with the ``topics`` table, so such rows are never
    returned.  It counts, on opening, all rows and each topic's rows: only where those
    disagree are the unknown ids looked up (a scan of the messages table).
    """
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader
    storage = getattr(reader, "storage", None)
    found = {}
    for db in getattr(storage, "storages", None) or [storage]:
        if not isinstance(db, Sqlite3Reader) or db.dbconn is None:
            continue
        if db.metadata.message_count == sum(c.msgcount for c in db.connections):
            continue
        rows = db.dbconn.execute(
            "SELECT topic_id, COUNT(*) FROM messages WHERE topic_id NOT IN "
            "(SELECT id FROM topics) GROUP BY topic_id ORDER BY topic_id").fetchall()
        if rows:
            found[str(db.path)] = {int(i): int(n) for i, n in rows}
    return found


def _check_metadata(path):
    """Refuse a rosbag2 directory whose metadata.yaml is missing, empty or not metadata."""
    meta = path / "metadata.yaml"
    if not meta.is_file():
        raise BagError(f"{path}: not a rosbag2 directory (no metadata.yaml)")
    try:
        data = yaml.safe_load(meta.read_bytes())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise BagError(f"{meta}: damaged metadata: not valid YAML "
                       f"({str(exc).splitlines()[0]})") from None
    if data is None:
        raise BagError(f"{meta}: damaged metadata: the file is empty")
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise BagError(f"{meta}: damaged metadata: no rosbag2_bagfile_information mapping")
    for key in ("storage_identifier", "relative_file_paths", "topics_with_message_count"):
        if key not in info:
            raise BagError(f"{meta}: damaged metadata (truncated?): no {key!r}")


class BagInput:
    """
    A rosbag2 (directory, or a single .mcap/.db3 file) opened for streaming replay.

    Use as a context manager.  On opening, the topics of ``topics`` are resolved and their
    message types checked: ``nut_state`` and ``axial_load`` are required,
    ``measured_torque`` is optional.  ``messages()`` then yields every message in log order;
    ``counts`` holds the messages actually read per topic (never metadata.yaml's claims) and
    ``joint_names`` the joint names seen on nut_state.  Every failure is a ``BagError``.

    Messages no reader can return are counted on opening: sqlite3 rows whose topic id has no
    row in the ``topics`` table (``unknown_topic_messages``); ``warnings()`` says so, and
    where the messages read disagree with the bag's own count.
    """

    def __init__(self, path, topics=Topics()):
        """Open ``path``; raise BagError (or FileNotFoundError) naming what is wrong."""
        self.path = Path(path)
        self.topics = topics
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such bag")
        if self.path.is_dir():
            _check_metadata(self.path)
        from rosbags.rosbag2 import Reader
        try:
            self._reader = Reader(self.path)
            self._reader.open()
            self.unknown_topic_messages = _unknown_topic_rows(self._reader)
        except Exception as exc:     # rosbags raises its own, sqlite3's and struct's errors
            files = self._files()
            self.close()
            raise BagError(f"{files}: not a readable rosbag2 ({_why(exc)})") from None
        try:
            self.connections = list(self._reader.connections)
            self.topic_types = {}
            for c in self.connections:
                self.topic_types.setdefault(c.topic, c.msgtype)
            self.resolved = self._resolve()
        except BaseException:
            self.close()
            raise
        self.counts = Counter()
        self.joint_names = Counter()
        self._store = _typestore()

    def _files(self):
        paths = getattr(getattr(self, "_reader", None), "paths", None) or []
        if len(paths) == 1:
            return str(paths[0])
        return str(self.path)

    def describe(self):
        """Return 'topic (type)' for every topic of the bag, comma separated."""
        return ", ".join(f"{t} ({m})" for t, m in sorted(self.topic_types.items())) or "none"

    def _resolve(self):
        resolved = {}
        for kind, msgtype in KIND_TYPES.items():
            name = self.topics.absolute(kind)
            found = self.topic_types.get(name)
            same_type = sorted(t for t, m in self.topic_types.items() if m == msgtype
                               and t != name)
            if found is None:
                if kind == "measured_torque":
                    continue
                base = name.rsplit("/", 1)[-1]
                nested = [t for t in self.topic_types if t.rsplit("/", 1)[-1] == base]
                hint = ""
                if nested:
                    hint = (f"; {', '.join(nested)} is recorded under a namespace: pass "
                            f"{KIND_FLAGS[kind]} {nested[0]}")
                elif same_type:
                    hint = (f"; topics of type {msgtype}: {', '.join(same_type)} (pass "
                            f"{KIND_FLAGS[kind]} TOPIC)")
                raise BagError(f"{self._files()}: no topic {name} ({msgtype}); the bag holds: "
                               f"{self.describe()}{hint}")
            if found != msgtype:
                hint = ""
                if same_type:
                    hint = (f"; topics of type {msgtype}: {', '.join(same_type)} (pass "
                            f"{KIND_FLAGS[kind]} TOPIC)")
                raise BagError(f"{self._files()}: topic {name} has type {found}, expected "
                               f"{msgtype}; the bag holds: {self.describe()}{hint}")
            resolved[name] = kind
        return resolved

    def __enter__(self):
        """Return self."""
        return self

    def __exit__(self, *exc):
        """Close the bag."""
        self.close()

    def close(self):
        """Close the bag (idempotent)."""
        reader, self._reader = getattr(self, "_reader", None), None
        if reader is not None:
            try:
                reader.close()
            except Exception:    # closing a damaged storage may fail again: already reported
                pass

    def warnings(self, all_topics=True):
        """
        Return sentences on messages of the bag that were not read, after reading it whole.

        Rows of an unknown topic (``unknown_topic_messages``), and topics whose count read
        differs from the bag's own (metadata.yaml of a directory): only the topics read
        (``all_topics`` False: the input topics).
        """
        out = []
        for name, ids in self.unknown_topic_messages.items():
            where = ", ".join(f"topic id {i}: {n}" for i, n in ids.items())
            out.append(f"{name}: {sum(ids.values())} messages carry a topic id with no row in "
                       f"its topics table ({where}): their topic and type are unknown, so "
                       "they were not read")
        listed = Counter()
        for c in self.connections:
            if all_topics or c.topic in self.resolved:
                listed[c.topic] += c.msgcount
        differ = [f"{listed[t]} on {t} ({self.counts[t]} read)" for t in sorted(listed)
                  if listed[t] != self.counts[t]]
        if differ:
            where = self.path / "metadata.yaml" if self.path.is_dir() else self._files()
            out.append(f"{where} lists other message counts than were read: "
                       f"{', '.join(differ)}; the summary counts the messages read")
        return out

    def total_messages(self):
        """Messages metadata.yaml announces (for a progress bar only: it may be wrong)."""
        return sum(c.msgcount for c in self.connections)

    def messages(self, all_topics=True):
        """
        Yield (connection, log time [ns], raw CDR bytes, Event or None) in log order.

        The Event is decoded for the resolved input topics; other topics (read only with
        ``all_topics``) are passed through undecoded.
        """
        conns = self.connections if all_topics else [
            c for c in self.connections if c.topic in self.resolved]
        if not conns:
            return
        it = self._reader.messages(connections=conns)
        while True:
            try:
                item = next(it)
            except StopIteration:
                return
            except Exception as exc:  # a truncated or corrupt storage file, at any depth
                raise BagError(f"{self._files()}: damaged bag: reading failed after "
                               f"{sum(self.counts.values())} messages ({_why(exc)})") from None
            conn, log_ns, raw = item
            self.counts[conn.topic] += 1
            kind = self.resolved.get(conn.topic)
            event = None
            if kind is not None:
                event = self._decode(kind, conn, log_ns, raw)
            yield conn, log_ns, raw, event

    def blocks(self, nut_joint, all_topics=True, size=None):
        """
        Yield the messages in log order as ``Block`` s of up to ``size`` (``READ_BLOCK``).

        The input topics are decoded a block at a time with numpy where the messages share
        one layout (``_decode_block``); ``Block.event(i)`` decodes any other one as
        ``messages()`` does, when the caller reaches it, so a damaged message is reported
        in order.  ``counts`` and ``joint_names`` count a block as it is read.  A read that
        fails yields the messages read before it, then raises BagError.
        """
        size = size or READ_BLOCK
        conns = self.connections if all_topics else [
            c for c in self.connections if c.topic in self.resolved]
        if not conns:
            return
        it = mcap_messages(self._reader, conns) or self._reader.messages(connections=conns)
        failed = None
        while failed is None:
            items = []
            try:
                for _ in range(size):
                    items.append(next(it))
            except StopIteration:
                failed = False
            except Exception as exc:  # a truncated or corrupt storage file, at any depth
                failed = BagError(f"{self._files()}: damaged bag: reading failed after "
                                  f"{sum(self.counts.values()) + len(items)} messages "
                                  f"({_why(exc)})")
            if items:
                yield self._decode_block(items, nut_joint)
            if failed:
                raise failed from None

    def _decode_block(self, items, nut_joint):
        before = {t: self.counts[t] for t in self.resolved}
        topics = [conn.topic for conn, _, _ in items]
        self.counts.update(topics)      # a list: Counter counts it in C
        block = Block(self, items, before)
        rows, logs, resolved = {}, [], self.resolved
        block.kinds = kinds = [resolved.get(t) for t in topics]
        for i, kind in enumerate(kinds):
            if kind is not None:
                item = items[i]
                rows.setdefault((kind, len(item[2])), []).append(i)
                logs.append(item[1])
        if logs:
            block.log_range = (min(logs), max(logs))
        for (kind, _), idx in rows.items():
            if kind == "nut_state":
                decoded = _decode_joint_states(items, idx, nut_joint, block)
                # the others are counted when decoded one by one (Block.event)
                if decoded is not None and decoded[1] and (
                        len(self.joint_names) < MAX_JOINT_NAMES_KEPT
                        or decoded[0] in self.joint_names):
                    self.joint_names[decoded[0]] += decoded[1]
            else:
                _decode_wrenches(items, idx, 16 if kind == "axial_load" else 40, block)
        return block

    def _decode(self, kind, conn, log_ns, raw):
        fast = _FAST_DECODERS[kind](raw)
        if fast is not None:
            sec, nanosec, *rest = fast
            stamp_s, stamp_ns_ = sec + 1e-9 * nanosec, sec * 1_000_000_000 + nanosec
            if kind != "nut_state":
                return Event(kind, stamp_s, value=rest[0], stamp_ns=stamp_ns_)
            names = rest[0]
            if len(self.joint_names) < MAX_JOINT_NAMES_KEPT or names in self.joint_names:
                self.joint_names[names] += 1
            return Event(kind, stamp_s, names, rest[1], rest[2], stamp_ns=stamp_ns_)
        try:
            msg = self._store.deserialize_cdr(raw, conn.msgtype)
            if kind == "nut_state":
                names = tuple(msg.name)
                if len(self.joint_names) < MAX_JOINT_NAMES_KEPT or names in self.joint_names:
                    self.joint_names[names] += 1
                return Event(kind, _stamp(msg.header), names,
                             tuple(float(x) for x in msg.position),
                             tuple(float(x) for x in msg.velocity),
                             stamp_ns=_stamp_ns(msg.header))
            value = msg.wrench.force.z if kind == "axial_load" else msg.wrench.torque.z
            return Event(kind, _stamp(msg.header), value=float(value),
                         stamp_ns=_stamp_ns(msg.header))
        except Exception as exc:      # rosbags' CDR decoder raises several types
            raise BagError(f"{self._files()}: damaged message {self.counts[conn.topic]} on "
                           f"{conn.topic} (log time {log_ns} ns): cannot decode it as "
                           f"{conn.msgtype} ({_why(exc)})") from None


# --- the input messages decoded without rosbags' message objects ---------------------------
# rosbags' generic decoder builds a message object per message (header, time, arrays): about
# a third of replay's reading time on the demo bag (profiled).  The two input types
# are decoded here with struct, for little-endian CDR, the encoding every ROS 2 bag on x86
# and ARM holds.  Anything else, and anything these checks do not accept (the same checks as
# rosbags': string bounds and terminators, sequences inside the message, no trailing bytes
# beyond padding), goes to rosbags, which decodes it or names the damage.
# test_bags checks the results equal rosbags' on generated and damaged messages.

_U32 = struct.Struct("<I").unpack_from
_TIME = struct.Struct("<iI").unpack_from
_FLOAT64 = struct.Struct("<d").unpack_from


def _cdr_string(buf, pos):
    """Return (the string at ``pos``, the position after it); raise if malformed."""
    pos = (pos + 3) & -4
    (size,) = _U32(buf, pos)
    end = pos + 4 + size
    if size < 1 or end > len(buf) or buf[end - 1] != 0:
        raise ValueError("bad string")
    return buf[pos + 4:end - 1].decode(), end


def _cdr_float64s(buf, pos):
    """Return (the float64 sequence at ``pos`` as a tuple, the position after it)."""
    pos = (pos + 3) & -4
    (size,) = _U32(buf, pos)
    pos += 4
    if size:
        pos = (pos + 7) & -8
    end = pos + 8 * size
    if end > len(buf):
        raise ValueError("bad sequence")
    return struct.unpack_from(f"<{size}d", buf, pos), end


def _cdr_header(buf):
    """Return (sec, nanosec, position after std_msgs/Header) of a CDR payload."""
    sec, nanosec = _TIME(buf, 0)
    _, pos = _cdr_string(buf, 8)        # frame_id: checked, not used
    return sec, nanosec, pos


def _complete(raw, end):
    """Return whether a payload ending at ``end`` fills ``raw`` (up to 3 padding bytes)."""
    return end + 4 <= len(raw) <= end + 4 + 3


def fast_joint_state(raw):
    """Return (sec, nanosec, names, positions, velocities) of a JointState, or None."""
    try:
        if raw[:2] != b"\x00\x01":
            return None
        buf = bytes(raw[4:])
        sec, nanosec, names, pos = _joint_state_names(buf)
        positions, pos = _cdr_float64s(buf, pos)
        velocities, pos = _cdr_float64s(buf, pos)
        _, pos = _cdr_float64s(buf, pos)                       # effort
        if not _complete(raw, pos):
            return None
        return sec, nanosec, names, positions, velocities
    except (struct.error, ValueError):          # UnicodeDecodeError is a ValueError
        return None


def _joint_state_names(buf):
    """Return (sec, nanosec, names, offset after them) of a JointState's CDR body ``buf``."""
    sec, nanosec, pos = _cdr_header(buf)
    pos = (pos + 3) & -4
    (count,) = _U32(buf, pos)
    pos += 4
    if count > len(buf):
        raise ValueError("JointState name count beyond the message")
    names = []
    for _ in range(count):
        name, pos = _cdr_string(buf, pos)
        names.append(name)
    return sec, nanosec, tuple(names), pos


def _fast_wrench(raw, offset):
    try:
        if raw[:2] != b"\x00\x01":
            return None
        buf = bytes(raw[4:])
        sec, nanosec, pos = _cdr_header(buf)
        pos = (pos + 7) & -8                    # geometry_msgs/Wrench: six float64
        if not _complete(raw, pos + 48):
            return None
        return sec, nanosec, _FLOAT64(buf, pos + offset)[0]
    except (struct.error, ValueError):
        return None


def fast_wrench_force_z(raw):
    """Return (sec, nanosec, force.z) of a WrenchStamped, or None."""
    return _fast_wrench(raw, 16)


def fast_wrench_torque_z(raw):
    """Return (sec, nanosec, torque.z) of a WrenchStamped, or None."""
    return _fast_wrench(raw, 40)


_FAST_DECODERS = {"nut_state": fast_joint_state, "axial_load": fast_wrench_force_z,
                  "measured_torque": fast_wrench_torque_z}


# --- a block of messages decoded at once ---------------------------------------------------
# Per message, even the struct decoders above cost ~10 us with the Event they build: 0.13 s
# of CPU for the 12 600 input messages of a 6-second bag at 1 kHz, a third of replay's work
# outside the model.  Messages of one topic and one length usually share one
# layout (the same frame_id, joint names and sequence sizes): the first is checked by the
# decoder above, and every other whose bytes equal it everywhere but the stamp and the
# numbers is read with numpy.  Anything else is decoded one by one when the caller reaches
# it (``Block.event``).  test_bags checks blocks against messages() on odd bags.

# Messages per block: numpy's per-call cost is paid per block, rows stay small (~1 MB).
READ_BLOCK = 2048


class Block:
    """
    Messages read together, in log order: ``items`` (connection, log time [ns], raw CDR).

    Per item (arrays of ``len(items)``): ``kinds`` (the input kind or None), and where
    ``fast`` is True the decoded ``sec``, ``nanosec``, ``stamp_s`` and ``value`` (the nut
    joint's angle [rad], force.z [N] or torque.z [N m]) and ``velocity`` (the nut joint's
    [rad/s]).  A nut_state is fast only with the nut joint in it and finite numbers: the
    others (and messages of other layouts) go through ``event(i)`` and the node's checks.
    """

    def __init__(self, src, items, counts_before):
        n = len(items)
        self.src, self.items, self.kinds = src, items, []
        self.log_range = None   # (first, last) log time [ns] of its input messages
        self._counts_before = counts_before
        self._numbers = None
        self.fast = np.zeros(n, dtype=bool)
        self.sec = np.zeros(n, dtype=np.int64)
        self.nanosec = np.zeros(n, dtype=np.int64)
        self.value = np.full(n, np.nan)
        self.velocity = np.full(n, np.nan)

    @property
    def stamp_s(self):
        """Header stamps [s] as the message decoders compute them (sec + 1e-9 * nanosec)."""
        return self.sec.astype(np.float64) + 1e-9 * self.nanosec.astype(np.float64)

    @property
    def stamp_ns(self):
        """Header stamps [ns], exact."""
        return self.sec * 1_000_000_000 + self.nanosec

    def event(self, i):
        """Return item ``i`` of an input topic as ``BagInput.messages`` decodes it."""
        conn, log_ns, raw = self.items[i]
        if self._numbers is None:
            # each message's number on its topic, for the error naming a damaged one
            # (counted once per block: a bag of odd messages takes this path for each)
            seen = Counter(self._counts_before)
            self._numbers = []
            for c, _, _ in self.items:
                seen[c.topic] += 1
                self._numbers.append(seen[c.topic])
        number = self._numbers[i]
        read = self.src.counts[conn.topic]
        self.src.counts[conn.topic] = number
        try:
            return self.src._decode(self.kinds[i], conn, log_ns, raw)
        finally:
            self.src.counts[conn.topic] = read


def _template_rows(items, idx, mask):
    """
    Return (the rows of ``idx`` as an (n, length) uint8 array, which equal the first).

    ``mask`` marks the bytes that may differ (the stamp and the numbers read).
    """
    data = np.frombuffer(b"".join(items[i][2] for i in idx), dtype=np.uint8)
    rows = data.reshape(len(idx), -1)
    keep = ~mask
    same = (rows[:, keep] == rows[0, keep]).all(axis=1)
    return rows, same


def _column(rows, start, dtype):
    """Return the little-endian number of ``dtype`` at byte ``start`` of each row."""
    width = np.dtype(dtype).itemsize
    return rows[:, start:start + width].copy().view(dtype)[:, 0]


def _set_stamps(block, idx, rows):
    block.sec[idx] = _column(rows, 4, "<i4")
    block.nanosec[idx] = _column(rows, 8, "<u4")


def _decode_joint_states(items, idx, nut_joint, block):
    """
    Decode JointStates of one length into ``block``; return (names, messages decoded).

    None: the first message is not one the struct decoder takes (all go one by one).
    """
    layout = _joint_state_layout(items[idx[0]][2])
    if layout is None:
        return None
    names, sequences = layout
    mask = np.zeros(len(items[idx[0]][2]), dtype=bool)
    mask[4:12] = True                                   # the stamp
    for offset, count in sequences:
        mask[offset:offset + 8 * count] = True          # position, velocity, effort
    rows, same = _template_rows(items, idx, mask)
    idx = np.asarray(idx)[same]
    rows = rows[same]
    if nut_joint not in names:
        return names, 0
    j = names.index(nut_joint)
    (p_off, n_pos), (v_off, n_vel), _ = sequences
    if j >= n_pos or j >= n_vel:
        return names, 0              # the node's checks name what is missing
    angle, velocity = _column(rows, p_off + 8 * j, "<f8"), _column(rows, v_off + 8 * j, "<f8")
    ok = np.isfinite(angle) & np.isfinite(velocity)
    idx, rows = idx[ok], rows[ok]
    _set_stamps(block, idx, rows)
    block.value[idx], block.velocity[idx] = angle[ok], velocity[ok]
    block.fast[idx] = True
    return names, len(idx)


def _joint_state_layout(raw):
    """Return (names, ((offset, count) of position, velocity, effort)) in ``raw``, or None."""
    if fast_joint_state(raw) is None:
        return None
    buf = bytes(raw[4:])
    _, _, names, pos = _joint_state_names(buf)
    sequences = []
    for _ in range(3):
        pos = (pos + 3) & -4
        (size,) = _U32(buf, pos)
        pos += 4
        if size:
            pos = (pos + 7) & -8
        sequences.append((4 + pos, size))          # offsets in raw, after encapsulation
        pos += 8 * size
    return names, tuple(sequences)


def _decode_wrenches(items, idx, offset, block):
    """Decode WrenchStampeds of one length into ``block`` (force.z or torque.z at offset)."""
    raw = items[idx[0]][2]
    if _fast_wrench(raw, offset) is None:
        return
    _, _, pos = _cdr_header(bytes(raw[4:]))
    wrench = 4 + ((pos + 7) & -8)                 # in raw, after the encapsulation
    mask = np.zeros(len(raw), dtype=bool)
    mask[4:12] = True
    mask[wrench:wrench + 48] = True               # six float64: force and torque
    rows, same = _template_rows(items, idx, mask)
    idx, rows = np.asarray(idx)[same], rows[same]
    _set_stamps(block, idx, rows)
    block.value[idx] = _column(rows, wrench + offset, "<f8")
    block.fast[idx] = True


# --- single-mcap bags read a chunk at a time ----------------------------------------------
# rosbags' McapReader walks each chunk through a BytesIO per record and merges the chunks
# with heapq, a generator step per message: ~4 us per message, a third of replay's own work
# at 1 rev/s (profiled).  ``mcap_messages`` yields the same messages in the same order from
# one bytes object per chunk.  test_bags checks it yields exactly what rosbags yields.

_MCAP_RECORD = struct.Struct("<BQ").unpack_from        # opcode, record length
_MCAP_MESSAGE_HEAD = struct.Struct("<HIQQ").unpack_from  # channel, sequence, log, publish
# both at once: a message record's opcode, length and head (one call per record)
_MCAP_MESSAGE_RECORD = struct.Struct("<BQHIQQ")


def _mcap_storage(reader, connections):
    """
    Return (the McapReader, {its channel id: the connection of ``connections``}) or None.

    Only a bag of one mcap file without per-message compression: the chunks' order then
    decides the messages' (``mcap_messages``); anything else is rosbags' to read.
    """
    from rosbags.rosbag2.reader import DirectoryReader
    from rosbags.rosbag2.storage_mcap import McapReader
    storage = getattr(reader, "storage", None)
    if type(storage) is McapReader:
        return storage, {c.id: c for c in connections}
    if type(storage) is not DirectoryReader or len(storage.storages) != 1 \
            or type(storage.storages[0]) is not McapReader \
            or storage.metadata.compression_mode == "message":
        return None
    mcap = storage.storages[0]
    # DirectoryReader.messages' own rule: a file's channel is the first connection asked
    # for of the same topic, type and QoS and (where both carry one) digest
    cmap = {}
    for x in mcap.connections:
        conn = next((y for y in connections
                     if y.topic == x.topic and y.msgtype == x.msgtype and y.ext == x.ext
                     and (not x.digest or not y.digest or y.digest == x.digest)), None)
        if conn is not None:
            cmap[x.id] = conn
    return mcap, cmap


def mcap_messages(reader, connections):
    """
    Yield what rosbags' ``reader.messages(connections)`` yields, read a chunk at a time.

    None where rosbags must read (``_mcap_storage``; a file without a chunk index; chunks
    whose time ranges overlap, which rosbags merges message by message).  Its order: each
    chunk's messages sorted by log time, stably, the chunks in file order, a message
    outside its chunk's indexed time range left out, as rosbags does.  A chunk that does
    not parse is read by rosbags instead, so a damaged one raises rosbags' own error.
    """
    found = _mcap_storage(reader, connections)
    if found is None or not found[0].chunks:
        return None
    mcap, cmap = found
    chunks = sorted(mcap.chunks, key=lambda c: c.chunk_start_offset)
    for before, after in zip(chunks, chunks[1:]):
        if after.message_start_time < before.message_end_time:
            return None
    chunks = [c for c in chunks if any(c.channel_count.get(cid, 0) for cid in cmap)]
    return _mcap_chunk_messages(mcap, chunks, cmap)


def _mcap_chunk_messages(mcap, chunks, cmap):
    """
    Yield (connection, log time [ns], CDR bytes) of ``chunks`` (``mcap_messages``).

    A chunk is read when rosbags' merge reads it: once the messages before its start time
    are out (a damaged chunk stops the run after the same messages).
    """
    held = []
    for chunk in chunks:
        start = chunk.message_start_time
        cut = bisect_left(held, start, key=_log_time)      # held is in log order
        yield from held[:cut]
        try:
            found = _mcap_chunk(mcap, chunk, cmap)
        except (struct.error, ValueError, IndexError):
            found = None
        if found is None:       # rosbags names the damage, or reads what this cannot
            from rosbags.rosbag2.storage_mcap import msgsrc
            found = [(m.connection, m.timestamp, m.data) for m in msgsrc(
                chunk, cmap, start, chunk.message_end_time + 1, mcap.bio) if m.offset]
        # the ones left hold the next chunk's start time (time ranges do not overlap)
        yield from held[cut:]
        held = found
    yield from held


def _mcap_chunk(mcap, chunk, cmap):
    """Return the messages of one chunk in rosbags' order, or None (unknown compression)."""
    from rosbags.rosbag2.storage_mcap import decompress, DECOMPRESSORS
    if chunk.compression not in DECOMPRESSORS:
        return None
    bio = mcap.bio
    # the chunk record: opcode and length (9 bytes), start, end, uncompressed size (24),
    # CRC (4), compression (a 4-byte length and the name), compressed size (8), the data
    bio.seek(chunk.chunk_start_offset + 9 + 24)
    (crc,) = struct.unpack("<I", bio.read(4))
    bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
    data = bio.read(chunk.compressed_size)
    if len(data) != chunk.compressed_size:
        return None
    buf = decompress(data, chunk.compression, chunk.uncompressed_size, crc)
    start, stop = chunk.message_start_time, chunk.message_end_time + 1
    record, head = _MCAP_RECORD, _MCAP_MESSAGE_HEAD
    whole, whole_size = _MCAP_MESSAGE_RECORD.unpack_from, _MCAP_MESSAGE_RECORD.size
    out, pos, end = [], 0, len(buf)
    while pos < end:
        if pos + whole_size <= end:
            op, length, channel, _, log_ns, _ = whole(buf, pos)
        else:
            (op, length), channel = record(buf, pos), None
        body, pos = pos + 9, pos + 9 + length
        if pos > end:
            return None
        if op == 0x05:
            if length < 22:
                return None
            if channel is None:
                channel, _, log_ns, _ = head(buf, body)
            if start <= log_ns < stop:
                conn = cmap.get(channel)
                if conn is not None:
                    out.append((conn, log_ns, buf[body + 22:pos]))
    out.sort(key=_log_time)     # stable, as rosbags sorts each chunk
    return out


# an item's log time, as a sort key: a C call (a Python key function was called per message)
_log_time = itemgetter(1)


def iter_events(path, topics=Topics()):
    """
    Return (an iterator of the input events in log order, messages read per topic).

    The bag is read as the iterator is consumed, so a long recording is never in memory as
    events, and closed when it is exhausted; the counts (a Counter of the messages actually
    read) fill as it goes.  Raises FileNotFoundError or BagError (a ValueError) naming the file
    when the bag cannot be opened; reading a damaged one raises BagError.
    """
    bag = BagInput(path, topics)

    def events():
        try:
            for _, _, _, ev in bag.messages(all_topics=False):
                yield ev
        finally:
            bag.close()
    return events(), bag.counts


def read_events(path, topics=Topics()):
    """
    Return (events in log order, messages read per topic) of a rosbag2.

    Only the input topics are read.  Raises FileNotFoundError or BagError (a ValueError)
    naming the file when the bag cannot be used.
    """
    events, counts = iter_events(path, topics)
    return list(events), dict(counts)
