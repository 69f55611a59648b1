"""
What one look-ahead profile costs, by the largest step its model copy takes; asserts nothing.

A 20 rev/s (and a 1 rev/s) motion at 1500 N is run through the runner as 1 kHz input, and
copies of its states after 40 steps are stepped over the default look-ahead horizon (2 model
periods of motion: 144 deg at 20 rev/s) in equal steps no longer than each size tried.
Prints ms per profile and per step (the longest time the live node's model thread cannot
give way to a due step) with the machine's load: absolute times are noisy on a shared
2-core machine; compare sizes within one run.

Run: .venv/bin/python bench/bench_profile.py
"""

import copy
import math
import os
import time

from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner, InputSample, profile_horizon_rad

LOAD_N = 1500.0
SIZES_DEG = (72.0, 36.0, 14.4, 7.2, 3.6, 1.8)


def main():
    """Print one line per speed and largest step."""
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    for rev_s in (1.0, 20.0):
        w = 2 * math.pi * rev_s
        runner = build_runner(bundled_config("ball_screw.yaml"), 100.0, 1.8, 14.4)
        seeds = []
        for k in range(1200):
            s = InputSample(1e-3 * k, w * 1e-3 * k, w, LOAD_N)
            if runner.process(s).stepped and k > 200:      # past the groups' start-up
                seeds.append(runner.profile_seed(s))
        seeds = seeds[::max(1, len(seeds) // 40)][:40]
        horizon = profile_horizon_rad(seeds[0], 2.0)
        for size_deg in SIZES_DEG:
            n = max(1, math.ceil(horizon / math.radians(size_deg) - 1e-9))
            if size_deg != SIZES_DEG[0] and n == 1:
                continue
            t0 = time.perf_counter()
            for seed in seeds:
                screw = copy.copy(seed.screw)
                a0 = seed.sample.nut_angle_rad
                for j in range(1, n + 1):
                    screw.step(a0 + horizon * j / n, w, LOAD_N, horizon / n / w)
            ms = 1e3 * (time.perf_counter() - t0) / len(seeds)
            print(f"{rev_s:4.0f} rev/s, horizon {math.degrees(horizon):6.1f} deg in {n:3d} "
                  f"steps of <= {size_deg:5.1f} deg: {ms:7.2f} ms per profile, "
                  f"{ms / n:6.2f} ms per step  (load {os.getloadavg()[0]:.1f})", flush=True)


if __name__ == "__main__":
    main()
