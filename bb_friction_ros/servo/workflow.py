"""
``run_servo_test``: the whole servo test, from files to the output directory.

Order: settings and files checked (nothing written before), the reference loaded, the
baselines fitted on the calibration run, every mode run on the same reference, the
measured-loop check when the recording holds the measured angle and drive torque, then
``modes/<mode>.csv`` (``none`` always), ``summary.json``, plots and ``report.md``.
"""

from pathlib import Path
import sys
import time

from bb_friction_ros.servo import modes as modes_mod
from bb_friction_ros.servo.metrics import mode_metrics
from bb_friction_ros.servo.outputs import verdict, write_mode_csv, write_plots, write_report, \
    write_summary
from bb_friction_ros.servo.run import check_modes, load, MEASURED_CHANNELS, Setup
from bb_friction_ros.servo.settings import load_settings


def run_servo_test(recording, loop_path, config, out, modes=(), progress=True, plant=None,
                   calibration=None, config_y=None, plots=True, measured_loop=None,
                   settings=None, safety_gate=True):
    """
    Run the servo test and write its outputs to ``out``; return the summary.

    ``modes``: the feedforward modes besides ``none`` (default: every one but ``node``).
    ``plant``: the plant's model file (default ``config``).  ``calibration``: a recording
    CSV the baselines and the rigid-body reference are fitted on.  ``measured_loop``: True
    requires the recording's measured channels, None compares when it has them.
    ``safety_gate`` False: a study of what the feedforward safety gate costs (servo.modes).
    """
    settings = settings or load_settings(loop_path)
    names = check_modes(modes or [m for m in modes_mod.BASE_MODES if m != "none"])
    need = MEASURED_CHANNELS if measured_loop else ()
    setup = Setup(settings, config, plant, config_y)
    setup.safety_gate = bool(safety_gate)
    reference = load(recording, settings, config, need, config_y)
    axis = reference.axes[0]
    has_measured = axis.meas_rad is not None and axis.torque_meas_nm is not None
    out = Path(out)
    say = (lambda msg: print(msg, file=sys.stderr)) if progress else (lambda msg: None)
    t_start = time.process_time()
    cal = setup.calibrate(reference, calibration)
    say(f"servo-test: baselines fitted on {cal.source}")
    results, cpu = {}, {}
    for name in names:
        t0 = time.process_time()
        if name == "node":
            from bb_friction_ros.servo.node_mode import run_node_mode
            results[name] = run_node_mode(setup, reference)
        elif name == "node_planned":
            from bb_friction_ros.servo.node_mode import run_node_planned_mode
            results[name] = run_node_planned_mode(setup, reference)
        else:
            results[name] = setup.run_mode(reference, name)
        cpu[name] = time.process_time() - t0
        say(f"servo-test: {name}: {cpu[name]:.2f} s CPU")
    duration = float(reference.t_s[-1] - reference.t_s[0])
    summary = {
        "recording": str(recording), "loop_file": str(loop_path), "model_file": str(config),
        "reference": {"source": reference.source, "kind": reference.kind,
                      "duration_s": duration, "axes": [a.name for a in reference.axes]},
        "loop": {k: getattr(settings.loop, k) for k in settings.loop.__dataclass_fields__},
        "plant": {"model_file": setup.plant_path, "inertia_kg_m2": setup.inertia,
                  **{k: getattr(settings.plant, k)
                     for k in settings.plant.__dataclass_fields__}},
        "lead_m": setup.lead_m,
        "safety_gate": setup.safety_gate,
        "calibration_source": cal.source,
        "baselines": {"coulomb_viscous": setup.fits["coulomb_viscous"].summary(),
                      "lugre": setup.fits["lugre"].summary()},
        "modes": {},
    }
    for name, runs in results.items():
        m = mode_metrics(reference, runs, setup.lead_m)
        counters = {}
        for r in runs:
            for k, v in r.counters.items():
                counters[k] = counters.get(k, 0) + v
        m["timing"] = modes_mod.timing_of(name)
        m["counters"] = counters
        m["cpu_s"] = cpu[name]
        m["simulated_s_per_cpu_s"] = duration * len(runs) / cpu[name] if cpu[name] else None
        if name in ("node", "node_planned"):
            m["node"] = runs.coverage
        summary["modes"][name] = m
    if has_measured:
        ml = setup.measured_loop(reference, results["none"][0], calibration)
        ml.pop("rigid_body_run", None)
        summary["measured_loop"] = ml
    summary["verdict"] = verdict(summary)
    summary["cpu_s"] = time.process_time() - t_start
    out.mkdir(parents=True, exist_ok=True)
    (out / "modes").mkdir(exist_ok=True)
    for name, runs in results.items():
        write_mode_csv(out / "modes" / f"{name}.csv", reference, runs, setup.lead_m)
    write_summary(out / "summary.json", summary)
    if plots:
        write_plots(out, reference, results, setup.lead_m)
    write_report(out / "report.md", summary)
    return summary
