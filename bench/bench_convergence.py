"""
Convergence study of the model-step schedule: error against a fine-step reference.

Asserts nothing; prints the table the default ``model_step_deg`` was chosen from.

Input: steady rotation at ``--load`` N (1500) at each speed (1, 5, 10, 20, 40 rev/s), as a
1 kHz nut-state stream (the node's and replay's input).  Each schedule is run through
``ModelRunner`` exactly as replay runs it (the live node is the same when it keeps up), and
its prediction at every 1 kHz sample (what the node publishes: the latest state, held) is
compared with a reference at the same nut angle.

Reference: the same whole-screw model stepped along the same angle path every
``--ref-deg`` (0.18 deg: 2000 steps per revolution; the 1 kHz angles are multiples of it, so
the reference has a step at every compared angle).  A second reference at twice that step
shows how far the reference itself is converged (the criterion: the two references agree
within 4 %).

Error: RMS over the samples after ``--settle-rev`` revolutions, as a share of the B2B
variation: the standard deviation of the reference's B2B torque over the same samples (the
ripple the schedule is meant to resolve).  "old": the time schedule used before the angle
schedule (a step every 10 ms of input time, at reversals; ``model_step_deg`` out of the
way).  The other rows are angle schedules with the 100 Hz time floor.  The CPU column is
the model's share of one core at that speed: steps per second of input times the measured
mean step time (this machine, this load; bench/bench_ball_screw.py for the step itself).

Run: .venv/bin/python bench/bench_convergence.py [--speeds 1 5 10 20 40]
     [--steps-deg 1.8 3.6 7.2] [--revs 6] [--json out.json]
"""

import argparse
import json
import math
import os
import time

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import bundled_config
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.runner import InputSample, ModelRunner

INPUT_RATE_HZ = 1000.0
OLD_RATE_HZ = 100.0          # the time schedule's default before the angle schedule
NO_ANGLE_STEP_DEG = 1e9      # an angle step never reached: the time schedule alone


def stream(rev_s, revs, ref_deg, load_n, t0=1000.0):
    """
    The 1 kHz input and the reference's angle path, on one grid of ``ref_deg`` increments.

    Returns (samples, reference samples, index of each input sample in the reference).
    """
    w = 2.0 * math.pi * rev_s
    per_sample = rev_s * 360.0 / INPUT_RATE_HZ / ref_deg    # reference steps per input
    m = int(round(per_sample))
    if m < 1 or abs(per_sample - m) > 1e-9:
        raise SystemExit(f"{rev_s} rev/s: the 1 kHz angles are not multiples of {ref_deg} deg")
    d = math.radians(ref_deg)
    n_ref = int(round(revs * 360.0 / ref_deg)) + 1
    dt = 1.0 / (INPUT_RATE_HZ * m)
    ref = [InputSample(t0 + i * dt, i * d, w, load_n) for i in range(n_ref)]
    idx = list(range(0, n_ref, m))
    return [ref[i] for i in idx], ref, np.array(idx)


def run(runner, samples):
    """Predictions of ``samples`` (replay's path) and the mean wall time of a model step."""
    runner.reset()
    steps0 = runner.stats.model_steps
    t0 = time.perf_counter()
    preds = [runner.process(s) for s in samples]
    wall = time.perf_counter() - t0
    n_steps = runner.stats.model_steps - steps0
    return preds, wall / max(n_steps, 1), n_steps


def make_runner(cfg, terms, rate_hz, step_deg, ref=False):
    # The reference answers every sample from its own step (its inputs are a step apart or
    # less, so the schedule's answer-first rule would make it lag a step).
    r = ModelRunner(WholeScrew(cfg), rate_hz, terms if len(terms) else None,
                    model_step_deg=step_deg, max_model_step_deg=max(step_deg, 36.0),
                    step_after_answer_fraction=0.0 if ref else None)
    r.warm_up(1500.0, 1.0)
    return r


def main():
    """Print the table; optionally write JSON."""
    default = NodeParameters()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 5.0, 10.0, 20.0, 40.0])
    ap.add_argument("--steps-deg", type=float, nargs="+",
                    default=sorted({default.model_step_deg, 1.8, 7.2}),
                    help="angle schedules to compare (the default is always included)")
    ap.add_argument("--revs", type=float, default=6.0, help="revolutions per speed")
    ap.add_argument("--settle-rev", type=float, default=1.0,
                    help="revolutions left out at the start (the groups form)")
    ap.add_argument("--ref-deg", type=float, default=0.18)
    ap.add_argument("--load", type=float, default=1500.0)
    ap.add_argument("--check-ref-at", type=float, default=10.0,
                    help="speed at which a reference of twice --ref-deg is compared too")
    ap.add_argument("--config", default=bundled_config("ball_screw.yaml"))
    ap.add_argument("--json")
    args = ap.parse_args()
    cfg, terms = load_model_file(args.config)
    steps = sorted(set(args.steps_deg) | {default.model_step_deg})
    schedules = [("old 100 Hz", OLD_RATE_HZ, NO_ANGLE_STEP_DEG)] + [
        (f"{s:g} deg" + (" (default)" if s == default.model_step_deg else ""),
         default.model_rate_hz, s) for s in steps]
    print(f"load average {os.getloadavg()[0]:.2f}; RMS error vs a {args.ref_deg:g} deg "
          f"reference at equal nut angles, as a share of the reference's B2B variation "
          f"(std); {args.load:g} N; CPU = share of one core for the model at that speed")
    header = f"{'rev/s':>6} {'B2B std N m':>12}" + "".join(
        f" {name:>22}" for name, _, _ in schedules)
    print(header)
    rows = []
    for rev_s in args.speeds:
        samples, ref_samples, idx = stream(rev_s, args.revs, args.ref_deg, args.load)
        ref_runner = make_runner(cfg, terms, default.model_rate_hz, args.ref_deg, True)
        ref_preds, ref_step_s, _ = run(ref_runner, ref_samples)
        keep = np.array([s.nut_angle_rad >= 2 * math.pi * args.settle_rev for s in samples])
        ref_total = np.array([ref_preds[i].torque_total_nm for i in idx])[keep]
        ref_b2b = np.array([ref_preds[i].torque_b2b_nm for i in idx])[keep]
        variation = float(np.std(ref_b2b))
        row = {"rev_s": rev_s, "b2b_std_nm": variation, "ref_deg": args.ref_deg,
               "ref_converged": all(p.converged for p in ref_preds), "schedules": {}}
        cells = []
        for name, rate, step in schedules:
            runner = make_runner(cfg, terms, rate, step)
            preds, step_s, n_steps = run(runner, samples)
            est = np.array([p.torque_total_nm for p in preds])[keep]
            err = float(np.sqrt(np.mean((est - ref_total) ** 2)))
            steps_per_s = n_steps / (len(samples) / INPUT_RATE_HZ)
            share = err / variation
            row["schedules"][name] = {"model_step_deg": step, "model_rate_hz": rate,
                                      "rms_error_nm": err, "share_of_b2b_variation": share,
                                      "steps_per_s": steps_per_s, "step_s": step_s,
                                      "cpu_share": steps_per_s * step_s}
            cells.append(f"{share:5.2f} {steps_per_s:5.0f}/s {100 * steps_per_s * step_s:4.0f}%")
        print(f"{rev_s:6g} {variation:12.3e}" + "".join(f" {c:>22}" for c in cells)
              + ("" if row["ref_converged"] else "  (reference had non-converged steps)"),
              flush=True)
        if rev_s == args.check_ref_at:
            r2 = make_runner(cfg, terms, default.model_rate_hz, 2 * args.ref_deg, True)
            preds2, _, _ = run(r2, ref_samples)
            est2 = np.array([preds2[i].torque_total_nm for i in idx])[keep]
            agree = float(np.sqrt(np.mean((est2 - ref_total) ** 2))) / variation
            row["reference_check"] = {"ref2_deg": 2 * args.ref_deg, "share": agree}
            print(f"{'':6} reference check at {rev_s:g} rev/s: {2 * args.ref_deg:g} deg vs "
                  f"{args.ref_deg:g} deg reference differ by {agree:.3f} of the B2B "
                  "variation", flush=True)
        rows.append(row)
    print("cells: error share, model steps per second, CPU share of one core")
    print(f"load at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
