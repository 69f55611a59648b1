"""Benchmarks of the linear-bearing models (issue #3); prints figures, asserts nothing.

Run: .venv/bin/python bench/bench_linear.py
"""

import math
import statistics
import tempfile
import time

import numpy as np

from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.contact import friction_maps
from bb_friction_ros.linear_bearing.case_study import LinearPairCase
from bb_friction_ros.linear_bearing.geometry import (contact_forces_rigid,
                                                     deviated_contact_angles)


def median_time(fn, repeat):
    """Median wall time of ``repeat`` calls after 10 warm-up calls  [s]."""
    for _ in range(10):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), np.percentile(times, 95)


def main():
    """Print map build time, two-ball solve times and analytical grid time."""
    cfg = load_linear_bearing()
    case = LinearPairCase(cfg)
    k = case.hertz().ellipticity
    with tempfile.TemporaryDirectory() as tmp:
        import os
        os.environ["BB_FRICTION_CACHE"] = tmp
        t0 = time.perf_counter()
        friction_maps.FrictionMapLine(k, n_nodes=cfg.map_nodes)
        build = time.perf_counter() - t0
        t0 = time.perf_counter()
        friction_maps.FrictionMapLine(k, n_nodes=cfg.map_nodes)
        cached = time.perf_counter() - t0
    print(f"friction map (line, {cfg.map_nodes} nodes): build {build:.3f} s, "
          f"from disk cache {cached * 1e3:.1f} ms   [goal: build <= 2 s or cached]")

    model = case.model
    theta = math.radians(2.0)
    beta = deviated_contact_angles(cfg.nominal_contact_angle_rad, -theta, theta, 0.0, 0.0)
    balls = [model.ball(beta, contact_forces_rigid(beta, r * cfg.vertical_load_n,
                                                   cfg.vertical_load_n)) for r in (-0.6, 0.6)]
    med, p95 = median_time(lambda: model.solve_group(balls), 500)
    print(f"two-ball B2B numerical solve (cold start): median {med * 1e3:.3f} ms, "
          f"p95 {p95 * 1e3:.3f} ms   [goal <= 1 ms; paper MATLAB 0.74 s]")
    warm = model.solve_group(balls).z
    med, p95 = median_time(lambda: model.solve_group(balls, z0=warm), 500)
    print(f"two-ball B2B numerical solve (warm start): median {med * 1e3:.3f} ms, "
          f"p95 {p95 * 1e3:.3f} ms")
    med, _ = median_time(lambda: case.numerical(theta, cfg.side_force_ratio), 200)
    print(f"whole case (2 free balls + active set + pair): median {med * 1e3:.3f} ms")

    th = np.radians(np.linspace(-3.0, 3.0, 100))[None, :]
    rho = np.linspace(-0.6, 0.6, 100)[:, None]
    med, p95 = median_time(lambda: case.analytical(th, rho), 50)
    print(f"analytical 100x100 theta-rho grid: median {med * 1e3:.3f} ms, "
          f"p95 {p95 * 1e3:.3f} ms   [goal <= 10 ms; paper 6.67 ms per point]")


if __name__ == "__main__":
    main()
