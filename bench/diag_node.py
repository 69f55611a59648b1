"""
friction_node with parts switched off or traced: diagnostics of bench/bench_node.py only.

Everything of the node runs as shipped (parameters, the fast input path, the live schedule
and its model thread, the runner's bookkeeping, the answers, groups, profiles and
diagnostics) except what the environment asks for:

- ``BENCH_FREE_STEP=1``: ``WholeScrew.step`` returns the state of its first step again
  instead of solving.  The schedule steps at the same inputs as the real node (it steps on
  nut angle and time, not on the state), so this node against the thin node is the edge's
  own cost, and against friction_node the model's.
- ``BENCH_NO_PROFILE=1``: no look-ahead profile is computed (the model thread only steps).
- ``BENCH_HANDOFF_ALL=1``: every due step with inputs waiting behind it goes to the model
  thread (the rule before 2026-11-25), not only when the model is behind.
- ``BENCH_NO_DEFER=1``: changed groups and a profile's hand-off right after the stepped
  answer (the rule before 2026-11-25), not when the input thread is idle.
- ``BENCH_SPIN_PROFILE=nogil|py``: every look-ahead profile replaced by about 0.5-0.6 ms
  of CPU, in compiled code without the GIL (``nogil``) or in Python holding it (``py``):
  whether a profile delays the answers through the GIL or by taking a core.
- ``BENCH_TRACE=path``: for every nut_state, the middleware's receipt, the moment the
  schedule got it (``LiveSchedule.on_nut_state``), the moment its answer was published and
  by which thread, and when the node's other work ran (look-ahead profiles, contact groups,
  diagnostics; with its thread's CPU time), written to ``path`` (.npz) when the node stops.

Never a product behaviour: this file lives in bench/ and patches classes in its process.

Run: BENCH_FREE_STEP=1 .venv/bin/python bench/diag_node.py [--ros-args ...]
"""

import atexit
import os
import sys
import threading
import time

import numpy as np

from bb_friction_ros import live, node_entry
from bb_friction_ros.ball_screw.whole_screw import WholeScrew


def _free_step():
    real = WholeScrew.step

    def held_step(self, *args, **kwargs):
        """The first step of this screw (or the one it was copied from), then that again."""
        res = self.__dict__.get("_bench_held_state")
        if res is None:
            res = real(self, *args, **kwargs)
            self._bench_held_state = res
        return res

    WholeScrew.step = held_step


def _no_profile():
    live.LiveSchedule._profile_wanted = lambda self, runner, pred, sample: False


def _trace(path):
    entered = {}        # stamp key: (recv_ns, entered_ns)
    answered = []       # (recv_ns, entered_ns, published_ns, thread, stepped)
    lock = threading.Lock()
    real_on_state = live.LiveSchedule.on_nut_state
    real_finish = live.LiveSchedule._finish

    def on_nut_state(self, stamp_s, names, positions, velocities, recv_ns, stamp,
                     more_waiting=False):
        with lock:
            entered[(stamp.sec, stamp.nanosec)] = (recv_ns, time.time_ns(), bool(more_waiting))
        return real_on_state(self, stamp_s, names, positions, velocities, recv_ns, stamp,
                             more_waiting)

    from bb_friction_ros import node
    real_answer = node.FrictionNode._answer
    published = threading.local()

    def answer(self, *args):
        out = real_answer(self, *args)
        published.t = time.time_ns()       # the answer's own publication, groups apart
        return out

    node.FrictionNode._answer = answer

    def finish(self, runner, pred, recv_ns, stamp, thread):
        published.t = None
        out = real_finish(self, runner, pred, recv_ns, stamp, thread)
        t = published.t or time.time_ns()
        with lock:
            got = entered.pop((stamp.sec, stamp.nanosec), None)
            if got is not None and pred is not None:
                answered.append((got[0], got[1], t, thread, pred.stepped, got[2]))
        return out

    spans = []          # (start_ns, end_ns, kind): other work of the node's threads

    def timed(cls, name, kind):
        real = getattr(cls, name)

        def wrapper(*args, **kwargs):
            t0 = time.time_ns()
            c0 = time.thread_time_ns()
            try:
                return real(*args, **kwargs)
            finally:
                with lock:
                    spans.append((t0, time.time_ns(), kind, time.thread_time_ns() - c0))
        setattr(cls, name, wrapper)

    for cls, name, kind in ((live.LiveSchedule, "_publish_profile", 0),
                            (live.LiveSchedule, "publish_groups", 1),
                            (node.FrictionNode, "_publish_diagnostics", 2)):
        timed(cls, name, kind)

    def dump():
        with lock:
            a = np.array(answered, dtype=np.int64).reshape(-1, 6)
            b = np.array(spans, dtype=np.int64).reshape(-1, 4)
        np.savez(path, recv_ns=a[:, 0], entered_ns=a[:, 1], published_ns=a[:, 2],
                 thread=a[:, 3], stepped=a[:, 4], more_waiting=a[:, 5],
                 span_start_ns=b[:, 0], span_end_ns=b[:, 1], span_kind=b[:, 2],
                 span_cpu_ns=b[:, 3])

    live.LiveSchedule.on_nut_state = on_nut_state
    live.LiveSchedule._finish = finish
    atexit.register(dump)


if os.environ.get("BENCH_FREE_STEP") == "1":
    _free_step()
if os.environ.get("BENCH_NO_PROFILE") == "1":
    _no_profile()
if os.environ.get("BENCH_HANDOFF_ALL") == "1":
    live.LiveSchedule._behind = lambda self, runner, sample, newest: True
if os.environ.get("BENCH_NO_DEFER") == "1":
    live.LiveSchedule.defer_to_idle = property(lambda self: False, lambda self, value: None)
if os.environ.get("BENCH_SPIN_PROFILE"):
    import numba

    @numba.njit(nogil=True, cache=False)
    def _spin(ns):
        acc = 0.0
        for i in range(ns):
            acc += (i % 7) * 1e-9
        return acc

    _spin(10)
    _mode = os.environ["BENCH_SPIN_PROFILE"]

    def _spin_profile(seed, horizon_periods=2.0, n_points=3, should_stop=None):
        if _mode == "nogil":
            _spin(600000)
        else:
            e = time.perf_counter() + 0.0006
            while time.perf_counter() < e:
                pass
        s = seed.sample
        return [s.nut_angle_rad] * n_points, [seed.torque_total_nm] * n_points, True
    live.look_ahead_profile = _spin_profile
if os.environ.get("BENCH_TRACE"):
    _trace(os.environ["BENCH_TRACE"])

if __name__ == "__main__":
    sys.exit(node_entry.main())
