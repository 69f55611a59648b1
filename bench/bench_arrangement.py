"""
The B2B torque against the balls' arrangement: why the feedforward carries its mean.

1. Runs of the bundled screw with theta 3 deg at 1500 N, 1 rev/s, from an even arrangement
   (the model's reset) and from random ones: the mean B2B torque of each revolution.  The
   balls settle into arrangements with few contacts within a few revolutions.
2. The table the feedforward uses (``ball_screw.arrangement.mean_b2b``): the mean over
   random arrangements after the burn-in, at the grid of loads, with its spread over starts,
   and what it took to build.

Usage: .venv/bin/python bench/bench_arrangement.py
"""

import math
import time

import numpy as np

from bb_friction_ros.ball_screw.arrangement import (ArrangementAverage, mean_b2b,
                                                    random_arrangement)
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import bundled_config
from bb_friction_ros.model_file import load_ball_screw


def per_revolution(screw, azimuth, revolutions=6, load=1500.0, step_deg=1.8):
    step = math.radians(step_deg)
    per_rev = int(round(360.0 / step_deg))
    w = 2.0 * math.pi
    screw.reset(0.0)
    if azimuth is not None:
        screw.azimuth = azimuth
    b2b = [screw.step(i * step, w, load, step / w if i else 0.0).torque_b2b_nm
           for i in range(revolutions * per_rev + 1)]
    return [float(np.mean(b2b[1 + r * per_rev:1 + (r + 1) * per_rev]))
            for r in range(revolutions)]


def main():
    cfg = load_ball_screw(bundled_config("ball_screw.yaml"),
                          {"errors": {"theta_amplitude_deg": 3.0}})
    screw = WholeScrew(cfg)
    rng = np.random.default_rng(1)
    print("start    | mean B2B torque per revolution [mN m], revolutions 1..6")
    for name, az in [("even", None)] + [(f"random{i}", random_arrangement(screw, rng))
                                        for i in range(3)]:
        print(f"{name:8s} | " + " ".join(f"{1e3 * v:6.2f}" for v in per_revolution(screw, az)))
    t0 = time.perf_counter()
    m = mean_b2b(cfg, ArrangementAverage(seed=7))      # a seed of its own: built here
    took = time.perf_counter() - t0
    print(f"\nmean over arrangements ({ArrangementAverage().starts} starts, "
          f"{ArrangementAverage().burn_in_revolutions:g} rev burn-in, "
          f"{ArrangementAverage().revolutions:g} rev mean; built in {took:.1f} s)")
    print("|W| N   | total mN m | B2B mN m | B2B spread mN m")
    for load, tot, v, sd in zip(m.loads_n, m.total_nm, m.torque_nm, m.spread_nm):
        print(f"{load:7.0f} | {1e3 * tot:10.2f} | {1e3 * v:8.3f} | {1e3 * sd:15.3f}")
    open_loop(cfg, m)


def open_loop(cfg, m, load=1500.0, step_deg=1.8):
    """A run-in screw against a fresh model along the same rotation: the feedforward's error."""
    step, w = math.radians(step_deg), 2.0 * math.pi
    per_rev = int(round(360.0 / step_deg))

    def run(screw, first, n):
        return np.array([(r.torque_total_nm, r.torque_b2g_nm) for r in (
            screw.step(i * step, w, load, step / w if i else 0.0)
            for i in range(first, first + n))])
    plant = WholeScrew(cfg)
    plant.reset(0.0)
    run(plant, 0, 10 * per_rev)                     # run in over ten revolutions
    truth = run(plant, 10 * per_rev, 4 * per_rev)[:, 0]
    model = WholeScrew(cfg)
    model.reset(0.0)                                # fresh: evenly spaced
    own = run(model, 0, 4 * per_rev)
    print(f"\nopen loop, {load:g} N, four revolutions: a run-in screw (its friction "
          f"{1e3 * truth.mean():.1f} mN m, spread {1e3 * truth.std():.2f}) against the fresh "
          "model's feedforward")
    print("feedforward                         | RMS error mN m")
    averaged = np.full(len(own), m.total_at(load, w))
    for name, ff in (("model state's own (model)", own[:, 0]),
                     ("state's ball-to-groove + mean B2B", own[:, 1] + m.at(load, w)),
                     ("mean over arrangements (averaged)", averaged)):
        print(f"{name:35s} | {1e3 * np.sqrt(np.mean((ff - truth) ** 2)):.3f}")


if __name__ == "__main__":
    main()
