"""
Closed-loop recordings made by a known plant and loop: what the servo test is checked on.

``closed_loop_recording`` runs a plant (a model file, with the plant settings given: a
finer integration than the servo test's default, pre-sliding, a ball state) in a known loop
(LoopSettings: its gains, delay, encoder) along a reference, with test pulses added to the
drive command, and writes what a drive logs: the reference, the encoder's angle, the drive
torque (applied command plus offset, with sensor noise if asked) and the command offset.
The same CSV carries the discrepancy workflow's columns (``nut_velocity_rad_s`` from the
encoder angle, ``torque_pred_nm`` 0: no model of the screw), so ``bb-friction discrepancy``
calibrates on it as it would on a drive's log.
"""

import dataclasses

import numpy as np

from bb_friction_ros.servo.modes import Mode
from bb_friction_ros.servo.run import Setup

COLUMNS = ("t_s", "nut_angle_ref_rad", "nut_angle_rad", "torque_meas_nm", "command_offset_nm",
           "axial_load_n", "nut_velocity_rad_s", "torque_pred_nm")


def test_pulses(t_s, amplitude_nm, period_s=0.5, width_s=0.02):
    """Return a command offset: +-``amplitude_nm`` pulses of ``width_s`` every ``period_s``."""
    if amplitude_nm == 0.0:
        return np.zeros(t_s.size)
    phase = np.mod(t_s, period_s)
    sign = np.where(np.mod(np.floor(t_s / period_s), 2) == 0, 1.0, -1.0)
    return np.where(phase < width_s, sign * amplitude_nm, 0.0)


def closed_loop_recording(path, reference, settings, plant_path, pulse_nm=0.0,
                          torque_noise_nm=0.0, seed=0):
    """
    Run ``plant_path`` in ``settings``' loop along ``reference``; write and return the CSV.

    Returns {column: array}.  ``settings.plant`` sets the plant's integration (use a finer
    one than the servo test's to measure its error), pre-sliding and ball state.
    """
    setup = Setup(settings, plant_path)
    axis = reference.axes[0]
    axis = dataclasses.replace(axis, command_offset_nm=test_pulses(reference.t_s, pulse_nm))
    run = setup.simulate_axis(reference, axis, Mode("none"))
    rng = np.random.default_rng(seed)
    t = reference.t_s
    cols = {"t_s": t, "nut_angle_ref_rad": axis.ref_rad, "nut_angle_rad": run.measured_rad,
            "torque_meas_nm": run.applied_nm + rng.normal(0.0, torque_noise_nm, t.size)
            if torque_noise_nm > 0.0 else run.applied_nm,
            "command_offset_nm": axis.command_offset_nm,
            "axial_load_n": setup.loads(reference, axis),
            "nut_velocity_rad_s": np.gradient(run.measured_rad, t),
            "torque_pred_nm": np.zeros(t.size)}
    with open(path, "w") as fh:
        fh.write(",".join(COLUMNS) + "\n")
        for row in np.column_stack([cols[c] for c in COLUMNS]):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    cols["plant_angle_rad"] = run.angle_rad
    return cols
