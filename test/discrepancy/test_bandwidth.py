"""
The acceleration cut-off chosen from the data (discrepancy/bandwidth.py).

A fixed 10 Hz filter missed the peaks of short servo moves and inflated the inertia: the
cut-off is chosen by blocked cross-validation, travels to augmented.yaml, is reported on a slow
log, and a configured one above the highest safe cut-off is refused naming the key.
"""

import dataclasses
import json

import numpy as np
import pytest

from bb_friction_ros.discrepancy.servo_moves import Drive, servo_recording
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.discrepancy.workflow import analyse, summary_of
from bb_friction_ros.empirical_terms import filter_lag_s, TermSet

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv

SETTINGS = DiscrepancySettings()


def test_cutoff_chosen_from_the_data_at_2_khz(tmp_path):
    """
    Servo moves with sharp acceleration edges, recorded at 2 kHz: the fixed 10 Hz filter
    removed half the reducible gap (J 17 % high); the chosen cut-off removes >= 80 %.
    """
    rec, _ = servo_recording(2000.0, 10.0)
    drive = Drive()
    chosen = analyse(rec, SETTINGS)
    fixed = analyse(rec, dataclasses.replace(SETTINGS, accel_cutoff_hz=10.0))
    s = summary_of(chosen)
    acc = s["acceleration"]
    assert acc["chosen_by"].startswith("blocked cross-validation")
    assert len(acc["candidates"]) == SETTINGS.accel_cutoff_grid_points
    # the one-standard-error rule, towards the highest cut-off (bandwidth.py)
    lowest = min(c["cv_mse_nm2"] for c in acc["candidates"])
    assert acc["cutoff_hz"] == max(c["cutoff_hz"] for c in acc["candidates"]
                                   if c["cv_mse_nm2"] <= lowest + acc["one_se_nm2"])
    assert all(c["within_one_se"] == (c["cv_mse_nm2"] <= lowest + acc["one_se_nm2"])
               for c in acc["candidates"])
    assert acc["cutoff_hz"] <= SETTINGS.accel_max_cutoff_fraction * 2000.0 + 1e-9
    assert acc["live_lag_s"] == pytest.approx(filter_lag_s(acc["cutoff_hz"]))
    j = {e["name"]: e["params"] for e in s["effects"]}["inertia"]
    assert j["j_kg_m2"] == pytest.approx(drive.j_kg_m2, rel=0.05)
    assert j["accel_cutoff_hz"] == acc["cutoff_hz"]          # travels to augmented.yaml

    def removed(a):
        return (a.rmse_before_nm - a.rmse_after_nm) / (a.rmse_before_nm - drive.noise_nm)
    assert removed(chosen) >= 0.8 > removed(fixed) + 0.2
    assert summary_of(fixed)["acceleration"]["chosen_by"] == "settings (accel_cutoff_hz)"


def test_10_hz_log_runs_with_a_reported_cutoff(tmp_path):
    """A 10 Hz log of the same drive: a cut-off <= 2 Hz and the report says what it means."""
    rec, _ = servo_recording(10.0, 60.0)
    a = write_csv(tmp_path / "log10.csv", rec)
    assert run_cli([a, "--out", tmp_path / "o", "--no-progress"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    acc = s["acceleration"]
    assert acc["sample_rate_hz"] == pytest.approx(10.0)
    assert acc["cutoff_hz"] <= 2.0 + 1e-9
    # either not identifiable at all, or bandwidth-limited: never silently "resolved"
    assert (not acc["inertia_identifiable"]) or acc["bandwidth_limited"]
    report = (tmp_path / "o" / "report.md").read_text()
    assert "Inertia cannot be identified here" in report or "Bandwidth-limited" in report


def test_clean_recording_without_inertia_says_inertia_untested(base):
    rng = np.random.default_rng(2)
    rec, _ = synthesize(base, TermSet([draw_effect("seal_drag", rng)]), 0.004, rng)
    a = analyse(rec, SETTINGS)
    s = summary_of(a)
    assert not s["acceleration"]["inertia_identifiable"]
    assert "inertia" in a.untested and "inertia" not in a.terms.names


def test_cutoff_above_the_safe_limit_is_refused_naming_the_key(pair, tmp_path, capsys):
    fit, _, _ = pair                       # 50 Hz: the highest safe cut-off is 10 Hz
    a = write_csv(tmp_path / "a.csv", fit)
    settings = tmp_path / "s.yaml"
    settings.write_text("discrepancy:\n  accel_cutoff_hz: 30\n")
    assert run_cli([a, "--out", tmp_path / "o", "--settings", settings,
                    "--no-progress"]) == 2
    out = capsys.readouterr().out
    assert "discrepancy.accel_cutoff_hz: 30 Hz is above the highest safe cut-off" in out
    assert "Nyquist 25 Hz" in out
