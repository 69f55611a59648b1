"""Studies and speed of bb-friction servo-test; prints tables, asserts nothing.

Run: .venv/bin/python bench/bench_servo.py [--part exact|speed|measured|b2b|sweep|node|gate|all]
                                           [--workdir DIR] [--repeats 3]

0. exact: the none mode against closed-loop recordings of the same plant and loop made with
   a finer integration: the integrator's error (docs/servo_test.md);
1. speed: simulated seconds per CPU second at 1 kHz of each mode, against the plant-only run
   (mode none) in the same process, on the bundled screw (reversals at 1 rev/s); medians of
   ``--repeats`` runs, with the machine's load;
2. measured: the check against a measured loop, on closed-loop recordings made here (a
   terms-only axis with a hidden viscous drag, Stribeck rise, ripple and 10 um of pre-sliding,
   a 17-bit encoder, torque noise, test pulses, a loop not tuned for it): the model is
   calibrated by ``bb-friction discrepancy --baseline zero`` on a second recording, then
   ``servo-test`` compares the none mode and the rigid-body reference with the recording;
3. b2b: the ball-to-ball case: a plant with theta = 3 deg, a hidden viscous drag and 10 um of
   pre-sliding, fresh and run-in balls; the product's model calibrated by
   ``bb-friction discrepancy`` on a closed-loop recording of that plant (never from the
   truth); every mode on reversals at 1 rev/s and on the ISO 230-4 circle; fresh, run-in
   (the model's balls run in the same way) and unknown (the plant's run in, the model's
   fresh) arrangements;
4. sweep: one factor at a time from the b2b case (run-in, unknown arrangement): theta, axial
   load, stroke, velocity-loop bandwidth, servo rate; the product's model is the plant's
   physics with the terms calibrated in part 3;
5. node: the node mode's profile coverage (the share of servo cycles whose measured angle lies
   inside a valid profile) and its following error against the model mode's, in one run;
6. gate: what the feedforward safety gate costs at reversals (the b2b case, run-in balls,
   reversals at 1 rev/s and the circle): every mode with and without the gate
   (``servo-test --no-safety-gate``), as ratios to fitted Coulomb + viscous.
"""

import argparse
import dataclasses
import json
import math
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml

from bb_friction_ros.config import bundled_config

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
# 10 um of pre-sliding on a 20 mm lead, in nut angle [rad]
PRESLIDING_RAD = 10e-6 * 2 * math.pi / 0.02
MODES = ["coulomb_viscous", "coulomb_viscous_commanded", "lugre", "lugre_commanded", "model",
         "model_commanded", "planned", "node_planned", "truth"]
LOOP = {"rate_hz": 1000.0, "position_gain_per_s": 100.0, "velocity_gain_nm_s_per_rad": 0.25,
        "velocity_integral_gain_nm_per_rad": 10.0, "torque_limit_nm": 5.0,
        "velocity_feedforward": 1.0, "acceleration_feedforward": 1.0,
        "encoder_counts_per_rev": 1048576}
INERTIA = 4.0e-4       # kg m^2: K_v / J = 625 rad/s, a 100 Hz velocity loop


def cli(*args):
    """Run ``bb-friction`` in a subprocess; return its stdout (raise on failure)."""
    res = subprocess.run([PY, "-m", "bb_friction_ros.cli", *map(str, args)], text=True,
                         capture_output=True)
    if res.returncode != 0:
        raise RuntimeError(f"bb-friction {' '.join(map(str, args))}: {res.stderr}")
    return res.stdout


def write_yaml(path, data):
    """Write ``data`` as YAML to ``path``; return the path."""
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def loop_file(path, plant=None, model=None, **loop):
    """Write a LOOP.yaml of LOOP with changes, a plant and a model section."""
    data = {"loop": {**LOOP, **loop}, "plant": {"inertia_kg_m2": INERTIA, **(plant or {})}}
    if model:
        data["model"] = model
    return write_yaml(path, data)


def screw_file(path, theta_deg, terms=(), physics=None):
    """Write the bundled screw with theta amplitude ``theta_deg`` and ``terms``."""
    base = yaml.safe_load(bundled_config("ball_screw.yaml").read_text())
    base["ball_screw"]["errors"]["theta_amplitude_deg"] = float(theta_deg)
    base["empirical_terms"] = list(terms)
    return write_yaml(path, base)


def spec_file(path, **spec):
    """Write a reference spec."""
    return write_yaml(path, {"reference": spec})


def summary(out):
    """Return an output directory's summary.json."""
    return json.loads((Path(out) / "summary.json").read_text())


# --- 1. speed --------------------------------------------------------------------------------

def part_speed(work, repeats):
    """Simulated s per CPU s per mode, against the plant-only run, same process."""
    from bb_friction_ros.servo.reference import load_reference
    from bb_friction_ros.servo.run import Setup
    from bb_friction_ros.servo.settings import load_settings
    loop = loop_file(work / "speed_loop.yaml")
    spec = spec_file(work / "speed_spec.yaml", kind="reversal", speeds_rev_s=[1.0],
                     stroke_rev=1.0, accel_rev_s2=20.0, axial_load_n=1500.0)
    model = bundled_config("ball_screw.yaml")
    s = load_settings(loop)
    setup = Setup(s, model)
    ref = load_reference(spec, s.loop.rate_hz, [setup.lead_m])
    setup.calibrate(ref)
    duration = float(ref.t_s[-1])
    load0 = os.getloadavg()[0]
    rows = {}
    for _ in range(repeats):
        for name in ["none"] + MODES:
            t0 = time.process_time()
            setup.run_mode(ref, name)
            rows.setdefault(name, []).append(duration / (time.process_time() - t0))
    print(f"\n1. servo-test speed: bundled screw, reversals at 1 rev/s, {duration:.2f} s at "
          f"1 kHz, plant model step 0.36 deg; median of {repeats}; load {load0:.2f} -> "
          f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    base = statistics.median(rows["none"])
    print(f"  {'mode':28s} {'sim s / CPU s':>14s} {'vs plant-only':>14s}")
    for name, v in rows.items():
        m = statistics.median(v)
        print(f"  {name:28s} {m:14.2f} {m / base:14.2f}")


# --- 0. the integrator's error -------------------------------------------------------------

def part_exact(work):
    """The none mode against closed-loop recordings of a finer plant (the stated error)."""
    from bb_friction_ros.servo.modes import Mode
    from bb_friction_ros.servo.reference import load_reference
    from bb_friction_ros.servo.run import relative_errors, Setup
    from bb_friction_ros.servo.settings import load_settings
    from bb_friction_ros.servo.synthetic import closed_loop_recording
    loop = loop_file(work / "exact_loop.yaml")
    spec = spec_file(work / "exact_spec.yaml", kind="reversal", speeds_rev_s=[0.5, 1.0, 2.0],
                     stroke_rev=1.0, accel_rev_s2=20.0, axial_load_n=1500.0)
    print("\n0. the simulator against a recording of the same plant and loop made with 128 "
          "sub-steps, the friction re-answered at each (0.05 N m test pulses, 20-bit "
          "encoder): relative errors of the none run, largest encoder-angle difference")
    print(f"  {'model':12s} {'sub-steps':>9s} {'friction':>9s} {'angle':>10s} "
          f"{'velocity':>10s} {'torque':>10s} {'max [um]':>9s}")
    for label, model in (("terms only", bundled_config("servo/axis_terms.yaml")),
                         ("ball screw", bundled_config("ball_screw.yaml"))):
        s = load_settings(loop)
        fine = dataclasses.replace(s, plant=dataclasses.replace(
            s.plant, substeps=128, friction_update="substep"))
        ref = load_reference(spec, 1000.0, [0.02])
        rec = work / f"exact_{label.replace(' ', '_')}.csv"
        cols = closed_loop_recording(rec, ref, fine, model, pulse_nm=0.05)
        ref = load_reference(rec, 1000.0, [0.02])
        for sub, update in ((8, "substep"), (8, "sample"), (32, "substep")):
            st = dataclasses.replace(s, plant=dataclasses.replace(
                s.plant, substeps=sub, friction_update=update))
            run = Setup(st, model).simulate_axis(ref, ref.axes[0], Mode("none"))
            e = relative_errors(ref.t_s, run, ref.axes[0])
            d = float(np.max(np.abs(run.measured_rad - cols["nut_angle_rad"])))
            print(f"  {label:12s} {sub:9d} {update:>9s} {e['angle']:10.2e} "
                  f"{e['velocity']:10.2e} {e['torque']:10.2e} {d * 0.02 / 2 / math.pi * 1e6:9.3f}",
                  flush=True)


# --- 5. the node mode -----------------------------------------------------------------------

def part_node(work, repeats):
    """The node mode's profile coverage and its following error against the model mode's."""
    loop = loop_file(work / "node_loop.yaml")
    spec = spec_file(work / "node_spec.yaml", kind="reversal", speeds_rev_s=[0.5, 1.0, 2.0],
                     stroke_rev=1.0, accel_rev_s2=20.0, axial_load_n=1500.0)
    print(f"\n5. node mode: the real friction_node at 1 kHz, bundled screw, reversals at "
          f"0.5-2 rev/s; load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  {'run':>4s} {'coverage':>9s} {'beyond':>7s} {'reversed':>9s} {'standstill':>11s} "
          f"{'late':>6s} {'node FE RMS':>12s} {'model FE RMS':>13s} {'node glitch':>12s} "
          f"{'model glitch':>13s}")
    for i in range(repeats):
        out = work / f"servo_node_{i}"
        cli("servo-test", spec, "--loop", loop, "--config", bundled_config("ball_screw.yaml"),
            "--out", out, "--modes", "model", "node", "--no-progress", "--no-plots")
        s = summary(out)["modes"]
        c = s["node"]["node"]
        n = c["cycles"]
        st = c["statuses"]
        print(f"  {i:4d} {c['coverage']:9.3f} {st.get('beyond', 0) / n:7.3f} "
              f"{st.get('reversed', 0) / n:9.3f} {st.get('standstill', 0) / n:11.3f} "
              f"{c['late_cycles'] / n:6.3f} {s['node']['following_error_rms_um']:12.3g} "
              f"{s['model']['following_error_rms_um']:13.3g} "
              f"{s['node']['reversal_glitch_max_um']:12.3g} "
              f"{s['model']['reversal_glitch_max_um']:13.3g}", flush=True)


# --- 2. the measured loop --------------------------------------------------------------------

def part_measured(work):
    """The measured-loop check on closed-loop recordings made here (module docstring)."""
    from bb_friction_ros.servo.reference import generate, ReferenceSpec
    from bb_friction_ros.servo.settings import load_settings
    from bb_friction_ros.servo.synthetic import closed_loop_recording
    hidden = write_yaml(work / "hidden_axis.yaml", {
        "physics": "none", "ball_screw": {"geometry": {"lead_mm": 20.0}},
        "empirical_terms": [
            {"name": "inertia", "params": {"j_kg_m2": 3e-4, "accel_cutoff_hz": 20.0,
                                           "max_gap_s": 0.05}},
            {"name": "viscous_drag", "params": {"c_nm_s_per_rad": 3e-3}},
            {"name": "seal_drag", "params": {"torque_nm": 0.12}},
            {"name": "stribeck", "params": {"torque_nm": 0.06, "velocity_rad_s": 1.0}},
            {"name": "offset", "params": {"torque_nm": 0.02}},
            {"name": "angle_ripple", "params": {"sin1_nm": 0.01}}]})
    # the drive's loop: softer, a compute delay, a 2-sample velocity estimate, 17-bit encoder
    loop = write_yaml(work / "measured_loop.yaml", {"loop": {
        "rate_hz": 1000.0, "position_gain_per_s": 40.0, "velocity_gain_nm_s_per_rad": 0.08,
        "velocity_integral_gain_nm_per_rad": 2.0, "velocity_estimate_span_samples": 2,
        "compute_delay_samples": 1, "torque_limit_nm": 3.0, "velocity_feedforward": 0.8,
        "acceleration_feedforward": 0.5, "encoder_counts_per_rev": 131072}})
    rows = []
    for presliding in (0.0, PRESLIDING_RAD):
        s = load_settings(loop)
        s = dataclasses.replace(s, plant=dataclasses.replace(
            s.plant, presliding_rad=presliding, substeps=16))
        test = generate(ReferenceSpec(kind="reversal", stroke_rev=1.0, accel_rev_s2=20.0),
                        [0.5, 1.0, 2.0], 1000.0, [0.02], "test")
        cal = generate(ReferenceSpec(kind="constant_speed", stroke_rev=2.0, accel_rev_s2=30.0,
                                     dwell_s=0.1), [0.25, 0.5, 1.0, 2.0, 3.0], 1000.0, [0.02],
                       "calibration")
        tag = f"pre{presliding:.0e}"
        rec, calrec = work / f"measured_{tag}.csv", work / f"calibration_{tag}.csv"
        closed_loop_recording(rec, test, s, hidden, pulse_nm=0.05, torque_noise_nm=0.005,
                              seed=1)
        closed_loop_recording(calrec, cal, s, hidden, pulse_nm=0.05, torque_noise_nm=0.005,
                              seed=2)
        disc = work / f"discrepancy_{tag}"
        cli("discrepancy", calrec, "--baseline", "zero", "--out", disc, "--no-progress",
            "--no-plots")
        out = work / f"servo_measured_{tag}"
        cli("servo-test", rec, "--loop", loop, "--config", disc / "augmented.yaml", "--out",
            out, "--measured-loop", "--modes", "none", "--no-progress", "--no-plots")
        ml = summary(out)["measured_loop"]
        terms = ", ".join(e["name"] for e in summary(disc)["effects"])
        rows.append((presliding, ml, terms))
    print("\n2. measured loop: relative errors ||sim - meas|| / ||meas|| of the none run "
          "(plant: the discrepancy workflow's augmented.yaml) and of the rigid-body reference")
    print(f"  {'pre-sliding':>12s} {'plant':>12s} {'angle':>10s} {'velocity':>10s} "
          f"{'torque':>10s} {'moving':>10s} {'standing':>10s}  terms found")
    for pre, ml, terms in rows:
        for key, label in (("none", "model file"), ("rigid_body", "rigid body")):
            r = ml[key]
            phase = r["torque_by_phase"]
            print(f"  {pre * 0.02 / (2 * math.pi) * 1e6:9.1f} um {label:>12s} "
                  f"{r['angle']:10.3g} {r['velocity']:10.3g} {r['torque']:10.3g} "
                  f"{phase['moving']:10.3g} {phase['standing']:10.3g}"
                  + (f"  {terms}" if key == "none" else ""))
    print("  (moving, standing: the torque's relative error split by the reference's motion; "
          "moving^2 + standing^2 = torque^2)")


# --- 3. the ball-to-ball case ----------------------------------------------------------------

def calibrated_model(work, theta_deg=3.0, viscous=3e-3):
    """Return (plant file, augmented.yaml): the product calibrated on a recording of the plant."""
    from bb_friction_ros.servo.reference import generate, ReferenceSpec
    from bb_friction_ros.servo.settings import load_settings
    from bb_friction_ros.servo.synthetic import closed_loop_recording
    plant = screw_file(work / "b2b_plant.yaml", theta_deg,
                       [{"name": "viscous_drag", "params": {"c_nm_s_per_rad": viscous}}])
    base = screw_file(work / "b2b_model.yaml", theta_deg)
    aug = work / "b2b_discrepancy" / "augmented.yaml"
    if aug.exists():
        return plant, aug
    s = load_settings(loop_file(work / "b2b_cal_loop.yaml",
                                plant={"presliding_rad": PRESLIDING_RAD}))
    cal = generate(ReferenceSpec(kind="constant_speed", stroke_rev=2.0, accel_rev_s2=30.0,
                                 dwell_s=0.1), [0.25, 0.5, 1.0, 2.0, 3.0], 1000.0, [0.02],
                   "calibration")
    cal.axial_load_n = 1500.0
    rec = work / "b2b_calibration.csv"
    closed_loop_recording(rec, cal, s, plant, pulse_nm=0.05, torque_noise_nm=0.003, seed=3)
    cli("discrepancy", rec, "--config", base, "--recompute-prediction", "--out",
        aug.parent, "--no-progress", "--no-plots")
    return plant, aug


CASES = (("fresh", "fresh", "fresh"), ("run-in", "run_in", "run_in"),
         ("unknown", "run_in", "fresh"))


def b2b_case(work, plant, model, case, spec, tag, modes=MODES, **loop):
    """Run servo-test for one case; return its summary."""
    name, plant_state, model_state = case
    lf = loop_file(work / f"loop_{tag}_{name}.yaml",
                   plant={"presliding_rad": PRESLIDING_RAD, "ball_state": plant_state},
                   model={"ball_state": model_state}, **loop)
    out = work / f"servo_{tag}_{name}"
    cli("servo-test", spec, "--loop", lf, "--config", model, "--plant", plant, "--out", out,
        "--modes", *modes, "--no-progress", *([] if tag == "circle" else ["--no-plots"]))
    return summary(out)


def print_table(title, results, circle=False):
    """Print the modes x cases table."""
    print(title + " (glitch: reversal glitch max; cruise: cruise RMS; "
          + ("radial: the circle's radial deviation range)" if circle
             else "FE RMS: following error RMS)"))
    cols = ("glitch", "cruise", "radial") if circle else ("glitch", "cruise", "FE RMS")
    keys = ("reversal_glitch_max_um", "cruise_rms_um", "circle") if circle else \
        ("reversal_glitch_max_um", "cruise_rms_um", "following_error_rms_um")
    print("  " + f"{'':27s}" + "".join(f"{name:>30s}" for name, _ in results))
    print("  " + " " * 27 + "".join(f"{c:>10s}" for _ in results for c in cols))
    for mode in results[0][1]["modes"]:
        line = f"  {mode:27s}"
        for _, s in results:
            m = s["modes"][mode]
            for k in keys:
                v = m["circle"]["radial_deviation_range_um"] if k == "circle" else m.get(k)
                line += f"{'-' if v is None else f'{v:.3g}':>10s}"
        print(line)


def part_b2b(work):
    """The ball-to-ball case table (module docstring)."""
    plant, model = calibrated_model(work)
    aug = summary(model.parent)
    print(f"\n3. ball-to-ball case: plant theta = 3 deg + viscous 3e-3 N m s/rad + "
          f"{PRESLIDING_RAD * 0.02 / (2 * math.pi) * 1e6:.0f} um pre-sliding; model "
          f"calibrated by discrepancy: {', '.join(e['name'] for e in aug['effects'])}")
    rev = spec_file(work / "b2b_reversal.yaml", kind="reversal", speeds_rev_s=[1.0],
                    stroke_rev=2.0, accel_rev_s2=20.0, axial_load_n=1500.0)
    circ = spec_file(work / "b2b_circle.yaml", kind="circle", radius_mm=10.0, feed_m_min=2.0,
                     accel_m_s2=1.0, directions="ccw", axial_load_n=1500.0)
    for tag, spec in (("reversal", rev), ("circle", circ)):
        results = [(c[0], b2b_case(work, plant, model, c, spec, tag)) for c in CASES]
        print_table(f"  {tag}: [um] per case ({', '.join(c[0] for c in CASES)})", results,
                    circle=tag == "circle")
    print(f"  ballbar plot of the unknown case: {work / 'servo_circle_unknown' / 'ballbar.png'}")


# --- 6. the safety gate's cost ----------------------------------------------------------------

def part_gate(work):
    """Every mode with and without the safety gate, as ratios to Coulomb + viscous."""
    plant, model = calibrated_model(work)
    rev = spec_file(work / "b2b_reversal.yaml", kind="reversal", speeds_rev_s=[1.0],
                    stroke_rev=2.0, accel_rev_s2=20.0, axial_load_n=1500.0)
    circ = spec_file(work / "b2b_circle.yaml", kind="circle", radius_mm=10.0, feed_m_min=2.0,
                     accel_m_s2=1.0, directions="ccw", axial_load_n=1500.0)
    modes = ["coulomb_viscous", "coulomb_viscous_commanded", "lugre", "lugre_commanded",
             "model", "planned", "truth"]
    case = ("unknown", "run_in", "fresh")
    print("\n6. the safety gate's cost: ratio to coulomb_viscous (gated) of the mean reversal "
          "glitch (reversals at 1 rev/s) and of the circle's radial range; run-in plant, "
          "arrangement unknown")
    rows = {}
    for tag, spec in (("reversal", rev), ("circle", circ)):
        for gate in (True, False):
            name, plant_state, model_state = case
            lf = loop_file(work / f"loop_gate_{tag}.yaml",
                           plant={"presliding_rad": PRESLIDING_RAD, "ball_state": plant_state},
                           model={"ball_state": model_state})
            out = work / f"servo_gate_{tag}_{'on' if gate else 'off'}"
            cli("servo-test", spec, "--loop", lf, "--config", model, "--plant", plant,
                "--out", out, "--modes", *modes, "--no-progress", "--no-plots",
                *([] if gate else ["--no-safety-gate"]))
            rows[(tag, gate)] = summary(out)["modes"]
    cv_rev = rows[("reversal", True)]["coulomb_viscous"]["reversal_glitch_mean_um"]
    cv_circ = rows[("circle", True)]["coulomb_viscous"]["circle"]["radial_deviation_range_um"]
    print(f"  {'mode':27s} {'glitch gated':>13s} {'ungated':>9s} {'radial gated':>13s} "
          f"{'ungated':>9s}")
    for mode in modes:
        g = [rows[("reversal", on)][mode]["reversal_glitch_mean_um"] / cv_rev
             for on in (True, False)]
        c = [rows[("circle", on)][mode]["circle"]["radial_deviation_range_um"] / cv_circ
             for on in (True, False)]
        print(f"  {mode:27s} {g[0]:13.3f} {g[1]:9.3f} {c[0]:13.3f} {c[1]:9.3f}")
    print(f"  (coulomb_viscous gated: glitch {cv_rev:.3g} um, radial range {cv_circ:.3g} um)")


# --- 4. the sweep ----------------------------------------------------------------------------

def part_sweep(work):
    """One factor at a time from the b2b case (module docstring)."""
    _, aug = calibrated_model(work)
    terms = [t for t in yaml.safe_load(aug.read_text()).get("empirical_terms") or []]
    rows = [("base", {}, {})] \
        + [(f"theta {t} deg", {"theta": t}, {}) for t in (0.0, 5.0)] \
        + [(f"load {w:g} N", {"load": w}, {}) for w in (500.0, 3000.0)] \
        + [(f"stroke {s:g} rev", {"stroke": s}, {}) for s in (0.5,)] \
        + [(f"velocity loop {bw} Hz", {},
            {"velocity_gain_nm_s_per_rad": INERTIA * 2 * math.pi * bw}) for bw in (50, 200)] \
        + [(f"servo rate {r:g} Hz", {}, {"rate_hz": r}) for r in (500.0, 2000.0)]
    print("\n4. sweep (run-in plant, model's balls fresh: the unknown arrangement): "
          "reversal glitch max / cruise RMS [um]")
    modes = ["coulomb_viscous", "coulomb_viscous_commanded", "model", "model_commanded",
             "truth"]
    print(f"  {'case':22s}" + "".join(f"{m[:22]:>24s}" for m in ["none"] + modes))
    for i, (label, plant_changes, loop_changes) in enumerate(rows):
        theta = plant_changes.get("theta", 3.0)
        plant = screw_file(work / f"sweep_plant_{i}.yaml", theta,
                           [{"name": "viscous_drag", "params": {"c_nm_s_per_rad": 3e-3}}])
        model = screw_file(work / f"sweep_model_{i}.yaml", theta, terms)
        spec = spec_file(work / f"sweep_spec_{i}.yaml", kind="reversal", speeds_rev_s=[1.0],
                         stroke_rev=plant_changes.get("stroke", 2.0), accel_rev_s2=20.0,
                         axial_load_n=plant_changes.get("load", 1500.0))
        s = b2b_case(work, plant, model, CASES[2], spec, f"sweep{i}", modes, **loop_changes)
        line = f"  {label:22s}"
        for m in ["none"] + modes:
            v = s["modes"][m]
            g, c = v.get("reversal_glitch_max_um"), v.get("cruise_rms_um")
            cell = f"{'-' if g is None else f'{g:.3g}'} / {'-' if c is None else f'{c:.3g}'}"
            line += f"{cell:>24s}"
        print(line, flush=True)


def main():
    """Parse the options and run the parts."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--part", choices=("exact", "speed", "measured", "b2b", "sweep", "node",
                                      "gate", "all"),
                   default="all")
    p.add_argument("--workdir", type=Path, default=None,
                   help="where the recordings and runs go (default: a temporary directory)")
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    work = args.workdir or Path(tempfile.mkdtemp(prefix="bench_servo_"))
    work.mkdir(parents=True, exist_ok=True)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    print(f"bench_servo: work directory {work}")
    if args.part in ("exact", "all"):
        part_exact(work)
    if args.part in ("speed", "all"):
        part_speed(work, args.repeats)
    if args.part in ("measured", "all"):
        part_measured(work)
    if args.part in ("b2b", "all"):
        part_b2b(work)
    if args.part in ("sweep", "all"):
        part_sweep(work)
    if args.part in ("node", "all"):
        part_node(work, args.repeats)
    if args.part in ("gate", "all"):
        part_gate(work)


if __name__ == "__main__":
    main()
