"""
The compiled kernels release the GIL: another Python thread runs while the model solves.

Why it matters: the live node answers inputs in one thread while the model thread is inside
a whole-screw step (``live.py``); a kernel that held the GIL would stall every answer for
the length of a solve.

Two checks.  Every compiled function of the kernel modules is declared ``nogil`` (a new
kernel written with a bare ``numba.njit`` fails it).  And, functionally, a counting thread
makes progress while ``kernel.warm_step`` (the rigid warm step's one compiled call) runs in
another thread: this also catches machine code loaded from a numba cache that was compiled
before the flag was set (numba's cache key does not include the flags).  Not timed: the
count is taken only between "entered" and "left" markers around the compiled call; a
kernel holding the GIL leaves the counter at zero in (almost) every call, a nogil kernel
lets it move in many (measured at load 7 on 2 cores: 10 of 19-24 calls with nogil, 0 of
200 with the kernels compiled without it).  The margin asked for (10 of up to 200 calls)
allows for a loaded machine that does not schedule the counting thread at once.
"""

import math
import sys
import threading

import numba
import pytest

from bb_friction_ros import compiled
from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.linear_bearing import kernel as lb_kernel
from bb_friction_ros.model_file import load_ball_screw

pytestmark = pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")


WANTED = 10          # solves in which the counting thread must have moved
CALLS = 200          # of at most this many
SWITCH_S = 0.05      # the interpreter's forced GIL switch interval during the test [s]


def _dispatchers(module):
    return {name: f for name, f in vars(module).items()
            if isinstance(f, numba.core.registry.CPUDispatcher)}


@pytest.mark.parametrize("module", [compiled, kernel, lb_kernel],
                         ids=["compiled", "ball_screw.kernel", "linear_bearing.kernel"])
def test_every_compiled_function_is_declared_nogil(module):
    found = _dispatchers(module)
    assert found, f"{module.__name__}: no compiled functions found"
    held = sorted(name for name, f in found.items() if not f.targetoptions.get("nogil"))
    assert not held, f"{module.__name__}: compiled without nogil: {held}"


def test_a_python_thread_runs_while_the_warm_step_solves(monkeypatch):
    # 370 balls: a compiled call of a few milliseconds, long enough for the other thread to
    # be scheduled inside it on a loaded machine.
    n = 370
    base = load_ball_screw()
    turns = base.track.loaded_turns * n / base.track.n_balls
    cfg = load_ball_screw(overrides={"track": {"n_balls": n, "loaded_turns": turns}})
    screw = WholeScrew(cfg)
    step = math.radians(3.6)
    omega = 2.0 * math.pi
    load = base.operation.axial_load_n * n / base.track.n_balls
    for k in range(1, 4):                     # cold start, then warm steps
        screw.step(k * step, omega, load, 0.01)

    state = {"inside": False, "count": 0, "stop": False}
    progressed = []
    real = kernel.warm_step

    def watched(*args):
        state["count"] = 0
        state["inside"] = True
        out = real(*args)
        state["inside"] = False
        progressed.append(state["count"] > 0)
        return out

    def count():
        while not state["stop"]:
            if state["inside"]:
                state["count"] += 1

    monkeypatch.setattr(kernel, "warm_step", watched)
    # A long switch interval: the interpreter then hands the GIL to the counter only when the
    # worker releases it (a nogil kernel) or rarely by force (every SWITCH_S).  With the
    # default 5 ms a forced switch often fell inside the dispatcher's own Python code
    # between the "entered" marker and the machine code (argument typing), so a kernel
    # holding the GIL still let the counter move in 5-7 % of the calls (measured).
    interval = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_S)
    counter = threading.Thread(target=count, daemon=True)
    counter.start()
    try:
        # Until the counter has moved inside WANTED solves, at most CALLS solves: a kernel
        # holding the GIL runs all CALLS with (almost) no progress.
        # (Bounded by steps, not by calls seen: a step that no longer goes through the
        # watched call must fail, not loop for ever.)
        for k in range(4, 4 + CALLS):
            if sum(progressed) >= WANTED:
                break
            assert screw.step(k * step, omega, load, 0.01).converged
    finally:
        state["stop"] = True
        counter.join()
        sys.setswitchinterval(interval)
    assert sum(progressed) >= WANTED, \
        f"the counting thread moved in only {sum(progressed)} of {len(progressed)} solves"
