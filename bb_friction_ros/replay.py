"""
``bb-friction replay``: a recording through exactly the live node's model path, offline.

Messages are fed in log order to the same ``InputAssembler`` and ``ModelRunner`` the node
uses, so the predictions equal the node's for the same messages (tested).  The bag is
streamed: each message is read, answered and written out before the next, so memory does not
grow with the recording.  Writes ``prediction.csv``, ``summary.json``, PNG plots and ``bag/``:
a rosbag2 (mcap) with the input topics copied and the node's output topics, for Foxglove,
PlotJuggler or ``ros2 bag play``.  Each output is logged at the log time of the input message
it answers and stamped with that message's header stamp, so the bag keeps one time line, the
recorder's, whatever clock the driver stamped with (a device clock near 0 s beside log times
since 1970 made a bag span 54 years), and a header stamp before 1970 is written as it came.

Into an ``--out`` used before, the earlier run's ``summary.json``, ``prediction.csv``, plot
and ``bag/`` are removed first (``bag/`` also with ``--no-bag``), so nothing stale sits beside
the new outputs; ``summary.json`` is written last with ``"complete": true``, or with
``"complete": false`` and the error if the run stops early: interrupted, a damaged message,
a full disk.  If even that cannot be written, the partial outputs are removed: no output of
a run that stopped is left unmarked.  ``duration_s`` is the
recording's span in log time (when the recorder received the messages): one far-future
header stamp does not make a 6-second bag last 2e9 s.
"""

from contextlib import contextmanager
import csv
import gc
import json
import math
from pathlib import Path
import shutil
import signal
import sys
import threading
import time

import numpy as np

from bb_friction_ros.alignment import MeasuredAligner
from bb_friction_ros.bag_types import BagError, stamp_ns, Topics
from bb_friction_ros.bags import BagInput
from bb_friction_ros.config import BBFrictionError, bundled_config
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay_outputs import (_CDR_LE, _csv_text, _csv_values,  # noqa: F401
                                            _FEEDFORWARD_CDR, _GROUPS_HEAD_CDR, _OutputBag,
                                            _PREDICTION_CDR, _row_formats, _Series,
                                            _write_lines, csv_values, feedforward_cdr,
                                            FEEDFORWARD_TOPIC, groups_cdr, GROUPS_TOPIC,
                                            OUTPUT_TOPICS, prediction_cdr, PREDICTION_TOPIC)
from bb_friction_ros.runner import build_runner, InputAssembler, InputError, \
    prediction_values

CSV_COLUMNS = ["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_pred_nm",
               "torque_b2b_nm"]
PLOT_FILE = "replay_torque_and_groups.png"
SUMMARY_FILE = "summary.json"
PREDICTION_FILE = "prediction.csv"
BAG_DIR = "bag"
# allocations between collections of the young generation while the bag streams
# (``_long_lived_frozen``); Python's default is 700.  Objects that die young are freed by
# their reference counts whatever this is: it holds back only garbage in cycles.
STREAM_GC_YOUNG = 50_000


class NothingAccepted(BagError):
    """A replay in which no nut_state sample was accepted (the message says why)."""


def feed_event(ev, runner, assembler):
    """Feed one event; return its Prediction, or None (a load, a measurement, a rejection)."""
    try:
        if ev.kind == "axial_load":
            assembler.on_axial_load(ev.value)
        elif ev.kind == "nut_state":
            sample = assembler.on_nut_state(ev.stamp_s, ev.names, ev.positions, ev.velocities)
            return runner.process(sample)
    except InputError as err:
        runner.reject(err.reason, nut_state=ev.kind == "nut_state")
    return None


def run_events(events, runner, assembler, progress=False):
    """
    Feed events in order; return the predictions.

    Rejected inputs are counted in ``runner.stats`` (``rejected`` by reason), as the node
    counts them.
    """
    iterator = events
    if progress:
        from tqdm import tqdm
        iterator = tqdm(events, desc="replay", unit="msg", file=sys.stderr, mininterval=0.5)
    preds = []
    for ev in iterator:
        pred = feed_event(ev, runner, assembler)
        if pred is not None:
            preds.append(pred)
    runner.settle()     # a step left to follow the last answer: counted as the node counts it
    return preds


def csv_header(measured, empirical):
    """
    Return the prediction.csv columns.

    The first six never move; ``torque_meas_nm`` follows when the bag records a measured
    torque, ``torque_empirical_nm`` when the model carries fitted terms, and ``converged``
    (1/0: every solve behind the value converged) is last.
    """
    return CSV_COLUMNS + (["torque_meas_nm"] if measured else []) + \
        (["torque_empirical_nm"] if empirical else []) + ["converged"]


def replay(bag, out, config=None, settings=NodeParameters(), topics=Topics(), progress=True,
           write_bag=True):
    """
    Replay ``bag`` into directory ``out``; return the summary dict.

    ``settings``: the node's parameters (``nut_joint``, ``model_rate_hz`` and
    ``max_axial_load_n`` shape the predictions); ``config`` is the model file (default:
    ``settings.config_file``, else the bundled ``config/ball_screw.yaml``).

    Raises FileNotFoundError or BagError (a ValueError) naming the file for a bag that
    cannot be used, and NothingAccepted when no nut_state sample was accepted (the summary
    is written first).  A run that stops early (a damaged message, a full disk, Ctrl-C)
    leaves ``summary.json`` with ``"complete": false`` and the error beside what it wrote,
    or, if that cannot be written, no outputs (``_mark_stopped``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    _remove_earlier_outputs(bag, out)
    with BagInput(bag, topics) as src:
        runner = build_runner(config or settings.config_file
                              or bundled_config("ball_screw.yaml"), *settings.schedule(),
                              b2b_feedforward=settings.b2b_feedforward)
        assembler = InputAssembler(settings.nut_joint, settings.max_axial_load_n)
        # metadata's count decides only whether the column exists: an empty measured topic
        # would hold every row back waiting for a measurement
        measured = any(c.topic == topics.absolute("measured_torque") and c.msgcount
                       for c in src.connections if c.topic in src.resolved)
        empirical = runner.terms is not None
        outbag = _OutputBag(out / BAG_DIR, src.connections) if write_bag else None
        try:
            with _interrupt_between_messages() as interrupted, _long_lived_frozen():
                summary = _stream(src, runner, assembler, out, measured, empirical, outbag,
                                  progress, interrupted)
            if outbag is not None:
                outbag.close()
            summary.update(bag=str(bag), model_rate_hz=settings.model_rate_hz,
                           model_step_deg=settings.model_step_deg,
                           topics=dict(src.topic_types),
                           messages_of_unknown_topics=sum(
                               sum(ids.values()) for ids in src.unknown_topic_messages.values()))
            unread = src.warnings(all_topics=outbag is not None)
            if unread:
                summary["warnings"] = list(summary.get("warnings", [])) + unread
            if outbag is not None:
                summary["output_bag"] = {"path": str(out / BAG_DIR),
                                         "written": outbag.written,
                                         "not_copied": {t: why for (t, _), why
                                                        in outbag.bag.not_copied.items()}}
            for warning in summary.get("warnings", ()):
                print(f"bb-friction replay: warning: {warning}", file=sys.stderr)
            _write_summary(out, summary)          # last: "complete": true
        except BaseException as exc:
            if outbag is not None:
                outbag.abandon()
            marked = _mark_stopped(out, bag, exc)
            if isinstance(exc, BagError):
                # the bag's own words name the message or file; say what is left behind
                raise BagError(f"{exc}; replay stopped there: {marked}") from None
            raise
        if summary["samples"] == 0:
            raise NothingAccepted(
                nothing_accepted_message(src, runner.stats.rejected, settings))
    return summary


@contextmanager
def _long_lived_frozen():
    """
    Keep the objects alive before the stream out of the garbage collector's walks.

    The model, numba, rosbags' typestore and matplotlib are ~185 000 objects that live as
    long as the process; the stream allocates a few per message, and each collection they
    trigger walked them: 0.26 -> 0.17 s of CPU for a 6-second bag at 1 rev/s with the model
    step taken out, 0.8 -> 0.6 s with it (measured at load 7-8; ``gc.freeze``).  And the
    young generation collected every ``STREAM_GC_YOUNG`` allocations, not 700: the stream's
    objects (answers, CDR records, CSV rows) die young without cycles, and collecting them
    every 700 was 5-10 % of replay's own work (6-second bags, the model step taken out,
    load ~1: 1.13x at 1 rev/s, 1.03x at 20 with 10 000; 50 000 another 1.04x at 20).
    """
    gc.freeze()
    threshold = gc.get_threshold()
    gc.set_threshold(max(threshold[0], STREAM_GC_YOUNG), *threshold[1:])
    try:
        yield
    finally:
        gc.set_threshold(*threshold)
        gc.unfreeze()


@contextmanager
def _interrupt_between_messages():
    """
    Let Ctrl-C stop the stream between two messages, never inside the model.

    A KeyboardInterrupt raised inside a model step can come out of the numerical code as
    another exception, which the runner counts as a ``model_error`` and goes on: the replay
    then ran to its end (seen in test_ctrl_c_leaves_no_stale_summary_and_exits_130).  So
    SIGINT only sets a flag here, and the stream raises KeyboardInterrupt at the next
    message; a second Ctrl-C raises at once.  Only in the main thread (where Python runs
    signal handlers), and not when SIGINT is ignored (a background job).
    """
    flag = []
    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        yield flag
        return

    def on_sigint(signum, frame):
        if flag:
            raise KeyboardInterrupt
        flag.append(signum)

    old = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, old)


def _write_summary(out, summary):
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2))


def _mark_stopped(out, bag, exc):
    """
    Mark the outputs of a run that stopped at ``exc``; return what is left, for the user.

    ``summary.json`` says ``"complete": false`` with the error, beside the partial
    ``prediction.csv`` and ``bag/``.  If it cannot be written (the disk is full),
    the partial outputs are removed instead: none is left to be taken for a whole run's.
    """
    if isinstance(exc, KeyboardInterrupt):
        summary = {"complete": False, "bag": str(bag),
                   "reason": "interrupted: prediction.csv and bag/ hold only the part replayed"}
    else:
        error = str(exc) if isinstance(exc, BBFrictionError) else \
            f"{type(exc).__name__}: {exc}"
        summary = {"complete": False, "bag": str(bag),
                   "reason": "stopped by an error: prediction.csv and bag/ hold only the "
                             "messages before it",
                   "error": error}
    try:
        _write_summary(out, summary)
    except OSError:
        try:
            _remove_outputs(out)
        except OSError:
            return f"the partial outputs in {out} could not be marked or removed"
        return f"the partial outputs in {out} were removed (summary.json could not be written)"
    return f"the outputs in {out} are partial (summary.json: \"complete\": false)"


def _remove_earlier_outputs(bag, out):
    """
    Remove what an earlier replay into ``out`` wrote and this one may not overwrite.

    A summary.json of another bag beside a new, partial prediction.csv (Ctrl-C), or a bag/
    beside a ``--no-bag`` run's outputs, would be read as this run's.  Refused first: an
    input bag that is (or lies in) ``out/bag``, which a replay replaces.
    """
    own_bag = (out / BAG_DIR).resolve()
    src = Path(bag).resolve()
    if src == own_bag or own_bag in src.parents:
        raise BagError(f"--out {out}: the input bag {bag} is replay's own output bag "
                       f"{out / BAG_DIR}, which a replay replaces; pass another --out")
    _remove_outputs(out)


def _remove_outputs(out):
    """Remove replay's outputs from ``out``: summary, prediction, plot and output bag."""
    for name in (SUMMARY_FILE, PLOT_FILE, PREDICTION_FILE):
        (out / name).unlink(missing_ok=True)
    own_bag = out / BAG_DIR
    if own_bag.is_dir() and not own_bag.is_symlink():
        shutil.rmtree(own_bag)
    elif own_bag.is_symlink() or own_bag.is_file():
        own_bag.unlink()


class _Sink:
    """
    What the stream writes per answer: prediction.csv, the plotted series, the output bag.

    And the RMSE against the measured torque: each answer is held until its measurement
    when the bag records one (``MeasuredAligner``).  An answer travels as the tuple of its
    fields (``ModelRunner.process_values``) to the CSV and the series, which take their
    columns from it a block at a time.
    """

    def __init__(self, measured, empirical, outbag):
        self.series = _Series(measured)
        self.aligner = MeasuredAligner() if measured else None
        self.empirical = empirical
        self.outbag = outbag
        self.lines = []
        self.sq_err, self.n_err = 0.0, 0

    def emit(self, done):
        """Write the answers the aligner released: (answer, measured)."""
        if not done:
            return
        isfinite = math.isfinite
        sq_err, n_err = self.sq_err, self.n_err
        rows = [(v, float(meas)) for v, meas in done]
        for v, meas in rows:
            if isfinite(meas):
                sq_err += (meas - v[4]) ** 2       # in order, as one by one
                n_err += 1
        self.sq_err, self.n_err = sq_err, n_err
        self.lines += rows
        self.series.add_rows(rows)

    def take(self, answers):
        """
        Queue ``answers`` (published already) for the CSV and series, in order.

        Without a measured torque each is written as it comes; with one, each waits in
        the aligner for its measurement.
        """
        if self.aligner is None:
            self.lines += [(v, None) for v in answers]
            return
        for v in answers:
            self.emit(self.aligner.add_prediction(v[0], v))

    def measure(self, stamp_s, value):
        """Take one measured torque (aligned with the answers by stamp)."""
        if self.aligner is not None:
            done = self.aligner.add_measured(stamp_s, value)
            if done:
                self.emit(done)

    def defer(self, block, stamps, fast):
        """
        Let the aligner release the answers of ``block`` once, at its end, where it can.

        Its measured torques and nut states must all be decoded (``fast``) for their
        stamps to be known here (``MeasuredAligner.defer``); ``release`` ends the block.
        Returns the indices of the block's measured torques if it deferred (the stream
        then hands them over together, ``measure_deferred``), else None.  Without a
        measured torque nothing waits: () .
        """
        if self.aligner is None:
            return ()
        kinds = block.kinds
        meas = [i for i, kind in enumerate(kinds) if kind == "measured_torque"]
        nut = [i for i, kind in enumerate(kinds) if kind == "nut_state"]
        if all(fast[i] for i in meas) and all(fast[i] for i in nut) \
                and self.aligner.defer([stamps[i] for i in meas], [stamps[i] for i in nut]):
            return meas
        return None

    def take_deferred(self, block, idx, answers):
        """
        ``take`` the ``answers`` of ``block`` and its measured torques at ``idx`` (``defer``).

        A deferred aligner only queues both until ``release``: one call for the block
        instead of two per sample.
        """
        if self.aligner is None:
            self.take(answers)
            return
        idx = np.asarray(idx, dtype=np.intp)
        self.aligner.add_to_batch(block.stamp_s[idx].tolist(), block.value[idx].tolist(),
                                  [v[0] for v in answers], answers)

    def release(self):
        """Write the answers the aligner held back during a block (``defer``)."""
        if self.aligner is not None:
            self.emit(self.aligner.release())

    def flush(self, fh, finish=False):
        """Write what is queued (``finish``: the aligner's held answers too)."""
        if finish and self.aligner is not None:
            self.emit(self.aligner.finish())
        if self.aligner is None and self.lines:
            self.series.add_rows(self.lines, measured=False)
        _write_lines(fh, self.lines, self.empirical)
        if self.outbag is not None:
            self.outbag.flush()


def _feed_block(block, runner, assembler, sink):
    """
    Feed one block of messages, in log order, to the runner; write its answers to ``sink``.

    Messages decoded with numpy (``bags.Block``) pass the node's own checks inline; any
    other is decoded one by one into an Event (``feed_event``).  Each input message is
    copied to the output bag before what the node publishes for it.
    """
    fast = block.fast.tolist()
    stamps, stamps_ns = block.stamp_s.tolist(), block.stamp_ns.tolist()
    values, velocities = block.value.tolist(), block.velocity.tolist()
    deferred = sink.defer(block, stamps, fast)
    try:
        _feed_items(block, runner, assembler, sink, fast, stamps, stamps_ns, values,
                    velocities, deferred)
    finally:
        sink.release()      # what a failure leaves answered is written too


def _feed_items(block, runner, assembler, sink, fast, stamps, stamps_ns, values,
                velocities, deferred):
    """
    Feed the messages of ``block`` one by one (``_feed_block``'s loop).

    ``deferred``: the indices of the block's measured torques if they wait for the block's
    end anyway (``_Sink.defer``; () without any), else None.  The block's answers are then
    handed to the sink together at its end (or where a failure stops it), with the
    measured torques before that point: the same rows as one by one.
    """
    outbag = sink.outbag
    clock = time.perf_counter
    process = runner.process_scalars
    items, kinds = block.items, block.kinds
    if outbag is not None:
        pending, publish, get = outbag.pending, outbag.publish_values, outbag.copies.get
        # each message's copy (its connection None: not copied), built in one pass
        copied = [(get(c.id), t, raw) for c, t, raw in items]
    got = [] if deferred is not None else None
    i = -1
    try:
        for i, kind in enumerate(kinds):
            # a message decoded one by one is decoded before its copy: a damaged one
            # stops the run before it reaches the output bag
            ev = block.event(i) if kind is not None and not fast[i] else None
            if outbag is not None and copied[i][0] is not None:
                pending.append(copied[i])
            if kind is None:
                continue
            if fast[i]:
                if kind == "measured_torque":
                    if got is None:
                        sink.measure(stamps[i], values[i])
                    continue
                if kind == "axial_load":
                    try:
                        assembler.on_axial_load(values[i])
                    except InputError as err:
                        runner.reject(err.reason)
                    continue
                load = assembler.load_n
                if load is not None:
                    t_in = clock()
                    answer = process(stamps[i], values[i], velocities[i], load)
                    if answer is not None:
                        if outbag is not None:
                            publish(answer, stamps_ns[i], items[i][1], clock() - t_in)
                        if got is None:
                            sink.take((answer,))
                        else:
                            got.append(answer)
                    continue
            if ev is None:      # a nut_state before any load: rejected with its reason
                ev = block.event(i)
            if ev.kind == "measured_torque":
                sink.measure(ev.stamp_s, ev.value)
                continue
            t_in = clock()
            pred = feed_event(ev, runner, assembler)
            if pred is not None:
                v = prediction_values(pred)
                if outbag is not None:
                    publish(v, stamp_ns(ev), items[i][1], clock() - t_in)
                if got is None:
                    sink.take((v,))
                else:
                    got.append(v)
        i = len(kinds)
    finally:
        if got is not None:
            # what was fed before the end (or the failure at message i)
            sink.take_deferred(block, [k for k in deferred if k < i], got)


def _stream(src, runner, assembler, out, measured, empirical, outbag, progress,
            interrupted=()):
    """Stream the bag through the runner into ``out``; return the summary (``replay``)."""
    sink = _Sink(measured, empirical, outbag)
    log_min, log_max = math.inf, -math.inf
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=src.total_messages(), desc="replay", unit="msg", file=sys.stderr,
                   mininterval=0.5)
    t0, cpu0 = time.perf_counter(), time.process_time()
    with open(out / PREDICTION_FILE, "w", newline="") as fh:
        csv.writer(fh).writerow(csv_header(measured, empirical))
        try:
            for block in src.blocks(assembler.nut_joint, all_topics=outbag is not None):
                if interrupted:
                    raise KeyboardInterrupt
                if bar is not None:
                    bar.update(len(block.items))
                if block.log_range is not None:
                    lo, hi = block.log_range
                    log_min, log_max = min(log_min, lo), max(log_max, hi)
                _feed_block(block, runner, assembler, sink)
                sink.flush(fh)
        except BaseException:
            # keep what was answered before the failure: the partial outputs end where the
            # run stopped (summary.json then says "complete": false)
            try:
                sink.flush(fh, finish=True)
            except Exception:   # the failure that stopped the run is the one reported
                pass
            raise
        sink.flush(fh, finish=True)
        runner.settle()     # a step left to follow the last answer, as the node takes it
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    if bar is not None:
        bar.close()
    # log time, not header stamps: a header stamp is whatever the driver wrote (one of
    # 2e9 s claimed a 2e9 s recording replayed at 1e10 x real time)
    span = (log_max - log_min) * 1e-9 if log_max > log_min else 0.0
    summary = _summary(src, runner.stats, sink, span, wall, cpu)
    if sink.series.rows:
        plot_replay(out, sink.series)
    sink.series.close()
    return summary


def _summary(src, stats, sink, span, wall, cpu):
    """Return summary.json of a stream that ran to its end (``replay`` adds the rest)."""
    summary = {
        "complete": True,
        "messages": dict(src.counts),
        "samples": sink.series.rows,
        "rejected": dict(stats.rejected),
        "resets": stats.resets,
        "late_samples": stats.late_samples,
        # the shared runner's schedule and stamp stalls
        "model_substeps": stats.substeps,
        "stamp_stalls": stats.stamp_stalls,
        "model_steps": stats.model_steps,
        "nonconverged_steps": stats.nonconverged_steps,
        "duration_s": span,
        "wall_s": wall,
        "speed_vs_realtime": span / wall if wall > 0 else None,
        # CPU time of the same loop: on a shared machine the wall time says more about the
        # other processes than about replay
        "cpu_s": cpu,
    }
    aligner = sink.aligner
    if aligner is not None:
        summary["rmse_nm"] = math.sqrt(sink.sq_err / sink.n_err) if sink.n_err else None
        summary["measured_rows"] = sink.n_err
        summary["measured_alignment"] = {
            "runs": aligner.runs, "late_stamps": aligner.late,
            "stamps_far_ahead": aligner.ahead,
            "unmatched_predictions": aligner.unmatched_predictions,
            "unmatched_measured": aligner.unmatched_measured}
        summary["warnings"] = aligner.warnings()
    if stats.stamp_stalls:
        summary["warnings"] = list(summary.get("warnings", [])) + [
            f"{stats.stamp_stalls} nut_state samples carry the previous sample's stamp "
            "(header.stamp not advancing): the model stepped on nut angle, direction and "
            "load only"]
    return summary


def nothing_accepted_message(src, rejected, settings):
    """
    Say why no sample was accepted: reasons with counts, what the bag holds, the fix.

    ``rejected``: the inputs refused, by reason (a Counter: ``RunnerStats.rejected``).
    """
    nut = src.topics.absolute("nut_state")
    load = src.topics.absolute("axial_load")
    lines = [f"{src.path}: no nut_state sample was accepted, so there is nothing to predict."]
    reasons = ", ".join(f"{r} {n}" for r, n in rejected.most_common()) or "none"
    lines.append(f"  rejected (reason count): {reasons}")
    lines.append("  messages read: " + (", ".join(f"{t} {n}" for t, n in
                                                  sorted(src.counts.items())) or "none"))
    lines.append(f"  topics in the bag: {src.describe()}")
    names = sorted({n for group in src.joint_names for n in group})
    lines.append(f"  joint names seen on {nut}: {names or 'none'} (nut_joint is "
                 f"{settings.nut_joint!r})")
    hints = []
    if src.counts[nut] == 0:
        hints.append(f"{nut} has no messages")
    if rejected.get("wrong_joint") and names:
        hints.append(f"the nut joint is named differently: pass --nut-joint {names[0]}"
                     + (f" (or one of {names})" if len(names) > 1 else ""))
    if rejected.get("no_load_yet"):
        hints.append(f"{load} has no messages" if src.counts[load] == 0 else
                     f"no valid load arrived on {load} (see its rejections)")
    if rejected.get("absurd_load"):
        hints.append(f"loads exceed max_axial_load_n = {settings.max_axial_load_n:g} N "
                     "(set it in --params-file)")
    if rejected.get("non_finite") or rejected.get("empty") \
            or rejected.get("missing_velocity"):
        hints.append("the messages carry no finite position, velocity or load")
    if hints:
        lines.append("  hint: " + "; ".join(hints))
    return "\n".join(lines)


def plot_replay(out, series):
    """Predicted vs measured torque, and the B2B groups over time (min/max decimated)."""
    from matplotlib.figure import Figure
    c = series.decimated()
    t = c["t"] - c["t"][0]
    fig = Figure(figsize=(10, 8))
    ax = fig.subplots(3, 1, sharex=True)
    if series.measured:
        ax[0].plot(t, c["meas"], lw=0.6, color="0.5", label="measured")
    ax[0].plot(t, c["torque"], lw=1.0, label="predicted (total)")
    ax[0].plot(t, c["b2b"], lw=1.0, label="predicted B2B part")
    ax[0].set_ylabel("friction torque [N m]")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, c["speed"], lw=0.8)
    ax[1].set_ylabel("nut speed [rad/s]")
    ax2 = ax[1].twinx()
    ax2.plot(t, c["load"], lw=0.8, color="C3")
    ax2.set_ylabel("axial load [N]", color="C3")
    ax[2].step(t, c["groups"], where="post", label="groups")
    ax[2].step(t, c["largest"], where="post", label="largest group (balls)")
    ax[2].set_ylabel("B2B contact groups")
    ax[2].set_xlabel("time [s]")
    ax[2].legend(fontsize=8)
    for a in ax:
        a.grid(True)
    fig.tight_layout()
    fig.savefig(Path(out) / PLOT_FILE, dpi=110)
