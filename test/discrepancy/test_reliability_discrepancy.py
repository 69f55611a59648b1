"""
The discrepancy workflow on awkward but valid input: clear words instead of wrong advice.

- a config value near its limit: the physical bracket stays within the parameter's range;
- a model that does not converge: the dropped samples are said first;
- a CSV with both a torque and a current column: which one was used is said;
- a workflow equal to the rigid-body reference up to the noise is not called worse;
- a short fast run in a multi-run file does not set the whole file's cut-off;
- an acceleration cut-off too low to be useful is refused naming the key.
"""

import json

import numpy as np
import pytest

from bb_friction_ros.discrepancy import physical as ph
from bb_friction_ros.discrepancy.bandwidth import choose_cutoff, grid_step_s
from bb_friction_ros.discrepancy.data import Recording
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.discrepancy.workflow import (nonconvergence_first, usable,
                                                  worse_than_reference)
from bb_friction_ros.empirical_terms import TermSet

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv


@pytest.mark.parametrize("name, base, hi", [("friction_coefficient", 0.7, 1.0),
                                            ("preload", 98.0, 100.0)])
def test_physical_bracket_stays_within_the_parameters_range(name, base, hi):
    """mu 0.7 x mu_ratio_hi 1.6 asked for 1.12, preload 98 + 4 um for 102: both refused."""
    for s in (ph.PhysicalSettings(), ph.PhysicalSettings(mu_ratio_hi=10.0,
                                                         preload_max_um=100.0)):
        grid = ph.PHYSICAL[name].bracket(base, s)
        assert grid and max(grid) <= hi and min(grid) >= ph.PHYSICAL[name].limits()[0]


def test_samples_the_model_could_not_solve_are_said_first():
    rec = Recording(*(np.zeros(5) for _ in range(8)), info={"config": "theta.yaml"})
    out = nonconvergence_first(["one direction only: ..."], {"model_not_converged": 4}, rec)
    assert out[0].startswith("4 of 5 samples were dropped because the model did not converge")
    assert "theta.yaml" in out[0] and out[1].startswith("one direction only")
    assert nonconvergence_first(["x"], {"model_not_converged": 0}, rec) == ["x"]


@pytest.fixture(scope="module")
def rec(base):
    rng = np.random.default_rng(6)
    fit, _ = synthesize(base, TermSet([draw_effect("seal_drag", rng)]), 0.004, rng)
    return fit


@pytest.mark.parametrize("flag, used", [(["--torque-constant-nm-per-a", "1"],
                                         "torque_meas_nm was ignored"),
                                        ([], "motor_current_a was ignored")])
def test_csv_with_torque_and_current_says_which_was_used(rec, tmp_path, flag, used):
    cols = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_meas_nm",
            "motor_current_a", "torque_pred_nm")
    f = write_csv(tmp_path / "both.csv", rec, columns=cols,
                  extra={"motor_current_a": rec.torque_meas_nm})
    assert run_cli(["--no-physical",
                    f, "--out", tmp_path / "o", "--no-progress", "--no-plots", *flag]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert any(used in w for w in s["warnings"])


def test_equal_to_the_reference_up_to_the_noise_is_not_worse():
    assert not worse_than_reference(0.0175737, 0.0175734)
    assert worse_than_reference(0.0212, 0.0175734)
    assert not worse_than_reference(0.02, None)


def _runs(rates_rows):
    t = np.concatenate([np.arange(n) / rate for rate, n in rates_rows])
    n = t.size
    w = 3.0 * np.sin(2.0 * np.pi * 0.5 * t)
    return Recording(t, t, np.cumsum(w) * 0.001, w, np.full(n, 1000.0),
                     0.05 * np.sign(w) + 0.01 * w, np.zeros(n), np.ones(n, bool))


def test_short_fast_run_does_not_set_the_cutoff_of_the_file():
    """40 rows at 2 kHz, then 3000 at 50 Hz: the grid tops at 0.2 x 50 Hz, not 400 Hz."""
    r = _runs([(2000.0, 40), (50.0, 3000)])
    assert grid_step_s(r, DiscrepancySettings().accel_grid_min_share) == pytest.approx(0.02)
    # a fast run holding a fifth of the samples still tops the grid (the RViMLab exports)
    assert grid_step_s(_runs([(2000.0, 800), (50.0, 3000)]), 0.1) == pytest.approx(5e-4)
    choice = choose_cutoff(r, DiscrepancySettings(), usable)
    assert choice.cutoff_hz <= 10.0 + 1e-9


def test_acceleration_cutoff_below_its_useful_range_is_refused(rec, tmp_path, capsys):
    """5e-324 Hz wrote Infinity into summary.json, which is not JSON."""
    settings = tmp_path / "s.yaml"
    settings.write_text("discrepancy:\n  accel_cutoff_hz: 5e-324\n")
    f = write_csv(tmp_path / "a.csv", rec)
    assert run_cli(["--no-physical", f, "--out", tmp_path / "o", "--settings", settings,
                    "--no-progress", "--no-plots"]) == 2
    assert "discrepancy.accel_cutoff_hz" in capsys.readouterr().out
    summary = tmp_path / "o" / "summary.json"           # marked partial, and JSON
    assert not summary.exists() or json.loads(summary.read_text())["complete"] is False
