"""
The simulator is exact: on a closed-loop recording made by a known plant and loop, the
``none`` mode reproduces the recorded angle and torque within the integrator's error.
"""

import dataclasses

import numpy as np
import pytest

from bb_friction_ros.servo.modes import Mode
from bb_friction_ros.servo.reference import load_reference
from bb_friction_ros.servo.run import relative_errors, Setup
from bb_friction_ros.servo.settings import load_settings
from bb_friction_ros.servo.synthetic import closed_loop_recording

# The integrator error stated in docs/servo_test.md for the default plant (8 sub-steps per
# 1 ms servo period, the friction re-answered at each), measured against 64 sub-steps:
# relative torque error (its floor is the encoder: one count is K_v q / T = 0.75 mN m) and
# largest encoder-angle difference.
TORQUE_REL = 1e-2
ANGLE_UM = 0.25


def _record(tmp_path, loop_file, spec, model, **plant):
    s = load_settings(loop_file)
    s = dataclasses.replace(s, plant=dataclasses.replace(s.plant, **plant))
    ref = load_reference(spec, s.loop.rate_hz, [0.02])
    path = tmp_path / "recording.csv"
    cols = closed_loop_recording(path, ref, s, model, pulse_nm=0.05)
    return path, cols


def _replay(path, loop_file, model):
    s = load_settings(loop_file)
    ref = load_reference(path, s.loop.rate_hz, [0.02])
    run = Setup(s, model).simulate_axis(ref, ref.axes[0], Mode("none"))
    return ref, run


def test_same_integration_reproduces_the_recording_to_rounding(tmp_path, loop_file,
                                                               short_spec, axis_model):
    """Same plant settings as the recorder: the CSV round trip and the run are exact."""
    path, cols = _record(tmp_path, loop_file, short_spec, axis_model)
    ref, run = _replay(path, loop_file, axis_model)
    err = relative_errors(ref.t_s, run, ref.axes[0])
    assert max(err["angle"], err["velocity"], err["torque"],
               *err["torque_by_phase"].values()) < 1e-12
    assert np.any(cols["command_offset_nm"] != 0.0)     # the test pulses are in the loop


def test_none_mode_reproduces_a_finer_recorder_within_the_stated_integrator_error(
        tmp_path, loop_file, short_spec, axis_model):
    path, cols = _record(tmp_path, loop_file, short_spec, axis_model, substeps=64,
                         friction_update="substep")
    ref, run = _replay(path, loop_file, axis_model)
    err = relative_errors(ref.t_s, run, ref.axes[0])
    assert err["torque"] < TORQUE_REL
    diff_um = np.max(np.abs(run.measured_rad - cols["nut_angle_rad"])) * 0.02 / 6.283185 * 1e6
    assert diff_um < ANGLE_UM
    assert err["torque"] > 0.0          # a different integration: not trivially equal


def test_recorded_torque_is_what_the_drive_applied(tmp_path, loop_file, short_spec,
                                                   axis_model):
    """torque_meas_nm = the command after the limit plus the offset (the drive's log)."""
    path, cols = _record(tmp_path, loop_file, short_spec, axis_model)
    ref, run = _replay(path, loop_file, axis_model)
    assert np.allclose(run.applied_nm, cols["torque_meas_nm"], rtol=0, atol=1e-12)
    assert run.applied_nm == pytest.approx(run.command_nm)      # no compute delay here
