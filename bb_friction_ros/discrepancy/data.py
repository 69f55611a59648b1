"""
A recording with measured and predicted torque, from a rosbag2 or a CSV file.

The prediction always comes from the replay path (``replay.run_events``: the live node's
``InputAssembler`` and ``ModelRunner``), so the residual is what the node would show.

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

import csv
import dataclasses
from pathlib import Path
from typing import Optional

import numpy as np

from bb_friction_ros.bags import Event, measured_torque_at, read_events, Topics
from bb_friction_ros.config import bundled_config, ConfigError
from bb_friction_ros.empirical_terms import Inputs
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay import run_events
from bb_friction_ros.runner import build_runner, InputAssembler

CSV_REQUIRED = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                "torque_meas_nm")
CSV_PREDICTION = "torque_pred_nm"
CSV_ACCELERATION = "nut_accel_rad_s2"
# Rows a run of a multi-run CSV needs: fewer between two backward steps of t_s is not a run
# but rows out of order (a shuffled or reversed file).
MIN_RUN_ROWS = 10


class InputProblem(ValueError):
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

    def take(self, mask):
        """Return the sub-recording of the samples where ``mask`` is true."""
        arrays = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                  if f.name != "info"}
        arrays = {k: (None if v is None else v[mask]) for k, v in arrays.items()}
        return Recording(info=dict(self.info), **arrays)

    def __len__(self):
        """Return the number of samples."""
        return int(self.t_s.size)


def run_times(stamps_s):
    """Return stamp - first stamp of its run; a run restarts where the stamps go backwards."""
    stamps = np.asarray(stamps_s, dtype=float)
    if stamps.size == 0:
        return stamps.copy()
    start = np.zeros(stamps.size, dtype=bool)
    start[0] = True
    start[1:] = np.diff(stamps) < 0.0      # the runner resets on a backward stamp
    first = stamps[np.maximum.accumulate(np.where(start, np.arange(stamps.size), 0))]
    return stamps - first


def inputs_of(rec, mask=None):
    """Return the empirical_terms.Inputs of a recording (or of the samples in ``mask``)."""
    sel = slice(None) if mask is None else mask
    accel = None if rec.nut_accel_rad_s2 is None else rec.nut_accel_rad_s2[sel]
    return Inputs.of(rec.t_run_s[sel], rec.nut_angle_rad[sel], rec.nut_velocity_rad_s[sel],
                     rec.axial_load_n[sel], accel)


def predict_events(events, config_path, replay_settings, progress=False):
    """Run events through the replay path; return (predictions, runner stats)."""
    runner = build_runner(config_path, replay_settings.model_rate_hz)
    assembler = InputAssembler(replay_settings.nut_joint, replay_settings.max_axial_load_n)
    preds = run_events(events, runner, assembler, progress=progress)
    return preds, runner.stats


def _from_predictions(preds, measured_nm, config_path, info):
    t = np.array([p.stamp_s for p in preds], dtype=float)
    t_run = run_times(t)
    angle = np.array([p.nut_angle_rad for p in preds], dtype=float)
    speed = np.array([p.nut_velocity_rad_s for p in preds], dtype=float)
    load = np.array([p.axial_load_n for p in preds], dtype=float)
    pred = np.array([p.torque_total_nm for p in preds], dtype=float)
    info["base_terms"] = list(load_model_file(config_path)[1].names)   # in pred already
    return Recording(t, t_run, angle, speed, load, np.asarray(measured_nm, dtype=float), pred,
                     np.array([p.converged for p in preds], dtype=bool), info)


def zero_baseline_events(events, replay_settings):
    """Return the nut-state samples of ``events`` without a model (``--baseline zero``)."""
    from bb_friction_ros.runner import InputError
    assembler = InputAssembler(replay_settings.nut_joint, replay_settings.max_axial_load_n)
    samples, rejected = [], {}
    for e in events:
        try:
            if e.kind == "axial_load":
                assembler.on_axial_load(e.value)
            elif e.kind == "nut_state":
                samples.append(assembler.on_nut_state(e.stamp_s, e.names, e.positions,
                                                      e.velocities))
        except InputError as exc:
            rejected[exc.reason] = rejected.get(exc.reason, 0) + 1
    return samples, rejected


def load_bag(path, config_path, replay_settings=NodeParameters(), topics=Topics(),
             progress=False, baseline="model"):
    """Read a rosbag2, predict through the replay path, align the measured torque."""
    try:
        events, counts = read_events(path, topics)
    except (FileNotFoundError, ValueError) as exc:
        raise InputProblem(str(exc)) from exc
    if measured_torque_at(events, []) is None:
        raise InputProblem(f"{path}: no measured torque: topic {topics.measured_torque!r} "
                           f"is missing or empty (topics in the bag: "
                           f"{', '.join(sorted(counts)) or 'none'}); the discrepancy needs "
                           "a measurement to compare with (--measured-topic)")
    if baseline == "zero":
        samples, rejected = zero_baseline_events(events, replay_settings)
        if not samples:
            raise InputProblem(f"{path}: no usable nut_state sample (rejected: "
                               f"{rejected or 'none'})")
        t = np.array([p.stamp_s for p in samples], dtype=float)
        meas = measured_torque_at(events, t)
        del events
        info = {"input": str(path), "format": "rosbag2", "baseline": "zero",
                "prediction_source": "none (--baseline zero: no model of this screw)",
                "messages": counts, "rejected": rejected, "base_terms": []}
        return Recording(t, run_times(t),
                         np.array([p.nut_angle_rad for p in samples], dtype=float),
                         np.array([p.nut_velocity_rad_s for p in samples], dtype=float),
                         np.array([p.axial_load_n for p in samples], dtype=float),
                         np.asarray(meas, dtype=float), np.zeros(t.size),
                         np.ones(t.size, dtype=bool), info)
    preds, stats = predict_events(events, config_path, replay_settings, progress)
    if not preds:
        raise InputProblem(f"{path}: no usable nut_state sample (rejected: "
                           f"{dict(stats.rejected) or 'none'})")
    meas = measured_torque_at(events, [p.stamp_s for p in preds])   # as replay aligns it
    info = {"input": str(path), "format": "rosbag2", "prediction_source": "model (replay path)",
            "messages": counts, "rejected": dict(stats.rejected),
            "nonconverged_steps": stats.nonconverged_steps, "resets": stats.resets}
    return _from_predictions(preds, meas, config_path, info)


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
        wanted = list(required) + [c for c in (CSV_PREDICTION, CSV_ACCELERATION)
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
    back = np.flatnonzero(np.diff(t_s) < 0.0) + 1
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


def csv_events(cols, nut_joint):
    """Return the events a CSV stands for: each row's axial load, then its nut state."""
    events = []
    for t, a, w, f in zip(cols["t_s"], cols["nut_angle_rad"], cols["nut_velocity_rad_s"],
                          cols["axial_load_n"]):
        events.append(Event("axial_load", float(t), value=float(f)))
        events.append(Event("nut_state", float(t), (nut_joint,), (float(a),), (float(w),)))
    return events


def load_csv(path, config_path, replay_settings=NodeParameters(), recompute=False,
             progress=False, baseline="model"):
    """Read a CSV recording; reuse its ``torque_pred_nm`` unless ``recompute`` (see module)."""
    cols = _read_csv_columns(path)
    if cols["t_s"].size == 0:
        raise InputProblem(f"{path}: CSV has no data rows")
    for c in ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", CSV_ACCELERATION):
        if c in cols and not np.all(np.isfinite(cols[c])):
            line = int(np.flatnonzero(~np.isfinite(cols[c]))[0]) + 2
            raise InputProblem(f"{path}: column {c} has non-finite values (first at line "
                               f"{line})")
    runs = check_time_order(path, cols["t_s"])
    accel = cols.get(CSV_ACCELERATION)
    info = {"input": str(path), "format": "csv", "runs": runs,
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
            info.update(prediction_source=f"csv column {CSV_PREDICTION} (reused)",
                        base_terms=[])
            if np.all(pred == 0.0):
                info["baseline"] = "zero"
        return Recording(cols["t_s"], t_run, cols["nut_angle_rad"],
                         cols["nut_velocity_rad_s"], cols["axial_load_n"],
                         cols["torque_meas_nm"], pred,
                         np.ones(cols["t_s"].size, dtype=bool), info, accel)
    preds, stats = predict_events(csv_events(cols, replay_settings.nut_joint), config_path,
                                  replay_settings, progress)
    if len(preds) != cols["t_s"].size:
        raise InputProblem(f"{path}: {cols['t_s'].size - len(preds)} row(s) rejected by the "
                           f"model input checks: {dict(stats.rejected)}")
    info.update(prediction_source="model (replay path, recomputed from the CSV inputs)",
                rejected=dict(stats.rejected), nonconverged_steps=stats.nonconverged_steps,
                resets=stats.resets)
    rec = _from_predictions(preds, cols["torque_meas_nm"], config_path, info)
    rec.nut_accel_rad_s2 = accel
    return rec


def load_recording(path, config_path=None, replay_settings=NodeParameters(), topics=Topics(),
                   recompute=False, progress=False, baseline="model"):
    """Load a rosbag2 directory or a ``.csv`` file (see module docstring)."""
    path = Path(path)
    config_path = config_path or bundled_config("ball_screw.yaml")
    if not Path(config_path).is_file():
        raise ConfigError(f"{config_path}: no such config file")
    if path.is_dir():
        return load_bag(path, config_path, replay_settings, topics, progress, baseline)
    if path.is_file() and path.suffix.lower() == ".csv":
        return load_csv(path, config_path, replay_settings, recompute, progress, baseline)
    if not path.exists():
        raise InputProblem(f"{path}: no such bag or CSV file")
    raise InputProblem(f"{path}: neither a rosbag2 directory nor a .csv file")
