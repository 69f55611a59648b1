"""
The whole-screw warm step against a previous version, in one process; prints, asserts nothing.

    .venv/bin/python bench/bench_warm_step.py [--baseline main] [--rev-s 1 20]
        [--seconds 1.0] [--rounds 3] [--calls path|step]

N = 37 at 1500 N and 1.8 deg steps (the node's and replay's default), rigid and elastic,
stepped as the schedule steps a steady rotation read at 1 kHz: at 20 rev/s an input is
7.2 deg, so three sub-steps (``substep=True``, solved to ``solver.substep_tolerance``) and
one answered step per input; at 1 rev/s one answered step every fifth input.

The baseline is the package as it is at a git ref (default ``main``), extracted from git
into out/bench_warm_step/ under another package name (``bench_ball_screw.import_baseline``;
its numba cache is kept there, so only the first run compiles it).  Both screws take the
same motion; each input's steps are taken by one screw then the other, alternating which
goes first, so both see the same load of this shared machine.  This version takes an
input's steps in one ``WholeScrew.step_path`` call (``--calls path``, as the runner does;
its CPU per step is the call's shared out over its steps) or step by step (``--calls
step``).  Printed per case: the median
thread CPU per step of each, the median over rounds of the ratio of their mean CPU per step,
Newton iterations per step of each, and the largest difference of the total torque relative
to the range of the B2B torque along the run.  The first 0.2 s of motion (cold start, the
groups forming) are not timed.
"""

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ball_screw import import_baseline  # noqa: E402

STEP_DEG = 1.8
INPUT_HZ = 1000.0
LOAD_N = 1500.0
SETTLE_S = 0.2


def inputs(rev_s, seconds):
    """Per 1 kHz input: the list of (angle, substep) steps the schedule takes to reach it."""
    w = 2.0 * math.pi * rev_s
    step = math.radians(STEP_DEG)
    out = []
    done = 0.0
    for k in range(1, int(round(seconds * INPUT_HZ)) + 1):
        angle = w * k / INPUT_HZ
        n = int(math.floor((angle - done) / step + 1e-9))
        if n < 1:
            continue
        todo = angle - done
        n = max(1, math.ceil(todo / step - 1e-9))
        out.append([(done + todo * i / n, i < n) for i in range(1, n + 1)])
        done = angle
    return w, out


def run_case(screws, rev_s, seconds, path=False):
    """
    One round: each screw's CPU per step, iterations and torques of the answered steps.

    With ``path`` this version takes each input's steps in one ``WholeScrew.step_path`` call
    (its CPU and iterations shared out evenly over them), the baseline step by step.
    """
    w, plan = inputs(rev_s, seconds)
    dt = math.radians(STEP_DEG) / w
    cpu = ([], [])
    its = ([], [])
    torque = ([], [])
    b2b = ([], [])
    for m, steps in enumerate(plan):
        timed = steps[0][0] / w > SETTLE_S
        for j in ((0, 1) if m % 2 else (1, 0)):
            if path and j == 0:
                c0 = time.thread_time()
                r = screws[0].step_path([a for a, _ in steps], [w] * len(steps),
                                        [LOAD_N] * len(steps), dt)
                c1 = time.thread_time()
                if timed:
                    k = len(steps)
                    cpu[0].extend([(c1 - c0) / k] * k)
                    its[0].extend([(r.iterations + r.substep_iterations) / k] * k)
                    torque[0].append(r.torque_total_nm)
                    b2b[0].append(r.torque_b2b_nm)
                continue
            for angle, sub in steps:
                c0 = time.thread_time()
                r = screws[j].step(angle, w, LOAD_N, dt, substep=sub)
                c1 = time.thread_time()
                if timed:
                    cpu[j].append(c1 - c0)
                    its[j].append(r.iterations)
                    if not sub:
                        torque[j].append(r.torque_total_nm)
                        b2b[j].append(r.torque_b2b_nm)
    return cpu, its, torque, b2b


def main():
    """Print one line per speed and load distribution."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--baseline", default="main", help="git ref to compare with")
    ap.add_argument("--rev-s", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--seconds", type=float, default=1.0, help="motion per round [s]")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--calls", choices=("path", "step"), default="path",
                    help="this version's calls: one step_path per input (as the runner "
                         "steps) or one step per step (as the baseline)")
    ap.add_argument("--workdir", default="out/bench_warm_step",
                    help="where the baseline is extracted (and its numba cache kept)")
    args = ap.parse_args()
    sha, old_screw, old_load = import_baseline(args.baseline, args.workdir)
    print(f"warm step, N = 37, {STEP_DEG} deg, {LOAD_N:g} N, 1 kHz input; this version "
          f"against {args.baseline} ({sha}), alternated input by input in one process; "
          f"this version's calls: {args.calls}")
    print(f"load average at start {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print("  rev/s  load path  CPU per step [us] this / baseline (median)  "
          "ratio of means (median over rounds)  iterations per step this / baseline  "
          "max |dT| / B2B range")
    for rev_s in args.rev_s:
        for dist in ("rigid", "elastic"):
            over = {"load_distribution": dist}
            ratios, med, its, dmax = [], ([], []), ([], []), 0.0
            for _ in range(args.rounds):
                screws = (WholeScrew(load_ball_screw(overrides=over)),
                          old_screw(old_load(overrides=over)))
                cpu, it, torque, b2b = run_case(screws, rev_s, args.seconds,
                                                args.calls == "path")
                ratios.append(statistics.mean(cpu[1]) / statistics.mean(cpu[0]))
                for j in (0, 1):
                    med[j].append(statistics.median(cpu[j]) * 1e6)
                    its[j].extend(it[j])
                span = max(np.ptp(b2b[1]), 1e-300)
                dmax = max(dmax, float(np.max(np.abs(np.subtract(*torque)))) / span)
            print(f"  {rev_s:5g}  {dist:9s}  {statistics.median(med[0]):7.1f} / "
                  f"{statistics.median(med[1]):7.1f}                        "
                  f"{statistics.median(ratios):5.2f}x ({', '.join(f'{r:.2f}' for r in ratios)})"
                  f"      {statistics.mean(its[0]):.3f} / {statistics.mean(its[1]):.3f}"
                  f"                 {dmax:.1e}", flush=True)
    print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
