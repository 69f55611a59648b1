"""
Feedforward accuracy at 1 kHz: zero-order hold vs the look-ahead profile.

Asserts nothing; prints the table.

Input: a 1 kHz nut-state stream at constant speed (1, 5, 10, 20 rev/s) with the axial load
varying as 1500 + 300 sin(2 pi 2 t) N.  Ground truth: the whole-screw model stepped at every
input sample, offline (ModelRunner at 1 kHz).  Compared against it, at every sample after the
first ``--settle`` seconds:

(a) ZOH: what friction_node answers today, the 100 Hz model state held between steps
    (ModelRunner at 100 Hz, the node's prediction for each sample);
(b) profile: the FeedforwardProfile of each 100 Hz step (node defaults: 3 points over 2
    periods), usable by the controller from t_step + latency on, where latency = the
    step's and look-ahead's measured wall time here + ``--transport-ms`` (DDS hop, measured by
    bench/bench_node.py); interpolated at the sample's measured angle by
    FeedforwardInterpolator, as a controller would;
(c) profile with ``--points-c`` points and load scaling (FeedforwardInterpolator's
    ``scale_with_load``: quasi-static Coulomb friction follows the axial load between steps).

Reports the RMS error in N m and as a share of the ground truth's B2B torque RMS, and the
ratio (b)/(a) and (c)/(a).  Also the "floor": the RMS of (a) at the samples where the 100 Hz
model has just stepped (no hold, no latency): what a 100 Hz model differs from a 1 kHz one at
the same input, because the balls' history depends on the step size.  No way of holding or
interpolating the 100 Hz model's output can get below it.

Run: .venv/bin/python bench/bench_feedforward.py [--speeds 1 5 10 20] [--duration 0.6]
"""

import argparse
import json
import math
import os
import time

import numpy as np

from bb_friction_ros.config import bundled_config
from bb_friction_ros.feedforward import FeedforwardInterpolator
from bb_friction_ros.runner import build_runner, InputSample, look_ahead_profile

RATE_HZ = 1000.0


def samples(rev_s, duration_s, t0=1000.0):
    """The 1 kHz input stream."""
    w = 2.0 * math.pi * rev_s
    out = []
    for k in range(int(duration_s * RATE_HZ)):
        t = k / RATE_HZ
        out.append(InputSample(t0 + t, w * t, w, 1500.0 + 300.0 * math.sin(2 * math.pi * 2 * t)))
    return out


def profiled(runner, stream, horizon, points, transport_s, fixed_latency_s=None):
    """(ZOH predictions, [(available-from stamp, profile)]) of a 100 Hz runner."""
    runner.reset()
    preds, profiles = [], []
    for s in stream:
        t0 = time.perf_counter()
        p = runner.process(s)
        preds.append(p)
        if p.stepped:
            prof = look_ahead_profile(runner.profile_seed(s), horizon, points)
            latency = time.perf_counter() - t0 + transport_s if fixed_latency_s is None \
                else fixed_latency_s
            profiles.append((s.stamp_s + latency, prof, s))
    return preds, profiles


def interpolate(stream, profiles, scale_with_load, max_axial_load_n=None):
    """The controller's torque at every sample from the newest profile it would have."""
    ff = FeedforwardInterpolator(scale_with_load=scale_with_load,
                                 max_axial_load_n=max_axial_load_n)
    out, j = [], 0
    for s in stream:
        while j < len(profiles) and profiles[j][0] <= s.stamp_s:
            (angles, torques, ok), src = profiles[j][1], profiles[j][2]
            ff.set_profile(angles, torques, src.nut_velocity_rad_s, src.axial_load_n, ok)
            j += 1
        out.append(ff.torque_at(s.nut_angle_rad, s.nut_velocity_rad_s, s.axial_load_n))
    return np.array(out)


def main():
    """Print the table; optionally write JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 5.0, 10.0, 20.0])
    ap.add_argument("--duration", type=float, default=0.6, help="input seconds per speed")
    ap.add_argument("--settle", type=float, default=0.1, help="seconds left out at the start")
    ap.add_argument("--transport-ms", type=float, default=1.0)
    ap.add_argument("--latency-ms", type=float, help="fixed profile latency instead of the "
                    "measured compute time + transport (the live node's, from bench_node)")
    ap.add_argument("--points-b", type=int, default=3)
    ap.add_argument("--points-c", type=int, default=5)
    ap.add_argument("--horizon-periods", type=float, default=2.0)
    ap.add_argument("--json")
    args = ap.parse_args()
    cfg = bundled_config("ball_screw.yaml")
    truth_runner = build_runner(cfg, RATE_HZ)
    node_runner = build_runner(cfg, 100.0)
    rows = []
    print(f"load {os.getloadavg()[0]:.1f}; RMS error vs the model stepped at every 1 kHz "
          "sample, N m (share of the B2B torque RMS)")
    print(f"{'rev/s':>6} {'B2B RMS':>9} {'(a) ZOH 100 Hz':>22} {'(b) profile':>22} "
          f"{'(c) profile+load':>22} {'b/a':>6} {'c/a':>6} {'latency ms':>10} "
          f"{'floor':>22}")
    for rev_s in args.speeds:
        stream = samples(rev_s, args.duration)
        truth_runner.reset()
        truth = [truth_runner.process(s) for s in stream]
        fixed = None if args.latency_ms is None else 1e-3 * args.latency_ms
        zoh, prof_b = profiled(node_runner, stream, args.horizon_periods, args.points_b,
                               1e-3 * args.transport_ms, fixed)
        _, prof_c = profiled(node_runner, stream, args.horizon_periods, args.points_c,
                             1e-3 * args.transport_ms, fixed)
        keep = np.array([s.stamp_s - stream[0].stamp_s >= args.settle for s in stream])
        ref = np.array([p.torque_total_nm for p in truth])[keep]
        b2b_rms = float(np.sqrt(np.mean(np.array([p.torque_b2b_nm for p in truth])[keep] ** 2)))
        est = {"a": np.array([p.torque_total_nm for p in zoh])[keep],
               "b": interpolate(stream, prof_b, False)[keep],
               "c": interpolate(stream, prof_c, True,
                                node_runner.screw.max_axial_load_n)[keep]}
        rms = {k: float(np.sqrt(np.mean((v - ref) ** 2))) for k, v in est.items()}
        at_step = np.array([p.stepped for p in zoh])[keep]
        rms["floor"] = float(np.sqrt(np.mean((est["a"] - ref)[at_step] ** 2)))
        lat = float(np.median([(p[0] - p[2].stamp_s) for p in prof_b]) * 1e3)
        ok = all(p.converged for p in truth)
        row = {"rev_s": rev_s, "b2b_rms_nm": b2b_rms, "rms_nm": rms, "latency_ms_p50": lat,
               "truth_converged": ok, "profile_points_b": args.points_b,
               "profile_points_c": args.points_c}
        rows.append(row)

        def cell(k):
            return f"{rms[k]:.2e} ({100 * rms[k] / b2b_rms:5.1f} %)"
        print(f"{rev_s:6.0f} {b2b_rms:9.2e} {cell('a'):>22} {cell('b'):>22} {cell('c'):>22} "
              f"{rms['b'] / rms['a']:6.2f} {rms['c'] / rms['a']:6.2f} {lat:10.1f} "
              f"{cell('floor'):>22}"
              + ("" if ok else "  (ground truth had non-converged steps)"), flush=True)
    print(f"load at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
