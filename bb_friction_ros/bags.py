"""
rosbag2 recordings (sqlite3 and mcap) read and written with ``rosbags``, without ROS.

Messages are yielded in log order, the order ``ros2 bag play`` publishes them, so a replay
sees what the live node would: including header stamps that jump backwards.

``BagInput`` streams a bag: the topics the node subscribes to are resolved and type-checked
before the first message is read, every message is counted as it is read, and a damaged bag
is a ``BagError`` naming the file, never a traceback from the storage library.

rosbags is imported on first use: it costs about 0.5 s, and every ``bb-friction`` command
builds its parser from this module's ``Topics``.
"""

import bisect
from collections import Counter, deque
from dataclasses import dataclass, field
import importlib.util
import math
from pathlib import Path
import struct

import numpy as np
import yaml

from bb_friction_ros import interface
from bb_friction_ros.config import BBFrictionError
from bb_friction_ros.interface import JOINT_STATE, MSGS_PACKAGE, WRENCH_STAMPED

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

    @staticmethod
    def add_arguments(parser):
        """Add the flags naming a recording's topics (replay, discrepancy) to ``parser``."""
        parser.add_argument("--nut-state-topic", default=interface.NUT_STATE,
                            help="nut state topic (sensor_msgs/JointState); a bag recorded "
                            "under a namespace needs its full name, e.g. /robot/nut_state")
        parser.add_argument("--axial-load-topic", default=interface.AXIAL_LOAD,
                            help="axial load topic (geometry_msgs/WrenchStamped force.z), "
                            "e.g. /robot/axial_load")
        parser.add_argument("--measured-topic", default=interface.MEASURED_TORQUE,
                            help="measured torque topic (geometry_msgs/WrenchStamped "
                            "torque.z)")

    @classmethod
    def from_args(cls, args):
        """Return the Topics named by ``add_arguments``' flags."""
        return cls(nut_state=args.nut_state_topic, axial_load=args.axial_load_topic,
                   measured_torque=args.measured_topic)

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


# A stamp that goes back by at most LATE_STAMP_TOLERANCE_S is a late sample (jitter, a
# delayed driver thread) if its stream is past its old newest stamp again within
# LATE_SAMPLES_MAX more samples; late samples are aligned by their stamps in the same run.
# If the stream carries on below for longer, or goes back by more, it restarted (a looping
# bag, a restarted source) and a new run begins; unless the newest stamp had jumped ahead
# by more than the tolerance and the stream carries on past its stamp before that jump: that
# one stamp was far ahead (a driver's glitch) and the run goes on.  Late samples seen in
# practice are one sample a few ms late (10.5 ms in a measured recording); a restart goes
# on below its old newest stamp for the length of a recording.
LATE_STAMP_TOLERANCE_S = 0.1
LATE_SAMPLES_MAX = 3
# Most predictions held waiting for their measurement, and most measured samples held for
# predictions not yet seen, while streaming (replay): about 20 s at 1 kHz, ~20 MB of rows.
# Beyond it the oldest is released unmatched (NaN), counted, and warned about: a stream that
# never catches up cannot grow memory without bound (it reached 497 MB on 4 minutes).
MAX_HELD = 20000


class _Runs:
    """
    Cut one stream's stamps into runs, telling late samples from restarts (see above).

    ``add`` returns the items whose run became known, as (run, item) in arrival order:
    a sample below the newest stamp is held as a suspect until the stream decides.
    """

    def __init__(self, tolerance_s, late_max):
        self.tolerance_s, self.late_max = tolerance_s, late_max
        self.run, self.newest = 0, None
        self.jump_from = None       # the newest stamp before a jump ahead > tolerance
        self.suspects = []          # (stamp, item) held since the stream went back
        self.late = 0               # samples found late, aligned in their run
        self.ahead = 0              # single stamps found far ahead of their stream
        self.outliers = []          # their items, for the owner to take back
        self.newest_item = None
        self.started = False

    def add(self, stamp, item):
        self.started = True
        if self.newest is None or (stamp >= self.newest and not self.suspects):
            if self.newest is not None:
                self.jump_from = self.newest if stamp > self.newest + self.tolerance_s \
                    else None
            self.newest, self.newest_item = stamp, item
            return [(self.run, item)]
        if stamp > self.newest:                   # back past the old newest: they were late
            out = self.settle()
            self.newest, self.newest_item, self.jump_from = stamp, item, None
            return out + [(self.run, item)]
        if stamp < self.newest - self.tolerance_s:
            out = self.settle()
            if self.jump_from is not None and stamp > self.jump_from:
                self.ahead += 1                   # the stream carries on from before a jump
                self.outliers.append(self.newest_item)
            else:
                self.run += 1                     # a restart
            self.newest, self.newest_item, self.jump_from = stamp, item, None
            return out + [(self.run, item)]
        self.suspects.append((stamp, item))
        if len(self.suspects) <= self.late_max:
            return []
        self.run += 1                             # carries on below: a restart after all
        out = [(self.run, it) for _, it in self.suspects]
        self.newest, self.newest_item = max(self.suspects, key=lambda s: s[0])
        self.suspects, self.jump_from = [], None
        return out

    def settle(self):
        """Decide the held suspects as late samples of the current run."""
        out = [(self.run, item) for _, item in self.suspects]
        self.late += len(self.suspects)
        self.suspects = []
        return out

    @property
    def count(self):
        """Return the number of runs begun so far (0 before any sample)."""
        return self.run + 1 if self.started else 0


class _MeasuredRun:
    """One run of measured samples, sorted by stamp, trimmed from the front (``head``)."""

    __slots__ = ("run", "stamps", "values", "head")

    def __init__(self, run):
        self.run = run
        self.stamps, self.values, self.head = [], [], 0

    def __len__(self):
        return len(self.stamps) - self.head

    def add(self, stamp, value):
        if self.stamps and stamp < self.stamps[-1]:       # late: keep the run sorted
            i = bisect.bisect_right(self.stamps, stamp, lo=self.head)
            self.stamps.insert(i, stamp)
            self.values.insert(i, value)
        else:
            self.stamps.append(stamp)
            self.values.append(value)

    def at(self, t, unconfirmed=None):
        """
        Return (value, known): interpolated at ``t``; known=False if no upper bracket yet.

        ``unconfirmed``: the stamp of a newest sample that jumped far ahead and may yet prove
        an outlier; it is no upper bracket until then.
        """
        st = self.stamps
        i = bisect.bisect_right(st, t, lo=self.head)     # first sample after t
        if i > self.head and st[i - 1] == t:
            return self.values[i - 1], True
        if i == self.head:
            return math.nan, i < len(st)                  # before the run's first sample
        if i == len(st) or st[i] == unconfirmed:
            return math.nan, False                        # after the last one (so far)
        t0, t1, v0, v1 = st[i - 1], st[i], self.values[i - 1], self.values[i]
        return v0 + (v1 - v0) * (t - t0) / (t1 - t0), True

    def remove(self, stamp):
        """Remove one sample at ``stamp``; return whether there was one."""
        i = bisect.bisect_left(self.stamps, stamp, lo=self.head)
        if i < len(self.stamps) and self.stamps[i] == stamp:
            del self.stamps[i], self.values[i]
            return True
        return False

    def trim_before(self, t):
        """Drop samples no query at or after ``t`` needs (keep the lower bracket of t)."""
        i = bisect.bisect_right(self.stamps, t, lo=self.head) - 1
        self.drop(i - self.head)

    def drop(self, n):
        """Drop the ``n`` oldest samples."""
        if n > 0:
            self.head += n
            if self.head > 4096 and self.head * 2 > len(self.stamps):
                del self.stamps[:self.head], self.values[:self.head]
                self.head = 0


class MeasuredAligner:
    """
    Measured torque at prediction stamps, run by run, as a stream.

    A recording that loops (``ros2 bag play --loop``, or a source restarted) repeats its
    stamps.  Aligning by stamp alone would give every pass the last pass's measurement, so
    both streams are cut into runs where their stamps restart, and the k-th run of
    predictions is aligned with the k-th run of measurements: linear interpolation between
    the measured samples that bracket the stamp, NaN outside the run's measured span.  A
    late sample (a stamp a little behind, after which the stream carries on past its newest,
    see ``LATE_STAMP_TOLERANCE_S``) is aligned by its stamp in the same run: one late
    ``nut_state`` stamp no longer cuts the prediction stream alone (it used to leave
    4500 of 6000 rows of a recording without their measurement).

    Feed both streams in any interleaving; ``add_*`` and ``finish`` return the
    ``(payload, measured_nm)`` pairs that became known, in prediction order.  Only the lag
    between the two streams is held in memory, at most ``max_held`` predictions and as many
    measured samples (None: no bound, for arrays already in memory); beyond it the oldest
    is released unmatched (NaN) and counted.  ``warnings()`` says when the streams' runs
    differ or data went unmatched.
    """

    def __init__(self, late_stamp_tolerance_s=LATE_STAMP_TOLERANCE_S,
                 late_samples_max=LATE_SAMPLES_MAX, max_held=MAX_HELD):
        """Start with no samples."""
        if not late_stamp_tolerance_s >= 0.0:
            raise ValueError(f"late_stamp_tolerance_s must be >= 0, got "
                             f"{late_stamp_tolerance_s}")
        self.tolerance_s = float(late_stamp_tolerance_s)
        self.max_held = max_held
        self._m_runs = _Runs(self.tolerance_s, late_samples_max)
        self._p_runs = _Runs(self.tolerance_s, late_samples_max)
        self._meas = deque()     # _MeasuredRun, oldest first
        self._preds = deque()    # [run or None while undecided, stamp, payload]
        self._p_max = None       # newest prediction stamp of the latest decided run
        self._p_run_decided = 0
        self._done = False
        self.samples = 0         # finite measured samples taken
        self.unmatched_predictions = 0    # released as NaN because max_held was reached
        self.unmatched_measured = 0       # dropped because max_held was reached

    @property
    def runs(self):
        """Return the runs seen so far: {"prediction": n, "measured": n}."""
        return {"prediction": self._p_runs.count, "measured": self._m_runs.count}

    @property
    def late(self):
        """Late samples aligned in their run: {"prediction": n, "measured": n}."""
        return {"prediction": self._p_runs.late, "measured": self._m_runs.late}

    @property
    def ahead(self):
        """Single stamps far ahead of their stream: {"prediction": n, "measured": n}."""
        return {"prediction": self._p_runs.ahead, "measured": self._m_runs.ahead}

    def add_measured(self, stamp_s, value_nm):
        """Take one measured sample (non-finite values are skipped)."""
        if not (math.isfinite(stamp_s) and math.isfinite(value_nm)):
            return self._drain()
        self.samples += 1
        self._take_measured(self._m_runs.add(stamp_s, (stamp_s, value_nm)))
        while self._m_runs.outliers:          # a stamp far ahead: it brackets nothing
            stamp, _ = self._m_runs.outliers.pop()
            for m in reversed(self._meas):
                if m.remove(stamp):
                    break
        return self._drain()

    def _take_measured(self, decided):
        for run, (stamp, value) in decided:
            if not self._meas or self._meas[-1].run != run:
                self._meas.append(_MeasuredRun(run))
            self._meas[-1].add(stamp, value)
        if self.max_held is not None:
            held = sum(map(len, self._meas))
            while held > self.max_held:
                oldest = self._meas[0]
                if len(oldest) <= 1 and len(self._meas) > 1:
                    self.unmatched_measured += len(oldest)
                    held -= len(oldest)
                    self._meas.popleft()
                    continue
                oldest.drop(1)
                self.unmatched_measured += 1
                held -= 1

    def add_prediction(self, stamp_s, payload):
        """Take one prediction stamp with the payload to return with its measurement."""
        entry = [None, stamp_s, payload]
        self._preds.append(entry)
        self._decide(self._p_runs.add(stamp_s, entry))
        while self._p_runs.outliers:          # a stamp far ahead: no measurement, at once
            self._p_runs.outliers.pop()[0] = "ahead"
        return self._drain()

    def _decide(self, decided):
        """Set the runs of predictions now decided; track the newest stamp of the last run."""
        for run, entry in decided:
            entry[0] = run
            if self._p_max is None or run > self._p_run_decided:
                self._p_run_decided, self._p_max = run, entry[1]
            elif run == self._p_run_decided and entry[1] > self._p_max:
                self._p_max = entry[1]

    def finish(self):
        """No more measured samples: resolve everything still waiting."""
        self._take_measured(self._m_runs.settle())
        self._decide(self._p_runs.settle())
        self._done = True
        return self._drain()

    def warnings(self):
        """Return sentences on what did not align: differing runs, unmatched data."""
        out = []
        runs = self.runs
        if self.samples and runs["prediction"] != runs["measured"]:
            out.append(f"the prediction stream has {runs['prediction']} run(s) and the "
                       f"measured torque {runs['measured']} (a run starts where the stamps "
                       "restart): the k-th runs were compared; rows of a run without a "
                       "counterpart have no measurement")
        if self.unmatched_predictions or self.unmatched_measured:
            out.append(f"{self.unmatched_predictions} prediction(s) and "
                       f"{self.unmatched_measured} measured sample(s) waited for the other "
                       f"stream beyond {self.max_held} held and were left unmatched")
        return out

    def _drain(self):
        out = []
        meas = self._meas
        while self._preds:
            run, t, payload = self._preds[0]
            over_limit = self.max_held is not None and len(self._preds) > self.max_held
            if run == "ahead":                        # far ahead of its stream: unmatched
                value, over_limit = math.nan, False
            elif run is None:                         # late or a restart: not known yet
                if not over_limit:
                    break
                value = math.nan
            else:
                while meas and meas[0].run < run:
                    meas.popleft()
                current = meas[0] if meas and meas[0].run == run else None
                run_over = self._done or self._m_runs.run > run
                jump = self._m_runs
                unconfirmed = jump.newest if (jump.jump_from is not None and not run_over
                                              and jump.run == run) else None
                value, known = current.at(t, unconfirmed) if current is not None \
                    else (math.nan, False)
                if not known and not run_over:
                    if not over_limit:
                        break                         # wait for the upper bracket
                    value = math.nan
                else:
                    over_limit = False
            if over_limit:
                self.unmatched_predictions += 1       # never held without bound
            self._preds.popleft()
            out.append((payload, value))
        # What later queries of this run can ask: a waiting prediction arrived when the newest
        # stamp was at least the head's, so it is no earlier than the head's stamp minus the
        # tolerance (else it started a new run); without one, a new prediction is no earlier
        # than the newest minus the tolerance.
        # The measured stream's own last tolerance is kept too: the waiting head may be a
        # stamp far ahead, found out only at the next prediction.
        if meas and self._preds and self._preds[0][0] == meas[0].run:
            floor = self._preds[0][1]
            if self._m_runs.newest is not None and self._m_runs.run == meas[0].run:
                floor = min(floor, self._m_runs.newest)
            meas[0].trim_before(floor - self.tolerance_s)
        elif meas and not self._preds and self._p_max is not None \
                and meas[0].run == self._p_run_decided:
            meas[0].trim_before(self._p_max - self.tolerance_s)
        return out


def measured_torque_at(events, stamps_s):
    """
    Return the measured torque at ``stamps_s`` [N m] run by run, or None if none recorded.

    ``stamps_s`` are prediction stamps in processing order; see ``MeasuredAligner`` for how
    a looping recording is aligned pass by pass.  Replay and the discrepancy workflow both
    align the measurement with it, so they agree.
    """
    aligner = MeasuredAligner(max_held=None)     # the arrays are in memory already
    for e in events:
        if e.kind == "measured_torque":
            aligner.add_measured(e.stamp_s, e.value)
    if aligner.samples == 0:
        return None
    # each prediction gets exactly one (index, value), filled in as the aligner releases it:
    # a list of 600,000 (index, value) tuples first peaked ~85 MB above the array
    stamps = np.asarray(stamps_s, dtype=float)
    values = np.full(stamps.size, np.nan)
    for k, t in enumerate(stamps):
        for j, v in aligner.add_prediction(float(t), k):
            values[j] = v
    for j, v in aligner.finish():
        values[j] = v
    return values


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
        it = self._reader.messages(connections=conns)
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
        self.counts.update(conn.topic for conn, _, _ in items)
        block = Block(self, items, before)
        rows = {}
        for i, (conn, _, raw) in enumerate(items):
            kind = self.resolved.get(conn.topic)
            block.kinds.append(kind)
            if kind is not None:
                rows.setdefault((kind, len(raw)), []).append(i)
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


def _why(exc):
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


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
                                              "message_end_time", "close_chunk")) \
        and all(hasattr(writer, a) for a in ("counts", "min_timestamp", "max_timestamp"))


def _mcap_write_batch(writer, batch):
    """
    Write ``batch``, a list of (connection, log time [ns], CDR bytes), in order.

    Exactly what ``writer.write`` does for each, in one ``write`` per chunk: the same
    records, message indexes, chunk boundaries, statistics and metadata counts.  The
    records' fixed fields are packed with numpy (a struct.pack per message cost ~1 us).
    """
    storage = writer.storage
    n = len(batch)
    ids = np.fromiter((item[0].id for item in batch), dtype=np.int64, count=n)
    stamps = np.fromiter((item[1] for item in batch), dtype=np.uint64, count=n)
    datas = [item[2] for item in batch]
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
        parts[0::2] = [heads[k * width:(k + 1) * width] for k in range(i, j)]
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
            chunk.msgs[cid].extend(zip(stamps[i:j][mine].tolist(),
                                       offsets[mine].tolist()))
            storage.channel_stats[cid] += count
            writer.counts[cid] += count
        if len(over):
            storage.close_chunk()
        i = j


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
                _mcap_write_batch(self._writer, batch)
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
        finally:
            self._writer = None
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
