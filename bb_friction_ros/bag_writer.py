"""
rosbag2 recordings (sqlite3 and mcap) written with ``rosbags``, in batches.

rosbags' public ``Writer.write`` takes one message per call (0.11: ``open``,
``add_connection``, ``write``, ``close`` are its whole writing API); at replay's rates its
per-message bookkeeping cost more than the packing itself, so an mcap bag is written a
chunk at a time into the writer's own state (``_mcap_write_batch``), checked byte for byte
against rosbags' own output (test_bags), and anything else goes through ``Writer.write``.
"""

from collections import defaultdict
from io import BytesIO
from pathlib import Path
import struct

import numpy as np

from bb_friction_ros.bag_types import (_header, _typestore, _why, _wrench, BagError,
                                       KIND_TYPES, Topics)
from bb_friction_ros.interface import JOINT_STATE

STORAGES = ("sqlite3", "mcap")

# Messages queued before they are written in one batch (about 1 MB at replay's sizes).
WRITE_BATCH = 4096
# An MCAP message record's opcode and fixed fields: opcode, record length, channel id,
# sequence, log time, publish time (then the payload).  rosbags' McapWriter.write spends
# ~15 us per message on a BytesIO, five small writes and the chunk's bookkeeping: 25 700
# writes were 0.45 s of a 6-second bag's replay at 1 rev/s, more than reading it.
_MCAP_MESSAGE = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"),
                          ("sequence", "<u4"), ("log", "<u8"), ("publish", "<u8")])
_MCAP_MESSAGE_OP = 0x05
_MCAP_MESSAGE_FIXED = _MCAP_MESSAGE.itemsize - 9  # record length without its payload
# rosbags' McapWriter closes a chunk after the message that takes it past this size.
_MCAP_CHUNK_BYTES = 2 ** 20


def _mcap_batch_writable(writer):
    """
    Whether ``_mcap_write_batch`` may write into rosbags' writer ``writer``.

    It writes the records rosbags' own ``McapWriter.write`` would, into the same chunk
    bookkeeping (rosbags is pinned in requirements.txt; test_bags checks that a bag written
    in batches is byte for byte the bag rosbags writes message by message).  Anything else
    (sqlite3, per-message compression, another rosbags layout) is written by rosbags.
    """
    from rosbags.rosbag2.storage_mcap import McapWriter
    from rosbags.rosbag2.writer import CompressionMode
    storage = getattr(writer, "storage", None)
    return type(storage) is McapWriter \
        and writer.compression_mode != CompressionMode.MESSAGE \
        and all(hasattr(storage, a) for a in ("chunk", "channel_stats", "message_start_time",
                                              "message_end_time", "close_chunk", "bio",
                                              "chunks", "compressor", "compression")) \
        and all(hasattr(writer, a) for a in ("counts", "min_timestamp", "max_timestamp"))


def _mcap_write_batch(writer, batch, index):
    """
    Write ``batch``, a list of (connection, log time [ns], CDR bytes), in order.

    Exactly what ``writer.write`` does for each, in one ``write`` per chunk: the same
    records, message indexes, chunk boundaries, statistics and metadata counts.  The
    records' fixed fields are packed with numpy (a struct.pack per message cost ~1 us).
    ``index``: the open chunk's message index, {channel id: [(log times, offsets)]} in
    order of first appearance, kept as arrays and written by ``_mcap_close_chunk``
    (rosbags' own ``chunk.msgs`` is left empty).
    """
    storage = writer.storage
    n = len(batch)
    conns, logs, datas = zip(*batch)        # the columns, transposed in C
    ids = np.array([c.id for c in conns], dtype=np.int64)
    stamps = np.fromiter(logs, dtype=np.uint64, count=n)
    sizes = np.fromiter(map(len, datas), dtype=np.int64, count=n)
    head = np.zeros(n, dtype=_MCAP_MESSAGE)
    head["op"] = _MCAP_MESSAGE_OP
    head["length"] = _MCAP_MESSAGE_FIXED + sizes
    head["channel"] = ids
    head["log"] = head["publish"] = stamps
    heads = head.tobytes()
    width = _MCAP_MESSAGE.itemsize
    ends = np.cumsum(width + sizes)              # record ends, from the batch's start
    i = 0
    while i < n:
        chunk = storage.chunk
        start = chunk.bio.tell()
        # rosbags closes the chunk after the message that takes it past the limit
        over = np.flatnonzero(start + ends[i:] - (ends[i - 1] if i else 0)
                              > _MCAP_CHUNK_BYTES)
        j = i + int(over[0]) + 1 if len(over) else n
        parts = [None] * (2 * (j - i))
        parts[0::2] = [heads[k:k + width] for k in range(i * width, j * width, width)]
        parts[1::2] = datas[i:j]
        # where each record starts in the chunk
        offsets = start + ends[i:j] - (width + sizes[i:j]) - (ends[i - 1] if i else 0)
        chunk.bio.write(b"".join(parts))
        lo, hi = int(stamps[i:j].min()), int(stamps[i:j].max())
        chunk.message_start_time = min(chunk.message_start_time, lo)
        chunk.message_end_time = max(chunk.message_end_time, hi)
        storage.message_start_time = min(storage.message_start_time, lo)
        storage.message_end_time = max(storage.message_end_time, hi)
        writer.min_timestamp = min(writer.min_timestamp, lo)
        writer.max_timestamp = max(writer.max_timestamp, hi)
        sub = ids[i:j]
        for cid in dict.fromkeys(sub.tolist()):      # in order of first appearance
            mine = sub == cid
            count = int(mine.sum())
            index.setdefault(cid, []).append((stamps[i:j][mine], offsets[mine]))
            storage.channel_stats[cid] += count
            writer.counts[cid] += count
        if len(over):
            _mcap_close_chunk(storage, index)
        i = j


def _mcap_close_chunk(storage, index):
    """
    Close the open chunk of rosbags' McapWriter ``storage`` as its ``close_chunk`` does.

    The same records byte for byte (test_bags), the message index written from ``index``
    (``_mcap_write_batch``) with numpy: rosbags writes two 8-byte fields per message
    through a BytesIO, a twentieth of replay's own work at 1 rev/s (profiled).
    """
    from rosbags.rosbag2.storage_mcap import PendingChunk
    chunk, bio = storage.chunk, storage.bio
    size = chunk.bio.tell()
    compressed = storage.compressor(chunk.bio.getvalue())
    name = storage.compression.encode()
    head = struct.pack("<QQQI", chunk.message_start_time, chunk.message_end_time, size, 0)
    head += struct.pack("<I", len(name)) + name + struct.pack("<Q", len(compressed))
    chunk_start = bio.tell()
    bio.write(struct.pack("<BQ", 0x06, len(head) + len(compressed)) + head)
    bio.write(compressed)
    chunk_end = bio.tell()
    offsets = []
    for cid, parts in index.items():
        offsets.append((cid, bio.tell()))
        pairs = np.empty((sum(len(t) for t, _ in parts), 2), dtype="<u8")
        pairs[:, 0] = np.concatenate([t for t, _ in parts])
        pairs[:, 1] = np.concatenate([o for _, o in parts])
        body = pairs.tobytes()
        bio.write(struct.pack("<BQHI", 0x07, 6 + len(body), cid, len(body)) + body)
    rec = BytesIO()
    rec.write(struct.pack("<QQQQI", chunk.message_start_time, chunk.message_end_time,
                          chunk_start, chunk_end - chunk_start, len(offsets) * 10))
    for cid, offset in offsets:
        rec.write(struct.pack("<HQ", cid, offset))
    rec.write(struct.pack("<Q", bio.tell() - chunk_end) + struct.pack("<I", len(name))
              + name + struct.pack("<QQ", len(compressed), size))
    storage.chunks.append(rec)
    storage.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
    index.clear()


class BagWriter:
    """
    A rosbag2 written in batches of ``WRITE_BATCH`` messages, in the order given.

    Connections carry their message definitions, so a reader without our packages can
    decode every topic.  Use as a context manager: the last batch is written on closing.
    """

    def __init__(self, path, store=None, storage="mcap"):
        """Create the bag directory ``path`` (it must not exist)."""
        from rosbags.rosbag2 import StoragePlugin, Writer
        if storage not in STORAGES:
            raise ValueError(f"storage: must be 'sqlite3' or 'mcap', got {storage!r}")
        plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
        self.store = store or _typestore()
        self.path = Path(path)
        self._writer = Writer(self.path, version=9, storage_plugin=plugin)
        self._writer.open()
        self._conns = {}
        self.not_copied = {}
        self._batch = []
        self._batched = _mcap_batch_writable(self._writer)
        self._index = {}        # the open chunk's message index (_mcap_write_batch)

    def connection(self, topic, msgtype):
        """Return the output connection of ``topic`` (added on first use)."""
        key = (topic, msgtype)
        if key not in self._conns:
            self._conns[key] = self._writer.add_connection(topic, msgtype,
                                                           typestore=self.store)
        return self._conns[key]

    def copy_connection(self, conn):
        """
        Return the output connection for input connection ``conn``, or None.

        The definition comes from our typestore when it knows the type, else from the input
        bag; a topic with neither is not copied (listed in ``not_copied``).
        """
        key = (conn.topic, conn.msgtype)
        if key in self._conns or key in self.not_copied:
            return self._conns.get(key)
        qos = list(getattr(conn.ext, "offered_qos_profiles", []) or [])
        from rosbags.typesys import get_types_from_msg
        try:
            if conn.msgtype not in self.store.types and conn.msgdef.data:
                self.store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
            self._conns[key] = self._writer.add_connection(
                conn.topic, conn.msgtype, typestore=self.store, offered_qos_profiles=qos)
        except Exception as exc:     # an unknown type without a usable definition
            self.not_copied[key] = _why(exc)
            return None
        return self._conns[key]

    def write_raw(self, conn, log_ns, raw):
        """Write already serialised CDR bytes (``conn`` from this writer)."""
        self._batch.append((conn, int(log_ns), raw))
        if len(self._batch) >= WRITE_BATCH:
            self.flush()

    def write_many(self, items):
        """
        Write (``conn`` from this writer, log time [ns] as an int, CDR bytes) items in order.

        ``write_raw`` for each, in one call (replay's stream writes a block at a time).
        """
        self._batch.extend(items)
        if len(self._batch) >= WRITE_BATCH:
            self.flush()

    def write(self, conn, log_ns, msg):
        """Serialise ``msg`` with rosbags' CDR (rclpy's may append junk bytes) and write it."""
        self.write_raw(conn, log_ns, self.store.serialize_cdr(msg, conn.msgtype))

    def flush(self):
        """Write the messages queued so far."""
        batch, self._batch = self._batch, []
        if not batch:
            return
        try:
            if self._batched:
                _mcap_write_batch(self._writer, batch, self._index)
            else:
                for conn, log_ns, raw in batch:
                    self._writer.write(conn, log_ns, raw)
        except (OverflowError, struct.error):
            # mcap stores log times as unsigned 64-bit ns since 1970: name the one that is not
            bad = next(((c, t) for c, t, _ in batch if not 0 <= t < 2 ** 64), None)
            if bad is None:
                raise
            raise BagError(f"{self.path}: cannot log a message on {bad[0].topic} at "
                           f"{bad[1]} ns: a bag's log time is 0 to 2^64 - 1 ns since "
                           "1970") from None

    def close(self):
        """Finish the bag (writes the last batch and metadata.yaml)."""
        writer = self._writer
        if writer is None:
            return
        try:
            self.flush()
            if self._batched and writer.storage.chunk.bio.tell():
                # the last chunk, as rosbags' close would close it, from our index
                _mcap_close_chunk(writer.storage, self._index)
        finally:
            self._writer = None
            if self._index:     # a failed flush: rosbags closes the chunk from its own index
                for cid, parts in self._index.items():
                    for stamps, offsets in parts:
                        writer.storage.chunk.msgs[cid].extend(zip(stamps.tolist(),
                                                                  offsets.tolist()))
                self._index.clear()
            writer.close()

    def __enter__(self):
        """Return self."""
        return self

    def __exit__(self, *exc):
        """Finish the bag."""
        self.close()


def write_events(path, events, topics=Topics(), storage="sqlite3", log_times_s=None):
    """
    Write events (any iterable) as a rosbag2 (storage 'sqlite3' or 'mcap').

    Log time = stamp unless ``log_times_s`` is given.  Serialised with rosbags' own CDR.
    """
    if storage not in STORAGES:
        raise ValueError(f"storage: must be 'sqlite3' or 'mcap', got {storage!r}")
    with BagWriter(path, storage=storage) as out:
        store = out.store
        conns = {kind: out.connection(topics.absolute(kind), msgtype)
                 for kind, msgtype in KIND_TYPES.items()}
        for i, ev in enumerate(events):
            if ev.kind == "nut_state":
                msg = store.types[JOINT_STATE](
                    header=_header(store, ev.stamp_s), name=list(ev.names),
                    position=np.asarray(ev.positions, float),
                    velocity=np.asarray(ev.velocities, float), effort=np.zeros(0))
            elif ev.kind == "axial_load":
                msg = _wrench(store, ev.stamp_s, force_z=ev.value)
            else:
                msg = _wrench(store, ev.stamp_s, torque_z=ev.value)
            log_t = ev.stamp_s if log_times_s is None else log_times_s[i]
            out.write(conns[ev.kind], int(round(log_t * 1e9)), msg)
