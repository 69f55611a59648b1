"""Benchmarks of the linear-bearing models; prints figures, asserts nothing.

Run: .venv/bin/python bench/bench_linear.py

The whole two-ball case (two free balls, the active set, the pair in contact; what
``LinearPairCase.numerical`` and the reproduce report's Table 3 timing row do) is timed
against a thin reference in the same run: the same case solved with MINPACK's hybrd
(``scipy.optimize.fsolve``, finite-difference Jacobian) on the numpy residual.  On a shared
machine only the ratio is comparable between runs; the machine load is printed with it.
"""

import math
import os
import statistics
import tempfile
import time

import numpy as np
from scipy.optimize import fsolve

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


def minpack_whole_case(model, cfg, theta):
    """Thin reference: the whole two-ball case with MINPACK hybrd on the numpy residual."""
    beta = deviated_contact_angles(cfg.nominal_contact_angle_rad, -theta, theta, 0.0, 0.0)
    rho, ny, v = cfg.side_force_ratio, cfg.vertical_load_n, cfg.groove_velocity_m_s
    balls = [model.ball(beta, contact_forces_rigid(beta, s * rho * ny, ny)) for s in (1, -1)]

    def solve(group, z0):
        prep = model._prepare(group)
        z, _, ok, _ = fsolve(lambda z: model._residual(group, z, v, False, prep)[0], z0,
                             xtol=1e-12, full_output=True)
        return z, ok == 1

    free = [solve([b], model.initial_guess([b])) for b in balls]
    if free[0][0][0] <= free[1][0][0]:          # ball 1 (rear) not faster: no contact
        return 0.0
    z0 = np.concatenate([[0.5 * (free[0][0][0] + free[1][0][0])], free[0][0][1:],
                         free[1][0][1:], [0.0]])
    z, _ = solve(balls, z0)
    return z[-1] * cfg.friction_coefficient * model._q_ref(balls)


def whole_case(case, cfg, theta):
    """Whole two-ball case: compiled (default), numpy path and the MINPACK reference."""
    model = case.model
    ref_f = minpack_whole_case(model, cfg, theta)
    ours = case.numerical(theta, cfg.side_force_ratio)
    print(f"whole case F_B2B: ours {ours.f_b2b_n:.6f} N, MINPACK reference {ref_f:.6f} N "
          f"(paper Table 3: 4.01 N)")
    ref, _ = median_time(lambda: minpack_whole_case(model, cfg, theta), 100)
    med, p95 = median_time(lambda: case.numerical(theta, cfg.side_force_ratio), 300)
    model.use_kernel = False
    med_np, _ = median_time(lambda: case.numerical(theta, cfg.side_force_ratio), 100)
    model.use_kernel = True
    print(f"whole case (2 free balls + active set + pair), warm: median {med * 1e3:.3f} ms "
          f"(p95 {p95 * 1e3:.3f}); numpy path {med_np * 1e3:.3f} ms; MINPACK reference "
          f"{ref * 1e3:.3f} ms   [goal <= 1 ms and >= 3x the reference]")
    print(f"  ratio reference / ours: {ref / med:.1f}x; numpy path / ours: {med_np / med:.1f}x;"
          f" machine load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")


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
    whole_case(case, cfg, theta)

    th = np.radians(np.linspace(-3.0, 3.0, 100))[None, :]
    rho = np.linspace(-0.6, 0.6, 100)[:, None]
    med, p95 = median_time(lambda: case.analytical(th, rho), 50)
    print(f"analytical 100x100 theta-rho grid: median {med * 1e3:.3f} ms, "
          f"p95 {p95 * 1e3:.3f} ms   [goal <= 10 ms; paper 6.67 ms per point]")


if __name__ == "__main__":
    main()
