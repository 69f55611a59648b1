"""Benchmark of the discrepancy workflow (issue #6): identification and false-alarm rates.

Random synthetic recordings on one model baseline (the reference trajectory of
``bb_friction_ros.discrepancy.synthetic``, computed once and cached): each has 0, 1 or 2
hidden effects of random physical magnitude (EFFECT_RANGES) and white noise of random level
(NOISE_RANGE_NM).  The workflow runs blind; prints the rates, asserts nothing.

- identification rate: recordings with effects whose selected set equals the hidden set
  (goal >= 90 %);
- false-alarm rate: clean recordings (no effect) that get any term (goal <= 10 %);
- RMSE criterion: held-out RMSE drops by >= 80 % of its reducible part (RMSE before minus
  the realised noise RMS on the held-out part).

Run: .venv/bin/python bench/bench_discrepancy.py [--cases 150] [--clean 60] [--seed 1]
     [--noise-scale 1.0] [--mismatch]

``--mismatch`` is the honest stress test: effects whose shapes are NOT in the library
(shear-thinning viscous drag, exponential Stribeck, linear thermal drift, a third lead
harmonic) and AR(1) coloured noise; the identification then means "the library term closest
to the hidden physics".
"""

import argparse
from collections import Counter
import dataclasses
import os
import time

import numpy as np

from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import (baseline, NOISE_RANGE_NM, random_case,
                                                   reference_trajectory, synthesize)
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.discrepancy.workflow import analyse

REDUCIBLE_SHARE = 0.8
# --mismatch: lag-1 correlation of the coloured noise (a sensor filter / drive ripple).
AR1_COEFFICIENT = 0.5
# --mismatch: exponents of the distorted shapes (library: 1 for viscous, 2 for Stribeck).
SHEAR_THINNING_EXPONENT = 0.8
STRIBECK_MISMATCH_EXPONENT = 1.0
# --mismatch: third lead-error harmonic (the library fits two), fraction of the first.
THIRD_HARMONIC_FRACTION = 0.3


def distorted_torque(term, rec):
    """
    Return a torque like ``term``'s but with a shape outside the library (--mismatch).

    viscous: c |w|^0.8 sign(w) scaled to the same torque at 2 pi rad/s; stribeck: exponent 1;
    thermal: linear in time with the same change at the end of the fit part; lead: a third
    harmonic added; seal and load_dependent: unchanged (already the physical shape).
    """
    x = (rec.t_run_s, rec.nut_angle_rad, rec.nut_velocity_rad_s, rec.axial_load_n)
    w, p = rec.nut_velocity_rad_s, term.param_dict()
    ref_speed = 2.0 * np.pi
    if term.name == "viscous_drag":
        return p["c_nm_s_per_rad"] * ref_speed * (np.abs(w) / ref_speed) \
            ** SHEAR_THINNING_EXPONENT * np.sign(w)
    if term.name == "stribeck":
        return p["torque_nm"] * np.exp(-(np.abs(w) / p["velocity_rad_s"])
                                       ** STRIBECK_MISMATCH_EXPONENT) * np.sign(w)
    if term.name == "thermal_drift":
        t_end = 0.7 * rec.t_run_s[-1]
        end = p["delta_torque_nm"] * -np.expm1(-t_end / p["time_constant_s"])
        return end * rec.t_run_s / t_end * np.sign(w)
    torque = TermSet([term]).torque_nm(*x)
    if term.name == "lead_error":
        amp = THIRD_HARMONIC_FRACTION * np.hypot(p.get("sin1_m", 0.0), p.get("cos1_m", 0.0))
        torque = torque + rec.axial_load_n * 3.0 * amp * np.cos(3.0 * rec.nut_angle_rad)
    return torque


def coloured(noise):
    """Return AR(1) noise with the same marginal std as white ``noise``."""
    out = np.empty_like(noise)
    acc = 0.0
    scale = np.sqrt(1.0 - AR1_COEFFICIENT ** 2)
    for i, e in enumerate(noise):
        acc = AR1_COEFFICIENT * acc + scale * e
        out[i] = acc
    return out


def mismatched(rec, hidden, noise):
    """Return (recording, noise) with distorted effect shapes and coloured noise."""
    effect = sum((distorted_torque(t, rec) for t in hidden.terms), np.zeros(len(rec)))
    noise = coloured(noise)
    return dataclasses.replace(rec, torque_meas_nm=rec.torque_pred_nm + effect + noise), noise


def cache_dir():
    """Return the baseline cache: $BB_FRICTION_CACHE/discrepancy or ~/.cache/..."""
    root = os.environ.get("BB_FRICTION_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "bb_friction_ros")
    return os.path.join(root, "discrepancy")


def rmse_ok(a, noise):
    """Tell whether the held-out RMSE dropped by >= 80 % of its reducible part."""
    hold = ~a.fit_mask
    noise_rms = float(np.sqrt(np.mean(noise[hold] ** 2)))
    reducible = a.rmse_before_nm - noise_rms
    return a.rmse_after_nm <= a.rmse_before_nm - REDUCIBLE_SHARE * reducible, reducible


def main():
    """Run the random cases and print the rates."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=150, help="recordings with 1 or 2 effects")
    ap.add_argument("--clean", type=int, default=60, help="recordings without effects")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise-scale", type=float, default=1.0,
                    help="multiply the noise range (harder cases with > 1)")
    ap.add_argument("--mismatch", action="store_true",
                    help="effect shapes outside the library and AR(1) coloured noise")
    args = ap.parse_args()
    settings = DiscrepancySettings()
    t0 = time.perf_counter()
    base = baseline(reference_trajectory(), cache_dir=cache_dir())
    print(f"baseline: {len(base.recording)} samples, "
          f"{base.recording.t_s[-1] - base.recording.t_s[0]:.1f} s of input "
          f"({time.perf_counter() - t0:.1f} s incl. the model run if not cached)")
    rng = np.random.default_rng(args.seed)
    hits, rmse_pass, per_effect, confusions, times = 0, 0, Counter(), Counter(), []
    seen = Counter()
    for k in range(args.cases):
        rec, hidden, noise, _ = random_case(base, rng, 1 + k % 2)
        if args.noise_scale != 1.0:       # same effects, scaled noise
            rec = dataclasses.replace(rec, torque_meas_nm=rec.torque_meas_nm
                                      + (args.noise_scale - 1.0) * noise)
            noise = noise * args.noise_scale
        if args.mismatch:
            rec, noise = mismatched(rec, hidden, noise)
        t1 = time.perf_counter()
        a = analyse(rec, settings)
        times.append(time.perf_counter() - t1)
        ok = set(a.terms.names) == set(hidden.names)
        hits += ok
        rmse_pass += rmse_ok(a, noise)[0]
        for n in hidden.names:
            seen[n] += 1
            per_effect[n] += n in a.terms.names
        if not ok:
            confusions[(tuple(sorted(hidden.names)), tuple(sorted(a.terms.names)))] += 1
    alarms = 0
    for _ in range(args.clean):
        noise_nm = float(rng.uniform(*NOISE_RANGE_NM)) * args.noise_scale
        rec, noise = synthesize(base, TermSet(), noise_nm, rng)
        if args.mismatch:
            rec, noise = mismatched(rec, TermSet(), noise)
        t1 = time.perf_counter()
        a = analyse(rec, settings)
        times.append(time.perf_counter() - t1)
        alarms += a.verdict != "none"
    print(f"noise std {NOISE_RANGE_NM[0] * args.noise_scale:.3g}-"
          f"{NOISE_RANGE_NM[1] * args.noise_scale:.3g} N m; seed {args.seed}"
          + ("; MISMATCH: shapes outside the library, AR(1) noise" if args.mismatch else ""))
    if args.cases:
        print(f"identification rate: {hits}/{args.cases} = {hits / args.cases:.1%} "
              "(goal >= 90 %)")
        print(f"held-out RMSE drop >= 80 % of reducible: {rmse_pass}/{args.cases} = "
              f"{rmse_pass / args.cases:.1%}")
        print("per effect (named when hidden): " + ", ".join(
            f"{n} {per_effect[n]}/{seen[n]}" for n in sorted(seen)))
    if args.clean:
        print(f"false-alarm rate: {alarms}/{args.clean} = {alarms / args.clean:.1%} "
              "(goal <= 10 %)")
    for (hidden, got), count in confusions.most_common(10):
        print(f"  missed: hidden {list(hidden)} -> selected {list(got)} (x{count})")
    print(f"analysis time per recording: median {np.median(times) * 1e3:.0f} ms, max "
          f"{np.max(times) * 1e3:.0f} ms ({len(base.recording)} samples)")


if __name__ == "__main__":
    main()
