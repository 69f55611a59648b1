"""
Measured torque paired with the predictions, stamp by stamp and run by run.

Replay and the discrepancy workflow both align with ``MeasuredAligner`` (streaming) or
``measured_torque_at`` (arrays), so they agree.  Late stamps and restarts follow the
runner's rule (``schedule.LATE_STAMP_TOLERANCE_S``), with a look-ahead the runner has not.
"""

import bisect
from collections import deque
import math

import numpy as np

from bb_friction_ros.schedule import LATE_SAMPLES_MAX, LATE_STAMP_TOLERANCE_S

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


def _goes_on(stamps, newest, tolerance_s, strict):
    """Whether ``stamps`` go on from ``newest``, increasing by at most ``tolerance_s`` a time."""
    if not stamps.size:
        return True
    steps = np.diff(stamps if newest is None else np.concatenate([[newest], stamps]))
    rising = steps > 0.0 if strict else steps >= 0.0
    return bool(np.all(np.isfinite(stamps)) and np.all(rising) and np.all(steps <= tolerance_s))


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
        self._deferred = False   # add_* hold what they would release until ``release``

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

    def defer(self, measured_stamps_s, prediction_stamps_s):
        """
        Hold releases until ``release`` for a batch, if that releases the same; say if it did.

        A prediction's measurement is decided by the measured samples around its stamp.
        While both streams go on increasing from where they are, by at most the tolerance
        at a time (no late sample, restart or stamp far ahead; no repeated measured
        stamp), a measured sample taken later lies after every bracket already known and
        no sample dropped as no longer needed is needed, so releasing once per batch gives
        every prediction the value a release after each sample gives, in the same order:
        replay's stream releases once per block of messages instead of twice per sample.
        ``measured_stamps_s``, ``prediction_stamps_s``: the batch's stamps in order (those
        of predictions may include samples that are then refused); the batch must stay
        within ``max_held`` both ways.
        """
        m, p = (np.asarray(s, dtype=float) for s in (measured_stamps_s, prediction_stamps_s))
        m_runs, p_runs, tol = self._m_runs, self._p_runs, self.tolerance_s
        if m_runs.suspects or p_runs.suspects or m_runs.jump_from is not None \
                or p_runs.jump_from is not None:
            return False
        if not (_goes_on(m, m_runs.newest, tol, strict=True)
                and _goes_on(p, p_runs.newest, tol, strict=False)):
            return False
        if p.size and self._p_max is not None and not self._p_max <= p[0]:
            return False
        if m.size and self._meas and self._meas[-1].stamps \
                and not self._meas[-1].stamps[-1] < m[0]:
            return False
        if self.max_held is not None and (
                len(self._preds) + p.size >= self.max_held
                or sum(map(len, self._meas)) + m.size >= self.max_held):
            return False
        self._deferred = True
        self._batch_m, self._batch_p = [], []
        return True

    def release(self):
        """End a batch (``defer``): return what it holds back, in prediction order."""
        if not self._deferred:
            return []                   # no batch: each sample released what it could
        self._deferred = False
        # What add_* would have done one by one, for stamps going on in the current runs
        # (``defer``): every sample joins its stream's current run, the newest stamps move.
        measured, preds = self._batch_m, self._batch_p
        self._batch_m = self._batch_p = None
        if measured:
            m_runs = self._m_runs
            m_runs.started = True
            m_runs.newest, m_runs.newest_item = measured[-1]
            self.samples += len(measured)
            if not self._meas or self._meas[-1].run != m_runs.run:
                self._meas.append(_MeasuredRun(m_runs.run))
            last = self._meas[-1]
            last.stamps.extend([t for t, _ in measured])
            last.values.extend([v for _, v in measured])
        if preds:
            p_runs = self._p_runs
            p_runs.started = True
            run = p_runs.run
            for entry in preds:
                entry[0] = run
            self._preds.extend(preds)
            p_runs.newest_item = preds[-1]
            p_runs.newest = self._p_max = preds[-1][1]
            self._p_run_decided = run
        return self._drain_run() or self._drain()

    def _drain_run(self):
        """
        Release the waiting predictions at once, as ``_drain`` one by one, where it can.

        Where every waiting prediction belongs to the measured stream's current run (its
        newest stamp confirmed, as ``defer`` leaves it): their values from the run's samples
        as arrays, by ``_MeasuredRun.at``'s rule and arithmetic, up to the first that waits
        for its upper bracket.  None where it cannot (``_drain`` then does).
        """
        preds, meas, m_runs = self._preds, self._meas, self._m_runs
        if not preds:
            return None
        run = m_runs.run
        if m_runs.jump_from is not None or any(entry[0] != run for entry in preds):
            return None
        while meas and meas[0].run < run:
            meas.popleft()
        if len(meas) != 1 or meas[0].run != run:
            return None
        current = meas[0]
        st = np.asarray(current.stamps[current.head:], dtype=float)
        sv = np.asarray(current.values[current.head:], dtype=float)
        t = np.fromiter((entry[1] for entry in preds), dtype=float, count=len(preds))
        i = np.searchsorted(st, t, side="right")       # first sample after t
        lo = np.maximum(i - 1, 0)
        exact = (i > 0) & (st[lo] == t) if st.size else np.zeros(t.size, dtype=bool)
        known = exact | (i == 0) & (st.size > 0) | (i > 0) & (i < st.size)
        n = int(np.argmin(known)) if not known.all() else t.size
        if n == 0:
            return None
        hi = np.minimum(i, st.size - 1)
        t0, t1, v0, v1 = st[lo[:n]], st[hi[:n]], sv[lo[:n]], sv[hi[:n]]
        with np.errstate(invalid="ignore", divide="ignore"):
            values = v0 + (v1 - v0) * (t[:n] - t0) / (t1 - t0)
        values = np.where(exact[:n], v0, np.where(i[:n] == 0, np.nan, values))
        out = [(preds.popleft()[2], v) for v in values.tolist()]
        self._trim()
        return out

    def add_measured(self, stamp_s, value_nm):
        """Take one measured sample (non-finite values are skipped)."""
        if not (math.isfinite(stamp_s) and math.isfinite(value_nm)):
            return [] if self._deferred else self._drain()
        if self._deferred:
            self._batch_m.append((stamp_s, value_nm))
            return []
        self.samples += 1
        self._take_measured(self._m_runs.add(stamp_s, (stamp_s, value_nm)))
        while self._m_runs.outliers:          # a stamp far ahead: it brackets nothing
            stamp, _ = self._m_runs.outliers.pop()
            for m in reversed(self._meas):
                if m.remove(stamp):
                    break
        return [] if self._deferred else self._drain()

    def add_to_batch(self, measured_stamps_s, values_nm, prediction_stamps_s, payloads):
        """In a batch (``defer``): ``add_measured`` and ``add_prediction`` of each, in order."""
        isfinite = math.isfinite
        self._batch_m += [(t, v) for t, v in zip(measured_stamps_s, values_nm)
                          if isfinite(t) and isfinite(v)]
        self._batch_p += [[None, t, p] for t, p in zip(prediction_stamps_s, payloads)]

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
        if self._deferred:
            self._batch_p.append(entry)
            return []
        self._preds.append(entry)
        self._decide(self._p_runs.add(stamp_s, entry))
        while self._p_runs.outliers:          # a stamp far ahead: no measurement, at once
            self._p_runs.outliers.pop()[0] = "ahead"
        return [] if self._deferred else self._drain()

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
        self._deferred = False
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
        self._trim()
        return out

    def _trim(self):
        """Drop the measured samples no later prediction can ask for."""
        meas = self._meas
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


def measured_torque_at(events, stamps_s):
    """
    Return the measured torque at ``stamps_s`` [N m] run by run, or None if none recorded.

    ``events``: the recording's events, of which the ``measured_torque`` ones are used
    (``measured_at`` takes them as columns).
    """
    meas = [(e.stamp_s, e.value) for e in events if e.kind == "measured_torque"]
    return measured_at([t for t, _ in meas], [v for _, v in meas], stamps_s)


def measured_at(measured_stamps_s, measured_nm, stamps_s):
    """
    Return the measured torque (its stamps and values) at ``stamps_s`` [N m], or None.

    Run by run: ``stamps_s`` are prediction stamps in processing order; see
    ``MeasuredAligner`` for how a looping recording is aligned pass by pass.  Replay and the
    discrepancy workflow both align the measurement with it, so they agree.  None when
    there is no measured sample.
    """
    aligner = MeasuredAligner(max_held=None)     # the arrays are in memory already
    for t, v in zip(measured_stamps_s, measured_nm):
        aligner.add_measured(t, v)
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
