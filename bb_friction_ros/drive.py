"""
One driver for a stream of samples: columns in, the runner over them, columns out.

The offline paths (the discrepancy workflow's data, the physical trials, ``bb-friction
feedforward``) hand the runner their nut-state samples as columns (``SampleColumns``:
stamps, angles, velocities and held loads, with the count of the inputs refused, by reason)
and get one row per sample back (``PredictionColumns``), with the index of the model step
whose state answered it.  The samples are validated once, as the node validates them
(``inputs.InputAssembler``): from events (``samples_of_events``) or from the rows of a
table that carries a load per row (``samples_of_rows``, the same rules vectorised).  What the
runner does at each sample is the schedule's decision (``schedule.Schedule.plan``).
"""

from array import array
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from bb_friction_ros.inputs import InputAssembler, InputError, InputSample

# The float columns of a PredictionColumns, in Prediction's names.
PREDICTION_COLUMNS = ("stamp_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                      "torque_total_nm", "torque_b2g_nm", "torque_b2b_nm",
                      "torque_empirical_nm", "feedforward_nm")


@dataclass
class SampleColumns:
    """
    Accepted nut-state samples as columns (SI), in order, and the inputs refused.

    ``rejected``: inputs of both topics refused, by reason (``InputError.reason``);
    ``rejected_nut_state``: how many of them were nut-state samples.
    """

    stamp_s: np.ndarray
    nut_angle_rad: np.ndarray
    nut_velocity_rad_s: np.ndarray
    axial_load_n: np.ndarray
    rejected: Counter = field(default_factory=Counter)
    rejected_nut_state: int = 0

    @classmethod
    def of(cls, stamp_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """Return the columns of samples already accepted (float arrays, broadcast)."""
        cols = np.broadcast_arrays(*(np.asarray(c, dtype=float) for c in (
            stamp_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)))
        return cls(*(np.ascontiguousarray(c) for c in cols))

    def __len__(self):
        """Return the number of samples."""
        return int(self.stamp_s.size)


def samples_of_events(events, nut_joint, max_axial_load_n):
    """
    Return the SampleColumns of events (any iterable, consumed once), validated in order.

    As the node takes them (``InputAssembler``): each load is held for the nut states after
    it; an input refused is counted by its reason.  Measured torques are left out.  The
    columns grow as packed floats, so a long bag is never in memory as samples.
    """
    assembler = InputAssembler(nut_joint, max_axial_load_n)
    cols = [array("d") for _ in range(4)]
    rejected, nut_rejected = Counter(), 0
    for ev in events:
        try:
            if ev.kind == "axial_load":
                assembler.on_axial_load(ev.value)
            elif ev.kind == "nut_state":
                s = assembler.on_nut_state(ev.stamp_s, ev.names, ev.positions, ev.velocities)
                for c, v in zip(cols, (s.stamp_s, s.nut_angle_rad, s.nut_velocity_rad_s,
                                       s.axial_load_n)):
                    c.append(v)
        except InputError as err:
            rejected[err.reason] += 1
            nut_rejected += ev.kind == "nut_state"
    return SampleColumns(*(np.frombuffer(c, dtype=float) if len(c) else np.zeros(0)
                           for c in cols), rejected, nut_rejected)


def samples_of_rows(stamp_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n,
                    max_axial_load_n):
    """
    Return the SampleColumns of rows that each carry a load and then a nut state (a CSV).

    The rules of ``samples_of_events`` for the events a row stands for (its load, then its
    nut state), vectorised: a load refused (non-finite, or above ``max_axial_load_n``) leaves
    the last accepted one held; a row before any accepted load is refused
    (``no_load_yet``), as is a row with a non-finite stamp, angle or velocity.
    """
    t, a, w, f = np.broadcast_arrays(*(np.asarray(c, dtype=float) for c in (
        stamp_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)))
    rejected = Counter()
    finite_load = np.isfinite(f)
    load_ok = finite_load & (np.abs(np.where(finite_load, f, 0.0)) <= max_axial_load_n)
    rejected["non_finite"] += int((~finite_load).sum())
    rejected["absurd_load"] += int((finite_load & ~load_ok).sum())
    # the load held at each row: the last accepted one up to it
    last = np.maximum.accumulate(np.where(load_ok, np.arange(f.size), -1)) if f.size \
        else np.zeros(0, dtype=np.int64)
    held = last >= 0
    bad_state = ~(np.isfinite(t) & np.isfinite(a) & np.isfinite(w))
    rejected["non_finite"] += int(bad_state.sum())
    rejected["no_load_yet"] += int((~bad_state & ~held).sum())
    ok = held & ~bad_state
    rejected = Counter({k: v for k, v in rejected.items() if v})
    return SampleColumns(t[ok].copy(), a[ok].copy(), w[ok].copy(),
                         f[last[ok]].copy(), rejected, int((~ok).sum()))


@dataclass
class PredictionColumns:
    """
    The runner's answer to each sample of a SampleColumns, as columns.

    The float columns are Prediction's (``PREDICTION_COLUMNS``), NaN where the model failed
    (``answered`` False: counted as ``model_error``).  ``step``: the index (from 0, in this
    run of the driver) of the model step whose state answered the sample, -1 where none did;
    ``stepped``: the sample made the model step (before its answer or after it);
    ``run_start``: the step at the sample began a run (the first sample, after a reset or a
    model error).  ``states``: per model step, the screw's own result (``torque_total_nm``,
    ``torque_b2b_nm``: physics only, no terms; ``converged``; ``direction``: the sign of
    the nut velocity it was taken at).
    """

    columns: dict
    converged: np.ndarray
    answered: np.ndarray
    step: np.ndarray
    stepped: np.ndarray
    run_start: np.ndarray
    states: dict = None

    def __getattr__(self, name):
        """Return a float column by its Prediction name (``torque_total_nm``...)."""
        try:
            return self.__dict__["columns"][name]
        except KeyError:
            raise AttributeError(name) from None

    def __len__(self):
        """Return the number of samples."""
        return int(self.converged.size)

    def column(self, name):
        """Return the float column ``name`` (``torque_total_nm``...)."""
        return self.columns[name]

    def take(self, mask):
        """Return the rows where ``mask`` is true (the step indices kept as they were)."""
        return PredictionColumns({c: v[mask] for c, v in self.columns.items()},
                                 self.converged[mask], self.answered[mask], self.step[mask],
                                 self.stepped[mask], self.run_start[mask], self.states)

    def steps(self):
        """Return (per model step: the sample it stepped at; per sample: its step, -1 none)."""
        at = np.flatnonzero(self.stepped)
        return at, self.step


def run_samples(runner, samples, settle=True, reset_before=None, stop_at_error=False):
    """
    Run SampleColumns through ``runner`` in order; return their PredictionColumns.

    The inputs ``samples`` refused are counted in ``runner.stats`` (``rejected`` by reason),
    as the node counts them.  ``settle``: take the step left to follow the last answer, as
    the node does (every other such step is taken right after its answer, as the live node
    takes it: when it runs changes no answer, and each step's state is seen).
    ``reset_before`` (a bool per sample, optional): reset the runner before those samples
    (a trial run that must begin its runs where another run began them).
    ``stop_at_error``: stop at the first sample the model could not answer (the columns then
    end there; ``runner.stats.last_error`` says why; a step that follows its answer and
    fails is counted, the sample was answered).
    """
    stats = runner.stats
    for reason, n in samples.rejected.items():
        stats.rejected[reason] += n
    stats.rejected_nut_state += samples.rejected_nut_state
    n = len(samples)
    out = {c: np.full(n, np.nan) for c in PREDICTION_COLUMNS}
    converged = np.zeros(n, dtype=bool)
    answered = np.zeros(n, dtype=bool)
    step = np.full(n, -1, dtype=np.int64)
    stepped = np.zeros(n, dtype=bool)
    run_start = np.zeros(n, dtype=bool)
    # packed as they come: 8 bytes a value (a 10-minute 1 kHz recording is 600 000 rows)
    rows = [array("d") for _ in PREDICTION_COLUMNS]
    conv, steps_at = array("b"), array("q")
    base = stats.model_steps - stats.substeps       # steps answered from, before this run
    fresh = True                  # the runner starts from no state: first, reset, error
    resets = stats.resets
    t, a, w, f = (samples.stamp_s.tolist(), samples.nut_angle_rad.tolist(),
                  samples.nut_velocity_rad_s.tolist(), samples.axial_load_n.tolist())
    resets_at = None if reset_before is None else np.asarray(reset_before, bool).tolist()
    process = runner.process
    states = [array("d"), array("d"), array("b"), array("d")]
    taken = base
    last = n
    for i in range(n):
        if resets_at is not None and resets_at[i]:
            runner.reset()
            fresh = True
        p = process(InputSample(t[i], a[i], w[i], f[i]))
        if p is None:             # a model error: counted, the runner reset itself
            fresh = True
            conv.append(False)
            steps_at.append(-1)
            for r in rows:
                r.append(np.nan)
            if stop_at_error:
                last = i
                break
            continue
        answered[i] = True
        if p.stepped or runner.pending:
            stepped[i] = True
            run_start[i] = fresh or stats.resets != resets
            resets, fresh = stats.resets, False
        steps_at.append(stats.model_steps - stats.substeps - base - 1)
        taken = _record_state(runner, taken, states)
        if runner.pending:
            runner.settle()
            taken = _record_state(runner, taken, states)
        conv.append(p.converged)
        for r, v in zip(rows, (p.stamp_s, p.nut_angle_rad, p.nut_velocity_rad_s,
                               p.axial_load_n, p.torque_total_nm, p.torque_b2g_nm,
                               p.torque_b2b_nm, p.torque_empirical_nm, p.feedforward_nm)):
            r.append(v)
    if settle:
        runner.settle()     # a step left to follow the last answer: counted as the node counts
        taken = _record_state(runner, taken, states)
    m = len(conv)
    if m:
        for c, r in zip(PREDICTION_COLUMNS, rows):
            out[c][:m] = np.frombuffer(r, dtype=float)
        converged[:m] = np.frombuffer(conv, dtype=np.int8)
        step[:m] = np.frombuffer(steps_at, dtype=np.int64)
    if last < n:
        keep = slice(0, last + 1)
        out = {c: v[keep] for c, v in out.items()}
        converged, answered, step = converged[keep], answered[keep], step[keep]
        stepped, run_start = stepped[keep], run_start[keep]
    names = ("torque_total_nm", "torque_b2b_nm", "converged", "direction")
    step_states = {k: (np.frombuffer(v, dtype=np.int8 if k == "converged" else float)
                       if len(v) else np.zeros(0)) for k, v in zip(names, states)}
    step_states["converged"] = step_states["converged"].astype(bool)
    return PredictionColumns(out, converged, answered, step, stepped, run_start, step_states)


def _record_state(runner, taken, states):
    """Append the runner's state to ``states`` if it stepped since ``taken``; return the count."""
    stats = runner.stats
    now = stats.model_steps - stats.substeps
    if now != taken and runner.state is not None:
        st = runner.state
        for col, v in zip(states, (st.torque_total_nm, st.torque_b2b_nm, bool(st.converged),
                                   runner.schedule.direction)):
            col.append(v)
    return now
