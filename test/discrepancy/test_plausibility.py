"""
A measurement of the wrong sign or scale is refused before anything is fitted to it.

Friction has the sign of the nut velocity; a motor current positive in the other direction
used to give a model with a negative friction coefficient that fed forward along the motion.
"""

import dataclasses

import numpy as np
import pytest

from bb_friction_ros.discrepancy.plausibility import measured_sign_check
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.empirical_terms import make_term, TermSet

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv

K_NM_PER_A = 0.05
COLUMNS = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_meas_nm",
           "torque_pred_nm")


@pytest.fixture(scope="module")
def rec(base):
    """A recording with seal drag and viscous drag on top of the model."""
    rng = np.random.default_rng(37)
    hidden = TermSet([draw_effect("seal_drag", rng), draw_effect("viscous_drag", rng)])
    fit, _ = synthesize(base, hidden, 0.004, rng)
    return fit


def _current_csv(path, rec, sign):
    cols = COLUMNS[:4] + ("motor_current_a", "torque_pred_nm")
    return write_csv(path, rec, columns=cols,
                     extra={"motor_current_a": sign * rec.torque_meas_nm / K_NM_PER_A})


def test_motor_current_of_the_opposite_sign_is_refused_naming_the_flag(rec, tmp_path, capsys):
    good = _current_csv(tmp_path / "good.csv", rec, 1.0)
    assert run_cli(["--no-physical", good, "--out", tmp_path / "g", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 0
    capsys.readouterr()
    bad = _current_csv(tmp_path / "bad.csv", rec, -1.0)
    assert run_cli(["--no-physical", bad, "--out", tmp_path / "b", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 2
    err = capsys.readouterr().err
    assert "follows the motion" in err and "--torque-constant-nm-per-a" in err
    assert "motor_current_a" in err and str(bad) in err
    assert not (tmp_path / "b" / "augmented.yaml").exists()


def test_torque_column_of_the_opposite_sign_is_refused_naming_the_column(
        rec, tmp_path, capsys):
    neg = dataclasses.replace(rec, torque_meas_nm=-rec.torque_meas_nm)
    f = write_csv(tmp_path / "neg.csv", neg)
    assert run_cli(["--no-physical",
                    f, "--out", tmp_path / "o", "--no-progress", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "follows the motion" in err and "torque_meas_nm" in err


def test_sign_rule_sees_through_a_gravity_offset(rec):
    """An offset larger than the friction: half the samples oppose either way."""
    s = DiscrepancySettings()
    offset = 3.0 * np.max(np.abs(rec.torque_meas_nm))
    up = dataclasses.replace(rec, torque_meas_nm=rec.torque_meas_nm + offset)
    down = dataclasses.replace(rec, torque_meas_nm=-rec.torque_meas_nm + offset)
    c_up, se_up, _, _ = measured_sign_check(up, s)
    c_down, se_down, against, _ = measured_sign_check(down, s)
    assert c_up > s.sign_error_z * se_up
    assert c_down < -s.sign_error_z * se_down
    assert 0.3 < against < 0.7      # a share rule alone would not see it


def test_pure_noise_is_not_called_a_sign_error(rec):
    rng = np.random.default_rng(5)
    noise = dataclasses.replace(rec, torque_meas_nm=rng.normal(0.0, 0.01, len(rec)))
    c, se, _, _ = measured_sign_check(noise, DiscrepancySettings())
    assert c > -DiscrepancySettings().sign_error_z * se


@pytest.mark.parametrize("k", ["1e-300", "1e100", "1e200"])
def test_torque_constant_outside_a_motors_range_is_refused(rec, tmp_path, capsys, k):
    f = _current_csv(tmp_path / "c.csv", rec, 1.0)
    assert run_cli(["--no-physical", f, "--out", tmp_path / "o", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", k]) == 2
    err = capsys.readouterr().err
    assert "--torque-constant-nm-per-a" in err and "not a motor's torque constant" in err
    assert not (tmp_path / "o").exists()


def test_measured_torque_orders_of_magnitude_off_the_model_is_refused(rec, tmp_path, capsys):
    milli = dataclasses.replace(rec, torque_meas_nm=1000.0 * rec.torque_meas_nm)
    f = write_csv(tmp_path / "mNm.csv", milli)
    assert run_cli(["--no-physical",
                    f, "--out", tmp_path / "o", "--no-progress", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "times the model's prediction" in err and "max_measured_scale_ratio" in err


def test_a_term_set_that_overturns_the_physics_is_friction_of_the_wrong_sign():
    """The terms that are not friction (offset, inertia) may take either sign."""
    terms = TermSet([make_term("offset", {"torque_nm": -5.0})])
    assert terms.friction_nm(0.0, 0.0, 1.0, 1000.0) == 0.0
    terms = TermSet([make_term("load_dependent", {"k_nm_per_n": -1e-4})])
    assert terms.friction_nm(0.0, 0.0, 1.0, 1000.0) == pytest.approx(-0.1)
