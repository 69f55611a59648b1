"""
Benchmark of the ball screw model (issue #4, item 7); prints figures, asserts nothing.

    .venv/bin/python bench/bench_ball_screw.py [--steps 60]

Two-ball module solve (Table 5, from scratch) and whole-screw warm-started steps for
N = 37, 74, 148, 370 balls (loaded turns scaled with N, same occupancy and theta pattern).
"""

import argparse
import math
import statistics
import time

import numpy as np

from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.ball_screw.parameters import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew


def bench_pair(model, repeats):
    """Median wall time of a complete two-ball solve (free + with B2B), cases (a), (b)."""
    out = {}
    for th in (2.0, 3.0):
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            solve_two_ball_module(model, 0.0, math.radians(th), 50.0)
            times.append(time.perf_counter() - t0)
        out[th] = statistics.median(times)
    return out


def bench_screw(model, n_balls, steps):
    """Median warm step time, iterations and per-iteration time for ``n_balls`` balls."""
    base = model.config
    turns = base.track.loaded_turns * n_balls / base.track.n_balls
    cfg = load_ball_screw(overrides={"track": {"n_balls": n_balls, "loaded_turns": turns}})
    screw = WholeScrew(cfg, model)
    op = cfg.operation
    dt = op.duration_s / op.n_steps
    times, iters, groups = [], [], []
    for k in range(1, steps + 1):
        r = screw.step(op.nut_speed_rad_s * k * dt, op.nut_speed_rad_s,
                       op.axial_load_n * n_balls / base.track.n_balls, dt)
        if k > 1:                       # the first step is the cold start
            times.append(r.solve_time_s)
            iters.append(r.iterations)
            groups.append(r.n_groups)
    med = statistics.median(times)
    per_it = np.array(times) / np.maximum(np.array(iters), 1)
    return med, statistics.median(iters), float(np.median(per_it)), max(groups)


def main():
    """Print the benchmark table."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--steps", type=int, default=60, help="whole-screw steps per N")
    p.add_argument("--repeats", type=int, default=7, help="two-ball repeats")
    args = p.parse_args()
    model = ScrewModel(load_ball_screw())
    pair = bench_pair(model, args.repeats)
    print("two-ball module (Table 5), full solve from scratch, median:")
    for th, t in pair.items():
        print(f"  theta2 = {th:g} deg: {1e3 * t:7.2f} ms   (target <= 20 ms; paper 15.3 s)")
    print(f"whole screw, warm-started step, {args.steps} steps of 3.6 deg, median:")
    print("      N   step [ms]  iterations  per iteration [ms]  max groups")
    for n in (37, 74, 148, 370):
        med, it, per_it, g = bench_screw(model, n, args.steps)
        print(f"  {n:5d}   {1e3 * med:8.2f}   {it:9.1f}   {1e3 * per_it:12.3f}       {g:4d}"
              f"    (per ball {1e6 * med / n:.1f} us)")


if __name__ == "__main__":
    main()
