"""Benchmark of the discrepancy workflow: synthetic rates, measured drives, speed.

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
     [--noise-scale 1.0] [--mismatch] [--no-realdata] [--no-speed] [--memory]

Besides the synthetic set (which draws the later library terms too: inertia, offset,
the two asymmetries, angle_ripple), every run prints:
- **measured drives** (RViMLab, MIT licence; Mablekos-Alexiou, da Cruz, Bergeles, IEEE T-RO
  37(4) 2021), from ``$BB_FRICTION_REALDATA`` or ``../shared/realdata``: per drive the terms
  named, the held-out RMSE before/after, and on the validation runs the relative error of
  the augmented model against the rigid-body least-squares reference fitted in the same run
  on the same samples (J alpha + c omega + T_c sign omega + T_0, alpha from the same filter);
- **speed**: a 25,000-sample (25 s at 1 kHz) CSV, file to report with plots, through the
  command line, against the same run's rigid-body least-squares fit on it (thin reference);
- ``--memory``: peak RSS of the workflow on a 10-minute 1 kHz bag.

``--mismatch`` is the honest stress test: effects whose shapes are NOT in the library
(shear-thinning viscous drag, exponential Stribeck, linear thermal drift, a third lead
harmonic) and AR(1) coloured noise; the identification then means "the library term closest
to the hidden physics".
"""

import argparse
from collections import Counter
import dataclasses
import math
import os
import time

import numpy as np

from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import (baseline, named_correctly, NOISE_RANGE_NM,
                                                   random_case, reference_trajectory,
                                                   synthesize)
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
    thermal: linear in time with the same change at the end of the fit part; lead and angle
    ripple: a third harmonic added; inertia: J times the true (unfiltered, finite-difference)
    acceleration of the trajectory, not the filtered one; seal, load_dependent, offset and the
    asymmetries: unchanged (already the physical shape).
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
    if term.name == "inertia":
        alpha = np.gradient(w, rec.t_s)
        return p["j_kg_m2"] * alpha
    if term.name == "angle_ripple":
        amp = THIRD_HARMONIC_FRACTION * np.hypot(p.get("sin1_nm", 0.0), p.get("cos1_nm", 0.0))
        return TermSet([term]).torque_nm(*x) + amp * np.cos(3.0 * rec.nut_angle_rad)
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
    ap.add_argument("--no-realdata", action="store_true", help="skip the measured drives")
    ap.add_argument("--no-speed", action="store_true", help="skip the 25,000-sample timing")
    ap.add_argument("--servo", action="store_true",
                    help="servo moves with sharp acceleration edges at 2 kHz to 10 Hz: the "
                    "chosen cut-off against a fixed one")
    ap.add_argument("--noise-floor", action="store_true",
                    help="measured drives: the velocity-spectrum noise-floor cut-off against "
                    "the cross-validated choice")
    ap.add_argument("--memory", action="store_true",
                    help="peak RSS on a 10-minute 1 kHz bag (writes it first; minutes)")
    ap.add_argument("--write-long-bag", metavar="DIR", help=argparse.SUPPRESS)
    ap.add_argument("--physical", action="store_true",
                    help="hidden physical parameters (theta, mu, preload) and "
                    "empirical-only cases; time and model runs on a 60 s 1 kHz recording")
    ap.add_argument("--empirical-effect", default=None, choices=PHYSICAL_EXTRA_EFFECTS,
                    help="--physical: the empirical-only cases all hide this effect (e.g. "
                         "load_dependent, mu's near-twin: the false alarms of the tie rule)")
    ap.add_argument("--no-tie-rule", action="store_true",
                    help="--physical: prefer_model_parameter_on_tie off (the better score "
                         "decides between a physical parameter and its twin), to compare")
    ap.add_argument("--physical-cases", type=int, default=4,
                    help="--physical: cases per hidden physical parameter")
    ap.add_argument("--empirical-cases", type=int, default=4,
                    help="--physical: cases with empirical effects only")
    ap.add_argument("--no-timing", action="store_true",
                    help="--physical: skip the 60 s 1 kHz timing")
    ap.add_argument("--memory-phases", nargs=2, metavar=("BAG", "BASELINE"),
                    help="peak RSS per phase (imports, model warm-up, load, cut-off, analysis) "
                    "of the workflow on BAG (e.g. one written by --write-long-bag) with "
                    "--baseline BASELINE (model or zero); run it alone, in a fresh process")
    args = ap.parse_args()
    if args.physical:
        physical_section(args)
        return
    if args.write_long_bag:
        write_long_bag(args.write_long_bag)
        return
    if args.memory_phases:
        memory_phases(*args.memory_phases)
        return
    settings = DiscrepancySettings()
    t0 = time.perf_counter()
    base = baseline(reference_trajectory(), cache_dir=cache_dir())
    print(f"baseline: {len(base.recording)} samples, "
          f"{base.recording.t_s[-1] - base.recording.t_s[0]:.1f} s of input "
          f"({time.perf_counter() - t0:.1f} s incl. the model run if not cached)")
    rng = np.random.default_rng(args.seed)
    hits, rmse_pass, per_effect, confusions, times = 0, 0, Counter(), Counter(), []
    phys_hits = 0
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
        ok = named_correctly(a, hidden.names)
        hits += ok
        phys_hits += ok or (args.mismatch and physically_named(a, hidden.names))
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
        print(f"identification rate (exact set; the offset/coulomb_asymmetry pair counts when "
              f"reported ambiguous): {hits}/{args.cases} = {hits / args.cases:.1%} "
              "(goal >= 90 %)")
        if args.mismatch:
            print(f"identification rate (physical reading: every hidden effect named, extras "
                  f"only from its shape family, MISMATCH_FAMILY): {phys_hits}/{args.cases} = "
                  f"{phys_hits / args.cases:.1%}")
        print(f"held-out RMSE drop >= 80 % of reducible: {rmse_pass}/{args.cases} = "
              f"{rmse_pass / args.cases:.1%}")
        print("per effect (named when hidden): " + ", ".join(
            f"{n} {per_effect[n]}/{seen[n]}" for n in sorted(seen)))
    if args.clean:
        print(f"false-alarm rate: {alarms}/{args.clean} = {alarms / args.clean:.1%} "
              "(goal <= 10 %)")
    for (hidden, got), count in confusions.most_common(10):
        print(f"  missed: hidden {list(hidden)} -> selected {list(got)} (x{count})")
    if times:
        print(f"analysis time per recording: median {np.median(times) * 1e3:.0f} ms, max "
              f"{np.max(times) * 1e3:.0f} ms ({len(base.recording)} samples)")
    if args.servo:
        servo_section(settings)
    if not args.no_realdata:
        realdata_section(settings)
    if args.noise_floor:
        noise_floor_section(settings)
    if not args.no_speed:
        speed_section()
    if args.memory:
        memory_section()
    print(f"machine load (uptime): {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} "
          f"{os.getloadavg()[2]:.2f} on {os.cpu_count()} cores")


# --mismatch, "physical reading": the library terms that together describe a distorted
# shape.  A shear-thinning drag c|w|^0.8 is a viscous drag plus a constant part (seal) or a
# low-speed excess (Stribeck); an exponential Stribeck curve a Gaussian one plus drag; the
# true-acceleration inertia leaves spikes at the ramps that a direction asymmetry or the drag
# terms do not describe, so it gets no family.
MISMATCH_FAMILY = {
    "viscous_drag": {"seal_drag", "stribeck"},
    "stribeck": {"seal_drag", "viscous_drag"},
    "thermal_drift": set(),
    "lead_error": {"angle_ripple"},
    "angle_ripple": set(),
    "inertia": set(),
}


def physically_named(a, hidden):
    """Every hidden effect named; each extra term belongs to a hidden effect's family."""
    got = set(a.terms.names)
    for amb in a.ambiguities:
        if not amb["separated"] and set(amb["pair"]) & set(hidden):
            got |= set(amb["pair"])
    if not set(hidden) <= got:
        return False
    allowed = set(hidden).union(*(MISMATCH_FAMILY.get(h, set()) for h in hidden))
    return (got - set(hidden)) <= allowed | {p for amb in a.ambiguities for p in amb["pair"]}


def _importer():
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / "tools" / "import_epos.py"
    spec = importlib.util.spec_from_file_location("import_epos", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _measured_drives(title, header=None):
    """
    Print ``title`` (and ``header``); yield (drive, fit CSV, validation CSV, its temporary
    directory) for each RViMLab drive, imported into a directory that lives until the next
    drive; without the shared data, print why and yield nothing.
    """
    import io
    import tempfile
    epos = _importer()
    root, why = epos.find_realdata()
    print(title)
    if root is None:
        print(f"skipped: {why}")
        return
    if header:
        print(header)
    for drive in ("driveNo1", "driveNo2", "driveNo3"):
        with tempfile.TemporaryDirectory() as tmp:
            fit, val = epos.import_rvim(root / "rvim_screw_drives" / "raw" / "experiments" /
                                        drive, tmp, log=io.StringIO())
            yield drive, fit, val, tmp


def servo_section(settings):
    """
    Sharp-edged inertia (trapezoidal moves) recorded at 2 kHz, 250, 50 and 10 Hz.

    Per rate: the cut-off chosen from the data and the share of the reducible held-out gap it
    removes, against a fixed 10 Hz cut-off (2 Hz at 10 Hz, its safe maximum), same run.
    """
    from bb_friction_ros.discrepancy.servo_moves import Drive, servo_recording
    from bb_friction_ros.discrepancy.workflow import analyse, summary_of
    drive = Drive()
    print(f"\n== servo moves, sharp acceleration edges (J = {drive.j_kg_m2:g} kg m^2, "
          f"noise {drive.noise_nm:g} N m): chosen cut-off vs a fixed one")
    for rate, span in ((2000.0, 10.0), (250.0, 10.0), (50.0, 60.0), (10.0, 60.0)):
        rec, _ = servo_recording(rate, span)
        row = []
        for fc in (0.0, min(10.0, settings.accel_max_cutoff_fraction * rate)):
            t0 = time.perf_counter()
            a = analyse(rec, dataclasses.replace(settings, accel_cutoff_hz=fc))
            wall = time.perf_counter() - t0
            s = summary_of(a)
            acc = s["acceleration"]
            j = {e["name"]: e["params"] for e in s["effects"]}.get("inertia", {}).get("j_kg_m2")
            removed = (a.rmse_before_nm - a.rmse_after_nm) / (a.rmse_before_nm - drive.noise_nm)
            flag = ("set in the settings" if fc else
                    "bandwidth-limited" if acc.get("bandwidth_limited") else
                    "inertia not identifiable" if acc.get("inertia_identifiable") is False
                    else "resolved")
            row.append(f"{'chosen' if fc == 0 else 'fixed'} {acc['cutoff_hz']:.3g} Hz "
                       f"({flag}): J {j if j is None else f'{j:.3g}'}, removed {removed:.0%}, "
                       f"{wall:.1f} s")
        print(f"{rate:g} Hz, {len(rec)} samples: " + "; ".join(row))


def realdata_section(settings):
    """
    The measured drives: fit on half the runs, --validate on the others.

    Per drive: the chosen acceleration cut-off, and the held-out and validation relative
    errors of the workflow and of the rigid-body least-squares reference that the same run
    fits on the same samples with the same alpha.
    """
    import contextlib
    import io
    import json
    from pathlib import Path
    from bb_friction_ros.cli import main as cli_main
    from bb_friction_ros.discrepancy.workflow import worse_than_reference
    for drive, fit, val, tmp in _measured_drives(
            "\n== measured drives (RViMLab screw drives, MIT licence; Mablekos-Alexiou, da "
            "Cruz, Bergeles, IEEE T-RO 37(4) 2021)",
            "drive | cut-off [Hz] (chosen by) | held-out rel. error: workflow / reference | "
            "validation rel. error: workflow / reference"):
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            status = cli_main(["discrepancy", str(fit), "--validate", str(val), "--out",
                               str(Path(tmp) / "out"), "--no-plots", "--no-progress"])
        wall = time.perf_counter() - t0
        s = json.loads((Path(tmp) / "out" / "summary.json").read_text())
        v, h, acc = s.get("validation", {}), s["heldout"], s["acceleration"]
        terms = ", ".join(f"{e['name']}(" + ", ".join(f"{k}={x:.3g}" for k, x in
                                                      e["params"].items()) + ")"
                          for e in s["effects"])
        print(f"{drive}: status {status}, {s['samples']['usable']} samples, {wall:.1f} s; "
              f"written (refitted on all): {terms}")
        for amb in s.get("ambiguities", []):
            print(f"  {amb['statement']}")
        print(f"  acceleration: cut-off {acc.get('cutoff_hz', float('nan')):.3g} Hz "
              f"({acc.get('chosen_by')}); sample rate {acc.get('sample_rate_hz', 0):.4g} Hz; "
              f"candidates " + ", ".join(f"{c['cutoff_hz']:.3g}:{c['cv_rmse_nm']:.4g}"
                                         for c in acc.get("candidates", [])) +
              f"; live filter lag {acc.get('live_lag_s', 0) * 1e3:.3g} ms")
        print(f"  held-out RMSE {s['rmse_before_nm']:.4g} -> {s['rmse_after_nm']:.4g} N m; "
              f"noise {s['noise_std_nm']:.3g} N m; regimes flagged {len(s['regions'])} "
              f"before, {len(s['regions_remaining'])} after")
        for what, row, a, b in (("held-out", h, "relative_error_after",
                                 "reference_relative_error"),
                                ("validation", v, "relative_error_after",
                                 "reference_relative_error")):
            verdict = "WORSE" if worse_than_reference(row[a], row[b]) else "no worse"
            print(f"  {what} ({row['n']} samples): relative error workflow {row[a]:.4f}, "
                  f"rigid-body reference {row[b]:.4f}: {verdict} "
                  f"({(row[a] / row[b] - 1) * 100:+.1f} %)")
        print("  reference (all samples): " + ", ".join(
            f"{k}={x:.3g}" for k, x in s["reference"]["params_all_samples"].items()))
        for w in s.get("warnings", []):
            print(f"  WARNING: {w}")


# --noise-floor: the velocity spectrum "meets its noise floor" where it falls below this
# multiple of the floor (the median PSD over the top quarter of the band); the criterion
# needs such a factor, which is one reason it was not built (docs/discrepancy.md).
NOISE_FLOOR_FACTORS = (10.0, 3.0)
NOISE_FLOOR_BAND = 0.375          # the floor: PSD above this fraction of the sample rate


def spectrum_floor_cutoff(rec, factor):
    """
    Return (the fastest run's rate [Hz], the frequency [Hz] where the velocity spectrum
    meets ``factor`` x its noise floor): Welch PSD of the fastest runs' velocity.
    """
    from scipy.signal import welch
    from bb_friction_ros.discrepancy.bandwidth import run_slices, sample_step_s
    psds = []
    for sl in run_slices(rec):
        run = rec.take(sl)
        step = sample_step_s(run)
        if step is not None and len(run) >= 64:
            w = run.nut_velocity_rad_s
            f, p = welch(w - w.mean(), fs=1.0 / step, nperseg=min(256, len(run)))
            psds.append((1.0 / step, f, p))
    fast = max(rate for rate, _, _ in psds)
    same = [(f, p) for rate, f, p in psds if abs(rate - fast) < 1e-6 * fast]
    f = same[0][0]
    p = np.mean([q for g, q in same if g.size == f.size], axis=0)
    floor = float(np.median(p[f > NOISE_FLOOR_BAND * fast]))
    above = np.flatnonzero(p > factor * floor)
    return fast, float(f[above[-1]]) if above.size else float(f[1])


def noise_floor_section(settings):
    """Validation error at the noise-floor cut-off against the cross-validated choice."""
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.discrepancy.workflow import analyse, validate, summary_of
    for drive, fit, val, _ in _measured_drives(
            "\n== acceleration cut-off: velocity-spectrum noise floor vs blocked CV "
            "(validation relative error, workflow / rigid-body reference)"):
        rec, rec2 = load_recording(fit), load_recording(val)
        row = []
        for factor in (None,) + NOISE_FLOOR_FACTORS:
            s = settings
            if factor is not None:
                rate, fc = spectrum_floor_cutoff(rec, factor)
                s = dataclasses.replace(settings, accel_cutoff_hz=min(
                    fc, settings.accel_max_cutoff_fraction * rate))
            a = analyse(rec, s)
            v = validate(a, rec2, s).summary
            fc_used = summary_of(a)["acceleration"]["cutoff_hz"]
            what = "CV (one-SE, highest)" if factor is None else f"floor x{factor:g}"
            row.append(f"{what} {fc_used:.3g} Hz: {v['relative_error_after']:.4f} / "
                       f"{v['reference_relative_error']:.4f}")
        print(f"{drive}: " + "; ".join(row))


def speed_section():
    """A 25,000-sample CSV (25 s at 1 kHz, no model), file to report, via the CLI."""
    import subprocess
    import sys
    import tempfile
    from pathlib import Path
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.discrepancy.reference import rigid_body_fit
    from bb_friction_ros.discrepancy.bandwidth import with_acceleration
    rng = np.random.default_rng(25)
    t = np.arange(25000) * 1e-3
    # a drive cycle of accelerations, cruises and reversals at 1 kHz
    w = 30.0 * np.sin(2 * np.pi * t / 2.5) + 5.0 * np.sin(2 * np.pi * t / 0.7)
    phi = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * 1e-3)))
    alpha = np.gradient(w, t)
    meas = (2e-4 * alpha + 4e-4 * w + 0.02 * np.sign(w) + 0.004
            + 0.01 * np.exp(-(w / 2.0) ** 2) * np.sign(w)
            + np.convolve(rng.normal(0, 0.002, t.size), np.ones(5) / 5, mode="same"))
    with tempfile.TemporaryDirectory() as tmp:
        csv_path = Path(tmp) / "drive_25k.csv"
        table = np.column_stack([t, phi, w, np.full(t.size, 500.0), meas, np.zeros(t.size)])
        np.savetxt(csv_path, table, delimiter=",", fmt="%.10g", comments="",
                   header="t_s,nut_angle_rad,nut_velocity_rad_s,axial_load_n,torque_meas_nm,"
                   "torque_pred_nm")
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "bb_friction_ros.cli", "discrepancy",
                               str(csv_path), "--out", str(Path(tmp) / "out"),
                               "--no-progress"], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        t1 = time.perf_counter()
        rec, _ = with_acceleration(load_recording(csv_path), DiscrepancySettings())
        rigid_body_fit(rec)
        ref = time.perf_counter() - t1
    print(f"\n== speed: 25,000 samples (25 s at 1 kHz), CSV to report.md with 4 figures, "
          f"via the command line: {wall:.1f} s (goal <= 30 s); status {proc.returncode}; "
          f"{proc.stdout.strip().splitlines()[0] if proc.stdout.strip() else proc.stderr[-300:]}")
    print(f"   same run, thin reference (read the CSV, derive alpha, rigid-body least "
          f"squares, in-process): {ref:.2f} s; ratio {wall / ref:.1f}x")


def memory_section():
    """Peak RSS of the workflow on a 10-minute 1 kHz bag."""
    import resource
    import subprocess
    import sys
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag10min"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--write-long-bag", str(bag)], check=True)
        print(f"\n== memory: wrote a 10-minute 1 kHz bag ({time.perf_counter() - t0:.0f} s)")
        for extra in (["--baseline", "zero"], []):
            t1 = time.perf_counter()
            before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            proc = subprocess.run([sys.executable, "-c",
                                   "import resource, sys\n"
                                   "from bb_friction_ros.cli import main\n"
                                   "status = main(sys.argv[1:])\n"
                                   "print('peak_rss_kb', resource.getrusage("
                                   "resource.RUSAGE_SELF).ru_maxrss)\n"
                                   "sys.exit(status)",
                                   "discrepancy", str(bag), "--out", str(Path(tmp) / "o"),
                                   "--no-plots", "--no-progress"] + extra,
                                  capture_output=True, text=True)
            del before
            peak = [line for line in proc.stdout.splitlines() if line.startswith("peak_rss_kb")]
            mb = int(peak[0].split()[1]) / 1024 if peak else float("nan")
            print(f"   discrepancy {' '.join(extra) or '(model)'}: peak RSS {mb:.0f} MB "
                  f"(goal <= 300 MB), {time.perf_counter() - t1:.0f} s, status "
                  f"{proc.returncode} {proc.stderr.strip()[-200:]}")


def _rss_mb():
    """Return (current, peak) resident set size of this process [MB] (Linux /proc)."""
    d = {}
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(("VmRSS", "VmHWM")):
                k, v = line.split(":")
                d[k] = int(v.split()[0]) / 1024
    return d.get("VmRSS", float("nan")), d.get("VmHWM", float("nan"))


def memory_phases(bag, baseline):
    """Print the peak RSS after each phase of the workflow on ``bag``."""
    import gc
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.discrepancy import workflow
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.runner import build_runner

    def say(what):
        now, peak = _rss_mb()
        print(f"   {what}: RSS {now:.0f} MB, peak so far {peak:.0f} MB", flush=True)
    say("imports (numpy, scipy, rosbags, numba via the runner)")
    if baseline == "model":
        build_runner(bundled_config("ball_screw.yaml"), 100.0)    # built, warmed, dropped
        gc.collect()
        say("ball-screw model built and warmed up (numba kernels)")
    rec = load_recording(bag, baseline=baseline, progress=False)
    say(f"recording loaded ({len(rec)} samples)")
    settings = DiscrepancySettings()
    choice = workflow.choose_cutoff(rec, settings, workflow.usable)
    say(f"cut-off chosen ({choice.cutoff_hz:.3g} Hz)")
    workflow.analyse(rec, settings)
    say("analysed (whole workflow, no plots)")


def write_long_bag(path, minutes=10.0, rate_hz=1000.0):
    """Write a bag of ``minutes`` at ``rate_hz``: nut state, axial load, measured torque."""
    from bb_friction_ros.bags import Event, write_events
    n = int(minutes * 60 * rate_hz)
    t = np.arange(n) / rate_hz
    w = 6.0 * np.sin(2 * np.pi * t / 4.0)
    phi = np.cumsum(w) / rate_hz
    rng = np.random.default_rng(0)
    meas = 0.2 * np.sign(w) + 0.004 * w + rng.normal(0, 0.005, n)

    def events():
        for k in range(n):
            yield Event("axial_load", float(t[k]), value=1500.0)
            yield Event("nut_state", float(t[k]), ("nut_joint",), (float(phi[k]),),
                        (float(w[k]),))
            yield Event("measured_torque", float(t[k]), value=float(meas[k]))
    write_events(path, events(), storage="mcap")


# ------------------------------------------------------------------------------------------
# --physical: the model's own parameters hidden from the config

# Effects drawn on top of a physical case, or alone in an empirical-only case: those the
# physical trajectory (20 s at 50 Hz) can carry; inertia and lead/ripple need the reference
# trajectory's acceleration filter and angle coverage, and are left to the main set.
PHYSICAL_EXTRA_EFFECTS = ("viscous_drag", "seal_drag", "stribeck", "thermal_drift",
                          "load_dependent", "offset", "viscous_asymmetry")
THETA_TARGET_DEG = 0.3
MU_TARGET_RELATIVE = 0.05


def physical_case_of(kind, rng, cache, mismatch, empirical=PHYSICAL_EXTRA_EFFECTS):
    """
    Return (recording, base config, noise, hidden physical or None, hidden TermSet).

    ``empirical``: the effects an empirical-only case (``kind`` None) draws from
    (``--empirical-effect`` narrows it to one, e.g. the twin of a physical candidate).
    """
    from bb_friction_ros.discrepancy import synthetic as sy
    from bb_friction_ros.discrepancy.synthetic import draw_effect
    hidden = sy.draw_physical(kind, rng) if kind else {}
    extra = []
    if kind is None or rng.uniform() < 0.5:
        pool = PHYSICAL_EXTRA_EFFECTS if kind else empirical
        extra = [draw_effect(str(rng.choice(pool)), rng)]
    terms = TermSet(extra)
    noise_nm = float(rng.uniform(*NOISE_RANGE_NM))
    if not mismatch:
        rec, cfg, noise = sy.physical_case(sy.physical_trajectory(), hidden, terms, noise_nm,
                                           rng, cache)
        return rec, cfg, noise, hidden, terms
    # the physics of the hidden model, the empirical effects' shapes outside the library
    # and AR(1) coloured noise
    rec, cfg, _ = sy.physical_case(sy.physical_trajectory(), hidden, TermSet(), 0.0, rng,
                                   cache)
    noise = coloured(rng.normal(0.0, noise_nm, len(rec)))
    effect = sum((distorted_torque(t, rec) for t in terms.terms), np.zeros(len(rec)))
    rec = dataclasses.replace(rec, torque_meas_nm=rec.torque_meas_nm + effect + noise)
    return rec, cfg, noise, hidden, terms


def physical_section(args):
    """Print the named share, parameter errors, false alarms and the cost."""
    from bb_friction_ros.discrepancy import physical as ph
    from bb_friction_ros.discrepancy.synthetic import PHYSICAL_RANGES
    from bb_friction_ros.node_parameters import NodeParameters
    cache = os.path.join(cache_dir(), "physical")
    settings = DiscrepancySettings()
    runner = ph.runner_args(NodeParameters(model_rate_hz=50.0))
    rng = np.random.default_rng(args.seed)
    rows = []
    kinds = [k for k in ph.PHYSICAL for _ in range(args.physical_cases)] + \
        [None] * args.empirical_cases
    print(f"physical cases: {len(kinds)} (20 s at 50 Hz, model 50 Hz floor; noise "
          f"{NOISE_RANGE_NM[0] * 1e3:g}-{NOISE_RANGE_NM[1] * 1e3:g} mN m"
          f"{', --mismatch: shapes outside the library, AR(1) noise' if args.mismatch else ''}"
          f"{', tie rule off' if args.no_tie_rule else ''}"
          f"; load {os.getloadavg()[0]:.1f})")
    for kind in kinds:
        rec, cfg, noise, hidden, terms = physical_case_of(
            kind, rng, cache, args.mismatch,
            (args.empirical_effect,) if args.empirical_effect else PHYSICAL_EXTRA_EFFECTS)
        t0 = time.perf_counter()
        a = analyse(rec, settings, ph.PhysicsContext(cfg, runner, ph.PhysicalSettings(
            enabled=True, prefer_model_parameter_on_tie=not args.no_tie_rule)))
        wall = time.perf_counter() - t0
        choice = ph.chosen(a.physical)
        true = None
        if kind:
            section, param, _ = PHYSICAL_RANGES[kind]
            true = hidden[section][param]
        got = choice.kind.name if choice else None
        ok_rmse, reducible = rmse_ok(a, noise)
        # the hidden physical change itself: a theta below its B2B onset changes the torque
        # by less than the noise, and no method can name it
        extra = terms.torque_nm(rec.t_run_s, rec.nut_angle_rad, rec.nut_velocity_rad_s,
                                rec.axial_load_n) if len(terms) else 0.0
        phys = rec.torque_meas_nm - noise - rec.torque_pred_nm
        phys = phys - (extra if not args.mismatch else sum(
            (distorted_torque(t, rec) for t in terms.terms), np.zeros(len(rec))))
        n_fit = int(np.floor((1.0 - settings.holdout_fraction) * len(rec)))
        effect_rms = float(np.sqrt(np.mean(phys[:n_fit] ** 2)))
        noise_std = float(np.std(noise))
        # the evidence the hidden change carries against white noise of the true std: the
        # log-likelihood ratio sum d^2 / s^2 (fit part), against what a parameter must pay
        # in the penalised BIC (ln n' + bic_threshold, n' = n / tau)
        evidence = float(np.sum(phys[:n_fit] ** 2)) / noise_std ** 2
        # ... and what is left of it beside the hidden empirical terms' own columns (their
        # amplitudes free): a change those columns can copy carries no evidence of its own
        evidence_beside = beside_hidden(phys[:n_fit], rec, n_fit, terms, settings) / \
            noise_std ** 2
        n_eff = n_fit / max(a.noise.tau, 1.0)
        price = math.log(n_eff) + settings.bic_threshold
        row = {"hidden": kind, "true": true, "extra": terms.names, "named": got,
               "value": choice.value if choice else None, "terms": a.terms.names,
               "runs": a.physical.runs + a.physical.validation_runs, "wall": wall,
               "rmse_ok": ok_rmse, "reducible": reducible,
               "ambiguous": [x["pair"] for x in a.ambiguities + a.physical.identifiability
                             if not x["separated"]],
               "snr": effect_rms / noise_std, "evidence": evidence, "price": price,
               "evidence_beside": evidence_beside,
               "phys_wall": a.physical.wall_s,
               "tie": bool(choice is not None and a.physical.tie),
               # a tie on the fit part that the held-out part's evidence broke
               # (physical._heldout_gap): the tie rule alone would have named the parameter
               "tie_broken": any("on the fit part" in n and n.endswith("is kept")
                                 for n in a.physical.notes),
               "interval": choice.interval_95 if choice else None}
        rows.append(row)
        print(f"  hidden {kind or '(empirical only)'} {'' if true is None else f'{true:.4g}'}"
              f" + {', '.join(terms.names) or '-'}: named {got or '-'}"
              f"{'' if choice is None else f' {choice.value:.4g}'} + "
              f"{', '.join(a.terms.names) or '-'}; physical effect rms / noise "
              f"{row['snr']:.2f} (evidence sum d^2/s^2 {evidence:.0f}, beside the hidden "
              f"terms' columns {evidence_beside:.0f}; price {price:.1f}); {row['runs']} "
              f"runs, {wall:.1f} s ({a.physical.wall_s:.1f} s in model runs); "
              f"held-out reducible {reducible * 1e3:.2f} mN m, 80 % removed: {ok_rmse}"
              f"{'; ambiguous: ' + str(row['ambiguous']) if row['ambiguous'] else ''}"
              f"{'; chosen on a tie with its twin' if row['tie'] else ''}"
              f"{'; a fit-part tie the held-out part broke' if row['tie_broken'] else ''}",
              flush=True)
    phys = [r for r in rows if r["hidden"]]
    emp = [r for r in rows if not r["hidden"]]
    named = [r for r in phys if r["named"] == r["hidden"]]
    right = [r for r in named if within_tolerance(r)]
    print(f"named: {len(named)}/{len(phys)} = {len(named) / max(len(phys), 1):.0%}; named "
          f"and within tolerance (theta +-{THETA_TARGET_DEG} deg, mu +-"
          f"{MU_TARGET_RELATIVE:.0%}): {len(right)}/{len(phys)} = "
          f"{len(right) / max(len(phys), 1):.0%} (goal >= 90 %)")
    off = [r for r in named if not within_tolerance(r)]
    for r in off:
        print(f"  named off tolerance: {r['hidden']} {r['true']:.4g} named {r['value']:.4g} "
              f"(95 %: {r['interval'][0]:.4g}-{r['interval'][1]:.4g}, covers the truth: "
              f"{r['interval'][0] <= r['true'] <= r['interval'][1]}); ambiguous pairs "
              f"reported: {r['ambiguous'] or '-'}")
    seen = [r for r in phys if r["snr"] >= 1.0]
    print(f"named where the hidden change's rms (fit part) is at least the noise std: "
          f"{sum(r['named'] == r['hidden'] for r in seen)}/{len(seen)}")
    payable = [r for r in phys if r["evidence_beside"] >= r["price"]]
    print(f"named where the hidden change's evidence (sum d^2/s^2, fit part, beside the "
          f"hidden terms' columns) exceeds the price of a parameter (ln n' + bic_threshold):"
          f" {sum(r['named'] == r['hidden'] for r in payable)}/{len(payable)}")
    pair = [r for r in phys if r["named"] != r["hidden"]
            and any(r["hidden"] in p for p in r["ambiguous"])]
    print(f"not named but reported as one ambiguous pair with its twin: {len(pair)}")
    for kind in ph.PHYSICAL:
        sub = [r for r in named if r["hidden"] == kind]
        if not sub:
            continue
        if kind == "friction_coefficient":
            err = [abs(r["value"] / r["true"] - 1.0) for r in sub]
            print(f"  {kind}: relative error max {max(err):.2%}, median "
                  f"{np.median(err):.2%} (goal <= {MU_TARGET_RELATIVE:.0%}); within: "
                  f"{sum(e <= MU_TARGET_RELATIVE for e in err)}/{len(sub)}")
        else:
            err = [abs(r["value"] - r["true"]) for r in sub]
            goal = f" (goal <= {THETA_TARGET_DEG} deg)" if kind.startswith("contact") else ""
            print(f"  {kind}: abs error max {max(err):.3g}, median {np.median(err):.3g} "
                  f"{ph.PHYSICAL[kind].unit}{goal}")
    extras_right = sum(set(r["terms"]) == set(r["extra"]) for r in phys)
    print(f"empirical terms on top equal the hidden extras: {extras_right}/{len(phys)}")
    alarms = sum(r["named"] is not None for r in emp)
    print(f"false alarms (empirical only, a physical parameter named): {alarms}/{len(emp)} "
          "(goal <= 10 %)")
    ties = [r for r in rows if r["tie"]]
    print(f"chosen on a tie with the twin (prefer_model_parameter_on_tie): {len(ties)} "
          f"({sum(r['named'] == r['hidden'] for r in ties)} the hidden parameter, "
          f"{sum(r['hidden'] is None for r in ties)} false alarms, "
          f"{sum(r['hidden'] is not None and r['named'] != r['hidden'] for r in ties)} "
          "another parameter's)")
    broken = [r for r in rows if r["tie_broken"]]
    print(f"fit-part ties with the twin that the held-out part broke (the twin kept; the tie "
          f"rule on the fit part alone would have named the parameter): {len(broken)} "
          f"({sum(r['hidden'] is None for r in broken)} on empirical-only recordings, "
          f"{sum(r['hidden'] is not None for r in broken)} with a hidden parameter)")
    judged = [r for r in rows if r["reducible"] > 0]
    print(f"held-out: >= 80 % of the reducible gap removed in "
          f"{sum(r['rmse_ok'] for r in judged)}/{len(judged)} cases with a reducible gap")
    print(f"model runs per analysis: median {np.median([r['runs'] for r in rows]):.0f}; "
          f"wall per analysis median {np.median([r['wall'] for r in rows]):.1f} s, of it "
          f"in model runs {np.median([r['phys_wall'] for r in rows]):.1f} s "
          f"(load {os.getloadavg()[0]:.1f})")
    if not args.no_timing:
        physical_timing(cache)


def within_tolerance(r):
    """Tell whether a named physical value is within the target tolerance of the truth."""
    if r["hidden"] == "contact_angle_deviation":
        return abs(r["value"] - r["true"]) <= THETA_TARGET_DEG
    if r["hidden"] == "friction_coefficient":
        return abs(r["value"] / r["true"] - 1.0) <= MU_TARGET_RELATIVE
    return True           # no tolerance is set for the preload; its error is printed


def beside_hidden(d, rec, n_fit, terms, settings):
    """Return |M d|^2: ``d`` (fit part) less its projection on the hidden terms' columns."""
    from bb_friction_ros.discrepancy.data import inputs_of
    from bb_friction_ros.discrepancy.selection import candidates
    if not len(terms):
        return float(d @ d)
    mask = np.arange(len(rec)) < n_fit
    x = inputs_of(rec, mask)
    cands = {c.name: c for c in candidates(x, settings)}
    cols = []
    for t in terms.terms:
        nl = getattr(t.params, t.kind.nonlinear) if t.kind.nonlinear else None
        cols.append(cands[t.name].columns(x, nl))
    a = np.hstack(cols)
    coef, *_ = np.linalg.lstsq(a, d, rcond=None)
    e = d - a @ coef
    return float(e @ e)


def physical_timing(cache):
    """Time a 60 s 1 kHz recording with a hidden theta: local, then a Dask LocalCluster."""
    from bb_friction_ros.discrepancy import physical as ph
    from bb_friction_ros.discrepancy import synthetic as sy
    from bb_friction_ros.node_parameters import NodeParameters
    traj = sy.physical_trajectory(duration_s=60.0, rate_hz=1000.0)
    rng = np.random.default_rng(21)
    t0 = time.perf_counter()
    rec, cfg, _ = sy.physical_case(traj, {"errors": {"theta_amplitude_deg": 2.5}}, TermSet(),
                                   0.004, rng, cache, model_rate_hz=100.0)
    print(f"60 s 1 kHz recording: {len(rec)} samples (made in "
          f"{time.perf_counter() - t0:.1f} s, cached after)")
    runner = ph.runner_args(NodeParameters())
    settings = DiscrepancySettings()
    t0 = time.perf_counter()
    analyse(rec, settings)
    plain = time.perf_counter() - t0
    print(f"  empirical terms only: {plain:.1f} s (load {os.getloadavg()[0]:.1f})")
    # local: the trial runs of a batch in 2 threads (the kernels release the GIL) and in 1;
    # then a Dask LocalCluster of 2 worker processes
    for how, workers, threads in (("local, 2 threads", 1, 2), ("local, 1 thread", 1, 1),
                                  ("Dask LocalCluster, 2 workers", 2, 1)):
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        a = analyse(rec, settings, ph.PhysicsContext(
            cfg, runner, ph.PhysicalSettings(enabled=True, workers=workers, threads=threads)))
        wall = time.perf_counter() - t0
        c = ph.chosen(a.physical)
        print(f"  with physical candidates, {how}: {wall:.1f} s (goal <= 60 s), "
              f"{a.physical.runs} model runs ({a.physical.coarse_runs} at the "
              f"{a.physical.coarse_step_factor}x coarser step) taking "
              f"{a.physical.wall_s:.1f} s, {a.physical.selections} empirical selections and "
              f"the rest {wall - a.physical.wall_s:.1f} s; named {c.kind.name if c else '-'} "
              f"{'' if c is None else f'{c.value:.3g}'} (hidden 2.5); ratio to empirical "
              f"only {wall / plain:.1f}x; load {load0:.1f} -> {os.getloadavg()[0]:.1f}",
              flush=True)


if __name__ == "__main__":
    main()
