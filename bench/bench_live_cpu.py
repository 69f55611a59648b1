"""
CPU the whole-screw model needs per second of motion, by step size; asserts nothing.

A steady motion at 1500 N, 1 kHz input, is run through the runner exactly as replay and the
live node do (sub-steps included), with every step at ``model_step_deg`` = each size tried.
Prints, per speed and step: the CPU time of this thread per second of motion (what the live
node must find on its core, besides taking and publishing messages), the wall time, and
CPU per step.  CPU time (``time.thread_time``) counts only what this thread ran, so it is
less sensitive to the machine's load than wall time (caches and a shared core still inflate
it); the load average is printed.

``--baseline REF`` (a git ref, as in bench/bench_ball_screw.py): the package as it is at REF
runs the same inputs in the same process, input by input in turn with this version
(alternating which goes first), so that both see the same machine load; printed per speed
and step: CPU per step and per degree of nut rotation of both, their ratio, Newton
iterations per step, and the largest torque difference as a share of the B2B variation.

Run: .venv/bin/python bench/bench_live_cpu.py [--rev-s 1 20] [--seconds 1]
     [--steps-deg 1.8 3.6 7.2 14.4] [--baseline REF]
"""

import argparse
import math
import os
from pathlib import Path
import statistics
import sys
import time

import numpy as np

from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner, InputSample

LOAD_N = 1500.0
RATE_HZ = 1000.0
SETTLE_S = 0.2          # groups' start-up, not timed
STEPS_DEG = (1.8, 3.6, 7.2, 14.4)


def _counting(runner):
    """Count the model steps and Newton iterations of ``runner`` (wraps step, step_path)."""
    screw = runner.screw
    step = screw.step
    counts = [0, 0]

    def counted(*args, **kw):
        r = step(*args, **kw)
        counts[0] += 1
        counts[1] += r.iterations
        return r
    screw.step = counted
    if hasattr(screw, "step_path"):
        path = screw.step_path

        def counted_path(angles, *args, **kw):
            # step_path calls step itself for the steps it does not take in one call:
            # counted here once, as the path's
            before = list(counts)
            r = path(angles, *args, **kw)
            counts[0] = before[0] + len(angles)
            counts[1] = before[1] + r.iterations + r.substep_iterations
            return r
        screw.step_path = counted_path
    return counts


def compare(rev_s, step, seconds, base):
    """This version against the baseline (``base``: its runner module and config path)."""
    w = 2 * math.pi * rev_s
    n_settle, n = int(SETTLE_S * RATE_HZ), int(seconds * RATE_HZ)
    samples = [InputSample(k / RATE_HZ, w * k / RATE_HZ, w, LOAD_N)
               for k in range(n_settle + n)]
    runners = (build_runner(bundled_config("ball_screw.yaml"), 100.0, step, step),
               base[0].build_runner(base[1], 100.0, step, step))
    samples_b = [base[0].InputSample(s.stamp_s, s.nut_angle_rad, s.nut_velocity_rad_s,
                                     s.axial_load_n) for s in samples]
    for s, sb in zip(samples[:n_settle], samples_b[:n_settle]):
        runners[0].process(s)
        runners[1].process(sb)
    counts = [_counting(r) for r in runners]
    cpu = ([], [])
    torque = ([], [])
    b2b = []
    for k in range(n_settle, n_settle + n):
        for j in ((0, 1) if k % 2 else (1, 0)):
            c0 = time.thread_time()
            p = runners[j].process((samples, samples_b)[j][k])
            cpu[j].append(time.thread_time() - c0)
            torque[j].append(p.torque_total_nm)
            if j == 1:
                b2b.append(p.torque_b2b_nm)
    total = [sum(c) for c in cpu]
    per_step = [t / max(c[0], 1) for t, c in zip(total, counts)]
    degrees = rev_s * 360.0 * seconds
    per_deg = [t / degrees for t in total]
    diff = float(np.max(np.abs(np.subtract(*torque)))) / max(float(np.std(b2b)), 1e-300)
    print(f"{rev_s:4g} rev/s, step {step:5.1f} deg: CPU per step {1e6 * per_step[0]:6.1f} us "
          f"(baseline {1e6 * per_step[1]:6.1f}), per degree {1e6 * per_deg[0]:6.1f} us "
          f"(baseline {1e6 * per_deg[1]:6.1f}), baseline / this {per_deg[1] / per_deg[0]:5.2f}x;"
          f" iterations/step {counts[0][1] / max(counts[0][0], 1):.2f} / "
          f"{counts[1][1] / max(counts[1][0], 1):.2f}; median CPU per input "
          f"{1e6 * statistics.median(cpu[0]):.0f} / {1e6 * statistics.median(cpu[1]):.0f} us;"
          f" max |torque difference| {diff:.1e} of the B2B std  (load "
          f"{os.getloadavg()[0]:.1f})", flush=True)


def main():
    """Print one line per speed and step size."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--rev-s", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--seconds", type=float, default=1.0, help="timed motion per run [s]")
    ap.add_argument("--steps-deg", type=float, nargs="+", default=list(STEPS_DEG))
    ap.add_argument("--baseline", help="git ref to compare with, in the same process")
    ap.add_argument("--workdir", default="out/bench_ball_screw",
                    help="where the baseline is extracted (and its numba cache kept)")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    base = None
    if args.baseline:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import importlib
        from bench_ball_screw import BASELINE_PACKAGE, import_baseline
        sha = import_baseline(args.baseline, args.workdir)[0]
        runner_b = importlib.import_module(f"{BASELINE_PACKAGE}.runner")
        config_b = importlib.import_module(f"{BASELINE_PACKAGE}.config")
        base = (runner_b, config_b.bundled_config("ball_screw.yaml"))
        print(f"against {args.baseline} ({sha}), input by input in one process")
    for rev_s in args.rev_s:
        w = 2 * math.pi * rev_s
        n_settle, n = int(SETTLE_S * RATE_HZ), int(args.seconds * RATE_HZ)
        samples = [InputSample(k / RATE_HZ, w * k / RATE_HZ, w, LOAD_N)
                   for k in range(n_settle + n)]
        for step in args.steps_deg:
            if base is not None:
                compare(rev_s, step, args.seconds, base)
                continue
            runner = build_runner(bundled_config("ball_screw.yaml"), 100.0, step, step)
            for s in samples[:n_settle]:
                runner.process(s)
            steps0 = runner.stats.model_steps
            c0, t0 = time.thread_time(), time.perf_counter()
            for s in samples[n_settle:]:
                runner.process(s)
            cpu, wall = time.thread_time() - c0, time.perf_counter() - t0
            steps = runner.stats.model_steps - steps0
            print(f"{rev_s:4.0f} rev/s, step {step:5.1f} deg: CPU {cpu / args.seconds:5.3f} s "
                  f"per s of motion (wall {wall / args.seconds:5.3f} s), "
                  f"{steps / args.seconds:5.0f} steps/s, {1e3 * cpu / max(steps, 1):5.3f} ms "
                  f"CPU per step  (load {os.getloadavg()[0]:.1f})", flush=True)


if __name__ == "__main__":
    main()
