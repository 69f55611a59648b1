"""
CPU the whole-screw model needs per second of motion, by step size; asserts nothing.

A steady motion at 1500 N, 1 kHz input, is run through the runner exactly as replay and the
live node do (sub-steps included), with every step at ``model_step_deg`` = each size tried.
Prints, per speed and step: the CPU time of this thread per second of motion (what the live
node must find on its core, besides taking and publishing messages), the wall time, and
CPU per step.  CPU time (``time.thread_time``) counts only what this thread ran, so it is
less sensitive to the machine's load than wall time (caches and a shared core still inflate
it); the load average is printed.

Run: .venv/bin/python bench/bench_live_cpu.py [--rev-s 1 20] [--seconds 1]
"""

import argparse
import math
import os
import time

from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner, InputSample

LOAD_N = 1500.0
RATE_HZ = 1000.0
SETTLE_S = 0.2          # groups' start-up, not timed
STEPS_DEG = (1.8, 3.6, 7.2, 14.4)


def main():
    """Print one line per speed and step size."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--rev-s", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--seconds", type=float, default=1.0, help="timed motion per run [s]")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    for rev_s in args.rev_s:
        w = 2 * math.pi * rev_s
        n_settle, n = int(SETTLE_S * RATE_HZ), int(args.seconds * RATE_HZ)
        samples = [InputSample(k / RATE_HZ, w * k / RATE_HZ, w, LOAD_N)
                   for k in range(n_settle + n)]
        for step in STEPS_DEG:
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
