"""
A recording with measured and predicted torque, from a rosbag2 or a CSV file.

The prediction always comes from the replay path (``drive.run_samples``: the live node's
input checks and ``ModelRunner``), so the residual is what the node would show.

CSV input: a header row and one row per nut-state sample with the columns ``t_s, nut_angle_rad,
nut_velocity_rad_s, axial_load_n, torque_meas_nm`` (SI; other columns are ignored; an optional
``nut_accel_rad_s2`` overrides the acceleration the workflow derives). The file may start with
a UTF-8 byte-order mark. Its rows must be in time order; a file of several runs (the stamps
restart, as in a looped bag's ``prediction.csv``) is read as consecutive runs when each run has
at least ``MIN_RUN_ROWS`` rows, and a file whose time goes backwards more often (shuffled or
reversed rows) is refused. ``bb-friction replay``'s own ``prediction.csv`` qualifies when it
has ``torque_meas_nm``; its ``torque_pred_nm`` is then reused as the prediction (it came out of
the same model path), unless ``recompute`` is set. Rows with a non-finite measured torque are
kept for the model (continuity of the ball state) but not analysed.
"""

from array import array
import csv
import dataclasses
import math
from pathlib import Path
import sys
from typing import Optional

import numpy as np

from bb_friction_ros.alignment import measured_at
from bb_friction_ros.bags import BagInput, Event, Topics
from bb_friction_ros.config import BBFrictionError, bundled_config, ConfigError
from bb_friction_ros.empirical_terms import Inputs
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.drive import run_samples, samples_of_events, samples_of_rows
from bb_friction_ros.replay import nothing_accepted_message
from bb_friction_ros.runner import build_runner
from bb_friction_ros.schedule import run_starts

CSV_REQUIRED = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                "torque_meas_nm")
CSV_PREDICTION = "torque_pred_nm"
CSV_ACCELERATION = "nut_accel_rad_s2"
# replay's prediction.csv of a model with fitted terms: the terms' share of torque_pred_nm
CSV_EMPIRICAL = "torque_empirical_nm"
# most users log the motor current, not the torque; with --torque-constant-nm-per-a
# K the measured torque is K times it
CSV_CURRENT = "motor_current_a"
CURRENT_FLAG = "--torque-constant-nm-per-a"
CURRENT_TOPIC = "motor_current"
# How closely the --config's terms, evaluated on the CSV rows as the runner does, must
# reproduce its torque_empirical_nm: replay writes it with repr (exact), so only rounding
# of a re-saved file [N m] and a relative share of its RMS separate the two.
EMPIRICAL_MATCH_ABS_NM = 1e-6
EMPIRICAL_MATCH_REL = 1e-3
# Rows a run of a multi-run CSV needs: fewer between two backward steps of t_s is not a run
# but rows out of order (a shuffled or reversed file).
MIN_RUN_ROWS = 10


class InputProblem(BBFrictionError):
    """The input cannot be analysed at all (missing file, no measured torque, bad CSV)."""


@dataclasses.dataclass
class Recording:
    """Per-sample arrays (SI) of one recording, in log order."""

    t_s: np.ndarray                 # header stamps
    t_run_s: np.ndarray             # stamp - first stamp since the runner's last reset
    nut_angle_rad: np.ndarray
    nut_velocity_rad_s: np.ndarray
    axial_load_n: np.ndarray
    torque_meas_nm: np.ndarray      # NaN where there is no measurement
    torque_pred_nm: np.ndarray
    converged: np.ndarray           # bool
    info: dict = dataclasses.field(default_factory=dict)
    nut_accel_rad_s2: Optional[np.ndarray] = None    # None: derived by the workflow
    # the replay path's run that predicted every sample, its steps kept (FirstPass); None:
    # the prediction came from elsewhere (a CSV's column, no model), or not every sample
    first_pass: object = None

    def take(self, mask):
        """Return the sub-recording of the samples where ``mask`` is true (no FirstPass)."""
        arrays = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                  if f.name not in ("info", "first_pass")}
        arrays = {k: (None if v is None else v[mask]) for k, v in arrays.items()}
        return Recording(info=dict(self.info), **arrays)

    def __len__(self):
        """Return the number of samples."""
        return int(self.t_s.size)


@dataclasses.dataclass(frozen=True)
class FirstPass:
    """
    The replay path's run over every sample of a Recording: what it stepped, and at what.

    The physical trials take their step schedule and the base run from it instead of
    running the model over the recording again (``physical.trials.base_run``).
    """

    config_path: str
    schedule_args: tuple            # NodeParameters.schedule() of the run
    predictions: object             # drive.PredictionColumns, one row per sample


def run_times(stamps_s):
    """Return stamp - first stamp of its run; runs start where the runner resets (run_starts)."""
    stamps = np.asarray(stamps_s, dtype=float)
    if stamps.size == 0:
        return stamps.copy()
    start = run_starts(stamps)[0]
    first = stamps[np.maximum.accumulate(np.where(start, np.arange(stamps.size), 0))]
    return stamps - first


def inputs_of(rec, mask=None):
    """Return the empirical_terms.Inputs of a recording (or of the samples in ``mask``)."""
    sel = slice(None) if mask is None else mask
    accel = None if rec.nut_accel_rad_s2 is None else rec.nut_accel_rad_s2[sel]
    return Inputs.of(rec.t_run_s[sel], rec.nut_angle_rad[sel], rec.nut_velocity_rad_s[sel],
                     rec.axial_load_n[sel], accel)


def _progress(events, progress):
    if not progress:
        return events
    from tqdm import tqdm
    return tqdm(events, desc="replay", unit="msg", file=sys.stderr, mininterval=0.5)


def predict_samples(samples, config_path, replay_settings):
    """
    Run SampleColumns through the replay path; return (PredictionColumns, runner stats).

    Only the samples the model answered are kept (a model error is counted, as replay
    counts it, and leaves no row).
    """
    runner = build_runner(config_path, *replay_settings.schedule())
    preds = run_samples(runner, samples)
    return (preds if preds.answered.all() else preds.take(preds.answered)), runner.stats


def predict_events(events, config_path, replay_settings, progress=False):
    """
    Run events (any iterable, consumed once) through the replay path.

    Return (PredictionColumns of the answered samples, runner stats): the events are
    validated as the node validates them (``drive.samples_of_events``), then driven.
    """
    samples = samples_of_events(_progress(events, progress), replay_settings.nut_joint,
                                replay_settings.max_axial_load_n)
    return predict_samples(samples, config_path, replay_settings)


def _from_predictions(preds, measured_nm, info, base_terms=(), first_pass=None):
    t = preds.column("stamp_s")
    info["base_terms"] = list(base_terms)     # in the prediction already
    return Recording(t, run_times(t), preds.column("nut_angle_rad"),
                     preds.column("nut_velocity_rad_s"), preds.column("axial_load_n"),
                     np.asarray(measured_nm, dtype=float), preds.column("torque_total_nm"),
                     preds.converged, info, first_pass=first_pass)


def _first_pass(preds, samples, config_path, replay_settings):
    """Return the FirstPass of a run that answered every sample, else None."""
    if len(preds) != len(samples):
        return None
    return FirstPass(str(config_path), tuple(replay_settings.schedule()), preds)


def _split_measured(events, stamps, values):
    """Yield the input events; append the measured torque's stamps and values instead."""
    for e in events:
        if e.kind == "measured_torque":
            if math.isfinite(e.value):
                stamps.append(e.stamp_s)
                values.append(e.value)
        else:
            yield e


def load_bag(path, config_path, replay_settings=NodeParameters(), topics=Topics(),
             progress=False, baseline="model", current=None):
    """
    Read a rosbag2, predict through the replay path, align the measured torque.

    The bag is streamed: inputs go through the model as they are read, and predictions and
    measurements are kept as packed float columns only.  ``current`` (torque constant [N m/A],
    topic): the measurement is the motor current on that topic times the constant.
    """
    measured = None
    if current is not None:
        measured = read_current_topic(path, current[1], current[0])
    try:
        src = BagInput(path, topics)
    except (FileNotFoundError, ValueError) as exc:
        raise InputProblem(str(exc)) from exc
    with src:
        rec = _load_bag_input(src, path, config_path, replay_settings, topics, progress,
                              baseline, measured)
        # rows of an unknown topic, messages not read: said in summary.json's warnings
        rec.info["notes"] = rec.info.get("notes", []) + src.warnings(all_topics=False)
    if current is not None:
        rec.info["measured_torque_source"] = (f"topic {current[1]} (motor current) x "
                                              f"{current[0]:g} N m/A ({CURRENT_FLAG})")
    else:
        rec.info["measured_torque_source"] = f"topic {topics.measured_torque}"
    return rec


# Message types a motor-current topic may have: the value [A] is ``data``; they carry no
# header, so the sample's time is the bag's log time.
CURRENT_TYPES = ("std_msgs/msg/Float64", "std_msgs/msg/Float32")


def read_current_topic(path, topic, torque_constant_nm_per_a):
    """
    Return (stamps [s], torque [N m]) of a motor-current topic of a bag, scaled by K.

    The topic's type must be one of ``CURRENT_TYPES`` (the current in ``data``, A); the
    stamps are its log times (``current_on_header_clock`` puts them on the motion's clock).  A
    missing or empty topic is refused, naming it and the flag.
    """
    from rosbags.highlevel import AnyReader
    name = "/" + topic.lstrip("/")
    try:
        reader = AnyReader([Path(path)])
        reader.open()
    except Exception as exc:         # rosbags raises its own types for a damaged bag
        raise InputProblem(f"{path}: cannot read the bag ({exc})") from exc
    try:
        conns = [c for c in reader.connections if c.topic == name]
        if not conns or not sum(c.msgcount for c in conns):
            have = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
            raise InputProblem(f"{path}: no motor current: topic {name} is missing or empty "
                               f"(topics in the bag: {have}); {CURRENT_FLAG} reads the "
                               "current from --current-topic")
        bad = [c.msgtype for c in conns if c.msgtype not in CURRENT_TYPES]
        if bad:
            raise InputProblem(f"{path}: topic {name} has type {bad[0]}; a motor current "
                               f"topic must be {' or '.join(CURRENT_TYPES)} (the current in "
                               "data, A)")
        stamps, values = array("d"), array("d")
        for conn, t_ns, raw in reader.messages(connections=conns):
            v = float(reader.deserialize(raw, conn.msgtype).data)
            if math.isfinite(v):
                stamps.append(t_ns * 1e-9)
                values.append(torque_constant_nm_per_a * v)
    finally:
        reader.close()
    return stamps, values


def _load_bag_input(src, path, config_path, replay_settings, topics, progress, baseline,
                    current=None):
    counts = src.counts                  # messages actually read, filled as the bag streams
    clock = (array("d"), array("d"))     # the nut states' (log time, header stamp) [s]

    def stream():
        for _, log_ns, _, ev in src.messages(all_topics=False):
            if ev is not None and ev.kind == "nut_state":
                clock[0].append(log_ns * 1e-9)
                clock[1].append(ev.stamp_s)
            yield ev
    events = stream()

    def no_measurement():
        return InputProblem(f"{path}: no measured torque: topic {topics.measured_torque!r} "
                            f"is missing or empty (topics in the bag: {src.describe()}); the "
                            "discrepancy needs a measurement to compare with "
                            "(--measured-topic)")
    measured = [c.msgcount for c in src.connections
                if c.topic.lstrip("/") == topics.measured_torque.lstrip("/")]
    if current is None and not any(measured):
        raise no_measurement()        # before running the model over the whole bag
    if current is None:
        meas_t, meas_v = array("d"), array("d")
        inputs = _split_measured(events, meas_t, meas_v)
    else:                             # the motor current x K, not the torque topic
        inputs = _split_measured(events, array("d"), array("d"))
        meas_t, meas_v = None, current[1]
    samples = samples_of_events(_progress(inputs, progress), replay_settings.nut_joint,
                                replay_settings.max_axial_load_n)
    if baseline == "zero":
        # no model of this screw: the samples themselves, the prediction 0 N m
        cols = (samples.stamp_s, samples.nut_angle_rad, samples.nut_velocity_rad_s,
                samples.axial_load_n)
        rejected = samples.rejected
        info = {"input": str(path), "format": "rosbag2", "baseline": "zero",
                "prediction_source": "none (--baseline zero: no model of this screw)",
                "messages": dict(counts), "rejected": dict(rejected)}
        base = ()
    else:
        preds, stats = predict_samples(samples, config_path, replay_settings)
        first = _first_pass(preds, samples, config_path, replay_settings)
        cols = (preds.stamp_s, preds.nut_angle_rad, preds.nut_velocity_rad_s,
                preds.axial_load_n)
        rejected = stats.rejected
        info = {"input": str(path), "format": "rosbag2",
                "prediction_source": "model (replay path)", "messages": dict(counts),
                "rejected": dict(rejected), "nonconverged_steps": stats.nonconverged_steps,
                "resets": stats.resets}
        base = load_model_file(config_path)[1].names
    time_base = None
    if current is not None:           # the current at its log time, on the stamps' clock
        meas_t, time_base = current_on_header_clock(current[0], clock[0], clock[1], path)
    if not len(meas_t):
        raise no_measurement()
    if not len(cols[0]):  # the reasons, what the bag holds and the fix, as replay says them
        raise InputProblem(nothing_accepted_message(src, rejected, replay_settings))
    meas = measured_at(meas_t, meas_v, cols[0])      # aligned as replay aligns it
    if time_base is not None:
        info["current_time_base"] = time_base
    if baseline == "zero":
        n = len(cols[0])
        info["base_terms"] = []
        return Recording(cols[0], run_times(cols[0]), *cols[1:], np.asarray(meas, float),
                         np.zeros(n), np.ones(n, dtype=bool), info)
    return _from_predictions(preds, meas, info, base, first)


# Nut states over which the offset between their log times and header stamps is smoothed (a
# running median): the recorder's latency jitters message by message, the offset between the
# two clocks (a device clock, the recorder's latency) changes slowly.
CLOCK_OFFSET_WINDOW = 51


def current_on_header_clock(current_log_s, state_log_s, state_stamp_s, path):
    """
    Return (the current's times on the nut states' header clock [s], a summary of the offset).

    A motor current without a header has only its log time; the motion is placed at its header
    stamps.  Both topics went through the same recorder, so the nut states' own (log time,
    header stamp) pairs give the offset between the two clocks at each log time: the
    current's log time plus that offset (smoothed, ``CLOCK_OFFSET_WINDOW``; held at the
    ends) is its time on the header clock.  Without it a recorder latency of 10 ms moved the
    current 10 ms against the motion and named the wrong effects.  Refused when the current's
    log times do not overlap the nut states' at all, naming both spans.
    """
    from scipy.ndimage import median_filter
    cur = np.asarray(current_log_s, dtype=float)
    log = np.asarray(state_log_s, dtype=float)
    stamp = np.asarray(state_stamp_s, dtype=float)
    if not cur.size or not log.size:
        return cur, None
    if cur[-1] < log[0] or cur[0] > log[-1]:
        raise InputProblem(
            f"{path}: the motor current and the nut states do not overlap in log time (current "
            f"{cur[0]:.6f}-{cur[-1]:.6f} s, nut_state {log[0]:.6f}-{log[-1]:.6f} s): they were "
            "not recorded together")
    offset = median_filter(stamp - log, size=min(CLOCK_OFFSET_WINDOW, log.size),
                           mode="nearest")
    mapped = cur + np.interp(cur, log, offset)
    summary = {"method": "log time + the nut states' (header stamp - log time), running "
                         f"median of {CLOCK_OFFSET_WINDOW}, interpolated",
               "offset_median_s": float(np.median(offset)),
               "offset_range_s": [float(offset.min()), float(offset.max())]}
    return mapped, summary


def _csv_header(path):
    """Return the header names of a CSV (empty when unreadable: the reader says why)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            return next(csv.reader(fh), [])
    except (OSError, UnicodeDecodeError):
        return []


def measurement_columns(path, torque_constant_nm_per_a):
    """
    Return the required columns of a CSV: its torque, or its motor current.

    ``motor_current_a`` needs ``--torque-constant-nm-per-a``; a constant without the column,
    or a current without the constant, is refused, naming the flag or the column.
    """
    header = _csv_header(path)
    base = CSV_REQUIRED[:-1]
    if torque_constant_nm_per_a is None:
        if CSV_CURRENT in header and "torque_meas_nm" not in header:
            raise InputProblem(f"{path}: has {CSV_CURRENT} but no torque_meas_nm: a motor "
                               f"current needs the motor's torque constant, "
                               f"{CURRENT_FLAG} K [N m/A] (the measured torque is K x "
                               "current)")
        return CSV_REQUIRED
    if header and CSV_CURRENT not in header:
        raise InputProblem(f"{path}: {CURRENT_FLAG} was given but the CSV has no "
                           f"{CSV_CURRENT} column (has: {', '.join(header)})")
    return base + (CSV_CURRENT,)


def _read_csv_columns(path, required=CSV_REQUIRED):
    try:
        # utf-8-sig: a spreadsheet's byte-order mark would otherwise glue itself to "t_s"
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise InputProblem(f"{path}: cannot read ({exc.strerror})") from exc
    with fh:
        reader = csv.DictReader(fh)
        try:
            header = reader.fieldnames or []
        except UnicodeDecodeError as exc:
            raise InputProblem(f"{path}: not a UTF-8 text CSV ({exc.reason})") from None
        missing = [c for c in required if c not in header]
        if missing:
            raise InputProblem(f"{path}: CSV lacks column(s) {', '.join(missing)} (needs "
                               f"{', '.join(required)}; optional {CSV_PREDICTION}, "
                               f"{CSV_ACCELERATION}); has: {', '.join(header) or 'no header'}")
        wanted = list(required) + [c for c in (CSV_PREDICTION, CSV_ACCELERATION,
                                               CSV_EMPIRICAL)
                                   if c in header and c not in required]
        cols = {c: [] for c in wanted}
        try:
            for line, row in enumerate(reader, start=2):
                for c in wanted:
                    try:
                        cols[c].append(float(row[c]))
                    except (TypeError, ValueError):
                        raise InputProblem(f"{path}: line {line}, column {c}: not a number "
                                           f"({row[c]!r})") from None
        except UnicodeDecodeError as exc:
            raise InputProblem(f"{path}: not a UTF-8 text CSV ({exc.reason})") from None
    return {c: np.array(v, dtype=float) for c, v in cols.items()}


def check_time_order(path, t_s):
    """
    Refuse rows out of time order; return the number of runs (restarts of t_s).

    A restart of the stamps begins a new run (the runner resets there, as for a looped
    bag).  Runs shorter than MIN_RUN_ROWS rows mean the rows are shuffled or reversed: the
    file is refused, naming the first backward line, rather than analysed as thousands of
    tiny runs with a wrong verdict.
    """
    back = np.flatnonzero(run_starts(t_s)[0][1:]) + 1     # restarts, not late rows
    starts = np.concatenate(([0], back, [t_s.size]))
    lengths = np.diff(starts)
    if back.size and lengths.min() < MIN_RUN_ROWS:
        i = int(back[0])
        raise InputProblem(
            f"{path}: rows are not in time order: line {i + 2} has t_s = {t_s[i]:.9g} after "
            f"{t_s[i - 1]:.9g} ({back.size} backward step(s), shortest run {lengths.min()} "
            f"row(s)); sort the file by t_s, or give each run of a multi-run file at least "
            f"{MIN_RUN_ROWS} rows")
    return int(back.size) + 1


def check_time_advances(path, t_s):
    """
    Refuse a file whose ``t_s`` never advances.

    Every row at one time has no sample period: no acceleration, no time regimes and no
    thermal time scale can be derived (it crashed in the thermal grid before).
    """
    if t_s.size > 1 and not np.ptp(t_s) > 0.0:
        raise InputProblem(f"{path}: column t_s never advances (all {t_s.size} rows at "
                           f"t_s = {t_s[0]:.9g}); the workflow needs the sample times in "
                           "seconds (a logger that leaves the stamp at 0 must be given one)")


def check_reused_terms(path, cols, config_path):
    """
    Refuse a reused prediction that carries terms the ``--config`` does not.

    Replay's ``prediction.csv`` of an augmented model has ``torque_empirical_nm``: its
    ``torque_pred_nm`` includes those terms.  ``augmented.yaml`` is written on ``--config``,
    so a config without the same terms lost them (a later replay was 11x worse than
    reported).  The config's terms are evaluated on the rows as the runner does (causal
    filter, reset where the stamps go backwards) and must reproduce the column.  Return the
    config's term names (in the prediction already).
    """
    terms = load_model_file(config_path)[1]
    emp = cols.get(CSV_EMPIRICAL)
    if emp is None or not np.any(emp != 0.0):
        return terms.names
    if not len(terms):
        raise InputProblem(
            f"{path}: its {CSV_PREDICTION} includes fitted empirical terms (column "
            f"{CSV_EMPIRICAL} is not zero), but --config {config_path} has none: pass the "
            "--config that replay used (e.g. DIR/augmented.yaml), or --recompute-prediction")
    live = terms.live()
    t = cols["t_s"]
    t_run = run_times(t)
    starts, late = run_starts(t)
    mine = np.empty(t.size)
    for i in range(t.size):
        if late[i]:         # the runner answers a late row with the last row's terms
            mine[i] = mine[i - 1]
            continue
        if i and starts[i]:
            live.reset()
        mine[i] = live.torque_nm(t[i], t_run[i], cols["nut_angle_rad"][i],
                                 cols["nut_velocity_rad_s"][i], cols["axial_load_n"][i])
    worst = float(np.max(np.abs(mine - emp)))
    if worst > EMPIRICAL_MATCH_ABS_NM + EMPIRICAL_MATCH_REL * float(np.sqrt(np.mean(emp ** 2))):
        raise InputProblem(
            f"{path}: its {CSV_EMPIRICAL} is not what the terms of --config {config_path} "
            f"give on its rows (up to {worst:.3g} N m apart): the prediction was made with "
            "another model file; pass the --config that replay used, or "
            "--recompute-prediction")
    return terms.names


def csv_events(cols, nut_joint):
    """Yield the events a CSV stands for: each row's axial load, then its nut state."""
    for t, a, w, f in zip(cols["t_s"], cols["nut_angle_rad"], cols["nut_velocity_rad_s"],
                          cols["axial_load_n"]):
        yield Event("axial_load", float(t), value=float(f))
        yield Event("nut_state", float(t), (nut_joint,), (float(a),), (float(w),))


def load_csv(path, config_path, replay_settings=NodeParameters(), recompute=False,
             progress=False, baseline="model", torque_constant_nm_per_a=None):
    """Read a CSV recording; reuse its ``torque_pred_nm`` unless ``recompute`` (see module)."""
    cols = _read_csv_columns(path, measurement_columns(path, torque_constant_nm_per_a))
    if cols["t_s"].size == 0:
        raise InputProblem(f"{path}: CSV has no data rows")
    measured_from = "csv column torque_meas_nm"
    if torque_constant_nm_per_a is not None:
        cols["torque_meas_nm"] = torque_constant_nm_per_a * cols[CSV_CURRENT]
        measured_from = (f"csv column {CSV_CURRENT} x {torque_constant_nm_per_a:g} N m/A "
                         f"({CURRENT_FLAG})")
    for c in ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", CSV_ACCELERATION):
        if c in cols and not np.all(np.isfinite(cols[c])):
            line = int(np.flatnonzero(~np.isfinite(cols[c]))[0]) + 2
            raise InputProblem(f"{path}: column {c} has non-finite values (first at line "
                               f"{line})")
    runs = check_time_order(path, cols["t_s"])
    check_time_advances(path, cols["t_s"])
    accel = cols.get(CSV_ACCELERATION)
    header = _csv_header(path)
    notes = []
    if CSV_CURRENT in header and "torque_meas_nm" in header:
        notes.append(f"{path} has both torque_meas_nm and {CSV_CURRENT}: "
                     + (f"{CURRENT_FLAG} reads {CSV_CURRENT}; torque_meas_nm was ignored"
                        if torque_constant_nm_per_a is not None else
                        f"torque_meas_nm was used; {CSV_CURRENT} was ignored (it needs "
                        f"{CURRENT_FLAG})"))
    info = {"input": str(path), "format": "csv", "runs": runs, "notes": notes,
            "measured_torque_source": measured_from,
            "acceleration_source": f"csv column {CSV_ACCELERATION}" if accel is not None
            else "derived (zero-phase filter)"}
    t_run = run_times(cols["t_s"])
    if baseline == "zero" or (CSV_PREDICTION in cols and not recompute):
        if baseline == "zero":
            pred = np.zeros(cols["t_s"].size)
            info.update(prediction_source="none (--baseline zero: no model of this screw)",
                        baseline="zero", base_terms=[])
        else:
            pred = cols[CSV_PREDICTION]
            base = check_reused_terms(path, cols, config_path)
            info.update(prediction_source=f"csv column {CSV_PREDICTION} (reused)",
                        base_terms=list(base))
            if np.all(pred == 0.0):
                info["baseline"] = "zero"
        return Recording(cols["t_s"], t_run, cols["nut_angle_rad"],
                         cols["nut_velocity_rad_s"], cols["axial_load_n"],
                         cols["torque_meas_nm"], pred,
                         np.ones(cols["t_s"].size, dtype=bool), info, accel)
    samples = samples_of_rows(cols["t_s"], cols["nut_angle_rad"], cols["nut_velocity_rad_s"],
                              cols["axial_load_n"], replay_settings.max_axial_load_n)
    preds, stats = predict_samples(samples, config_path, replay_settings)
    if len(preds) != cols["t_s"].size:
        raise InputProblem(f"{path}: {cols['t_s'].size - len(preds)} row(s) rejected by the "
                           f"model input checks: {dict(stats.rejected)}")
    info.update(prediction_source="model (replay path, recomputed from the CSV inputs)",
                rejected=dict(stats.rejected), nonconverged_steps=stats.nonconverged_steps,
                resets=stats.resets)
    rec = _from_predictions(preds, cols["torque_meas_nm"], info,
                            load_model_file(config_path)[1].names,
                            _first_pass(preds, samples, config_path, replay_settings))
    rec.nut_accel_rad_s2 = accel
    return rec


def load_recording(path, config_path=None, replay_settings=NodeParameters(), topics=Topics(),
                   recompute=False, progress=False, baseline="model",
                   torque_constant_nm_per_a=None, current_topic=CURRENT_TOPIC):
    """
    Load a rosbag2 directory or a ``.csv`` file (see module docstring).

    ``torque_constant_nm_per_a``: the measured torque is this times the motor current (the
    CSV column ``motor_current_a``, or the bag topic ``current_topic``).
    """
    path = Path(path)
    config_path = config_path or bundled_config("ball_screw.yaml")
    if not Path(config_path).is_file():
        raise ConfigError(f"{config_path}: no such config file")
    if torque_constant_nm_per_a is not None and not (math.isfinite(torque_constant_nm_per_a)
                                                     and torque_constant_nm_per_a > 0):
        raise InputProblem(f"{CURRENT_FLAG}: must be a finite torque constant > 0 N m/A, got "
                           f"{torque_constant_nm_per_a!r}")
    if path.is_dir():
        current = None
        if torque_constant_nm_per_a is not None:
            current = (torque_constant_nm_per_a, current_topic)
        return load_bag(path, config_path, replay_settings, topics, progress, baseline,
                        current)
    if path.is_file() and path.suffix.lower() == ".csv":
        return load_csv(path, config_path, replay_settings, recompute, progress, baseline,
                        torque_constant_nm_per_a)
    if not path.exists():
        raise InputProblem(f"{path}: no such bag or CSV file")
    raise InputProblem(f"{path}: neither a rosbag2 directory nor a .csv file")
