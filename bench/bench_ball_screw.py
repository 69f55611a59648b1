"""
Benchmark of the ball screw model (issue #4, item 7); prints figures, asserts nothing.

    .venv/bin/python bench/bench_ball_screw.py [--steps 60] [--numpy]

Two-ball module solve (Table 5, from scratch) and whole-screw warm-started steps for
N = 37, 74, 148, 370 balls (loaded turns scaled with N, same occupancy and theta pattern),
then the real-time mode (iteration cap) for N = 37.  ``--numpy`` runs the numpy solver path
(lagged B2B Jacobian, no numba) instead of the compiled kernel, for comparison.  Wall times
on a shared machine vary by +-20 %: compare runs made back to back.
"""

import argparse
import math
import statistics
import time

import numpy as np

from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.model_file import load_ball_screw
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


def bench_screw(model, n_balls, steps, realtime=0):
    """Median warm step time, iterations and per-iteration time for ``n_balls`` balls."""
    base = model.config
    turns = base.track.loaded_turns * n_balls / base.track.n_balls
    cfg = load_ball_screw(overrides={"track": {"n_balls": n_balls, "loaded_turns": turns},
                                     "solver": {"realtime_max_iterations": realtime}})
    screw = WholeScrew(cfg, model)
    op = cfg.operation
    dt = op.duration_s / op.n_steps
    times, iters, groups, conv = [], [], [], []
    for k in range(1, steps + 1):
        r = screw.step(op.nut_velocity_rad_s * k * dt, op.nut_velocity_rad_s,
                       op.axial_load_n * n_balls / base.track.n_balls, dt)
        if k > 1:                       # the first step is the cold start
            times.append(r.solve_time_s)
            iters.append(r.iterations)
            groups.append(r.n_groups)
            conv.append(r.converged)
    times, iters = np.array(times), np.array(iters)
    return {"median": float(np.median(times)), "p95": float(np.percentile(times, 95)),
            "it_median": float(np.median(iters)), "it_mean": float(iters.mean()),
            "per_it": float(np.median(times / np.maximum(iters, 1))),
            "groups": max(groups), "unconverged": int(len(conv) - sum(conv))}


def main():
    """Print the benchmark table."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--steps", type=int, default=60, help="whole-screw steps per N")
    p.add_argument("--repeats", type=int, default=7, help="two-ball repeats")
    p.add_argument("--numpy", action="store_true", help="numpy solver path (no kernel)")
    args = p.parse_args()
    model = ScrewModel(load_ball_screw())
    if args.numpy:
        model.solver.use_kernel = False
    print("solver:", "numpy path" if not model.solver.use_kernel else "compiled kernel")
    pair = bench_pair(model, args.repeats)
    print("two-ball module (Table 5), full solve from scratch, median:")
    for th, t in pair.items():
        print(f"  theta2 = {th:g} deg: {1e3 * t:7.2f} ms   (target <= 20 ms; paper 15.3 s)")
    print(f"whole screw, warm-started step, {args.steps} steps of 3.6 deg:")
    print("      N   median [ms]  p95 [ms]  iterations (median/mean)  per iteration [ms]"
          "  max groups")
    for n in (37, 74, 148, 370):
        r = bench_screw(model, n, args.steps)
        print(f"  {n:5d}   {1e3 * r['median']:9.3f}  {1e3 * r['p95']:8.3f}"
              f"  {r['it_median']:10.1f} / {r['it_mean']:4.2f}"
              f"  {1e3 * r['per_it']:17.3f}  {r['groups']:10d}"
              f"    (per ball {1e6 * r['median'] / n:.1f} us)")
    print("real-time mode (solver.realtime_max_iterations), N = 37:")
    for cap in (4, 6):
        r = bench_screw(model, 37, args.steps, realtime=cap)
        print(f"  cap {cap}: median {1e3 * r['median']:.3f} ms, p95 {1e3 * r['p95']:.3f} ms,"
              f" unconverged (flagged) {r['unconverged']}/{args.steps - 1}")


if __name__ == "__main__":
    main()
