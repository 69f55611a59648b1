"""The theta-amplitude sweep of Fig. 19: spec, Fig. 21 outputs, calibration to one feature."""

import math
import subprocess
import sys

import numpy as np
import pytest

from bb_friction_ros.config import bundled_config
from bb_friction_ros.sweep import theta_amplitude as ta
from bb_friction_ros.sweep.models import FAILED, MODELS, OK, evaluate
from bb_friction_ros.sweep.spec import load_spec


def _rows(amps_deg, shares, elastic=0.0):
    return {ta.AMPLITUDE: np.radians(amps_deg), ta.ELASTIC: np.full(len(amps_deg), elastic),
            "fig21_peak_b2b_share": np.asarray(shares, dtype=float)}


def test_bundled_spec_is_the_whole_grid():
    spec = load_spec(bundled_config(ta.SPEC_NAME))
    assert spec.model == "whole_screw"
    assert spec.n_samples == 26            # 13 amplitudes 2-5 deg x rigid, elastic
    assert "fig21_peak_b2b_share" in spec.outputs


def test_calibration_solves_the_line_through_the_crossing():
    # share = 0.2 (A - 1 deg): 49.6 % at 3.48 deg exactly, no scatter
    amps = np.arange(2.0, 5.01, 0.25)
    amp, unc = ta.calibrate_amplitude(_rows(amps, 0.2 * (amps - 1.0)), elastic=False)
    assert math.degrees(amp) == pytest.approx(3.48, abs=1e-9)
    assert unc == pytest.approx(0.0, abs=1e-12)


def test_calibration_reports_scatter_and_refuses_a_sweep_that_never_crosses():
    amps = np.arange(2.0, 5.01, 0.25)
    wobble = 0.01 * (-1.0) ** np.arange(amps.size)
    amp, unc = ta.calibrate_amplitude(_rows(amps, 0.2 * (amps - 1.0) + wobble), False)
    assert abs(math.degrees(amp) - 3.48) < 0.1 and math.degrees(unc) > 0.01
    assert ta.calibrate_amplitude(_rows(amps, np.full(amps.size, 0.3)), False) is None


def test_whole_screw_sample_records_the_fig21_features():
    model = MODELS["whole_screw"]
    base = model.load_base(None, {"operation": {"n_steps": 40, "duration_s": 0.4}})
    names = {"errors.theta_amplitude_rad"}
    params = {"errors.theta_amplitude_rad": math.radians(3.44), "elastic_load_distribution": 1}
    out, status, _ = evaluate(model, base, params, {"settle_steps": 0}, names)
    assert status == OK
    assert 0.3 < out["fig21_peak_b2b_share"] < 0.7
    assert math.radians(60) < out["fig21_peak_nut_angle_rad"] < math.radians(140)
    # the smoothed peak is a peak of the same hump: within the smoothing window of the raw one
    from bb_friction_ros.ball_screw.simulation import PEAK_SMOOTHING_WINDOW_RAD
    assert abs(out["fig21_peak_nut_angle_smoothed_rad"] - out["fig21_peak_nut_angle_rad"]) \
        <= PEAK_SMOOTHING_WINDOW_RAD
    assert out["max_groups"] == 4
    params["elastic_load_distribution"] = 2
    _, status, reason = evaluate(model, base, params, {"settle_steps": 0}, names)
    assert status == FAILED and "elastic_load_distribution" in reason


def test_reproduce_imports_no_sweep_engine():
    """Reproducing the paper needs neither Dask nor Arrow (start-up cost), in a clean process."""
    code = ("import sys, bb_friction_ros.reproduce; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed', 'pyarrow') or m == 'bb_friction_ros.sweep.engine'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_in_process_sweep_is_the_engine_s_samples():
    """run_theta_sweep gives the rows the engine's own batch function gives for the same spec."""
    from bb_friction_ros.sweep.engine import run_batch
    rows = ta.run_theta_sweep(coarse=True)
    spec = load_spec(bundled_config(ta.SPEC_NAME),
                     {"grid": {"errors.theta_amplitude_deg": {"start": 2.0, "stop": 5.0,
                                                              "num": 7},
                               ta.ELASTIC: [0, 1]}})
    batches = [run_batch(spec, b) for b in range(spec.n_batches)]
    assert len(rows["sample"]) == spec.n_samples == 14
    for name in ("sample", ta.AMPLITUDE, ta.ELASTIC, *spec.outputs):
        engine = np.concatenate([np.asarray(b[name], dtype=float) for b in batches])
        np.testing.assert_array_equal(rows[name], engine, err_msg=name)
