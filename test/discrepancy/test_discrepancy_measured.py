"""
The discrepancy workflow on inputs a user brings: validation, baselines, bad input, noise.

- --validate: DIR/validation/prediction.csv, summary.json["validation"], report; a bad
  validation file exits 2 naming it.
- --baseline zero for bags; a CSV whose torque_pred_nm is 0 is the same.
- inertia: the replay (the runner) evaluates it with the causal filter: live = replay.
- bad input exits 2: non-finite values, a recording too short to derive alpha.
- rows out of time order are refused (reversed crashed before), runs accepted;
- a fit that does not improve the held-out part is verdict "none", with why;
- a CSV with a UTF-8 byte-order mark is read.
- noise: on smooth (low-pass filtered) noise the estimate holds and selection does not call
  every regime significant; stroke_position is named on a trajectory that travels.
"""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from bb_friction_ros.bags import with_measurement, write_events
from bb_friction_ros.config import bundled_config
from bb_friction_ros.discrepancy.data import Recording, run_times
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.discrepancy.workflow import analyse, summary_of
from bb_friction_ros.empirical_terms import AccelerationFilter, make_term, TermSet
from bb_friction_ros.model_file import read_model_file, write_model_file
from bb_friction_ros.replay import replay

from .test_discrepancy_inputs import run_cli

SETTINGS = DiscrepancySettings()
COLUMNS = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_meas_nm",
           "torque_pred_nm")


def write_csv(path, rec, columns=COLUMNS, bom=False, extra=None):
    cols = {"t_s": rec.t_s, "nut_angle_rad": rec.nut_angle_rad,
            "nut_velocity_rad_s": rec.nut_velocity_rad_s, "axial_load_n": rec.axial_load_n,
            "torque_meas_nm": rec.torque_meas_nm, "torque_pred_nm": rec.torque_pred_nm}
    cols.update(extra or {})
    with open(path, "w", newline="", encoding="utf-8-sig" if bom else "utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in zip(*(cols[c] for c in columns)):
            w.writerow(repr(float(v)) for v in row)
    return path


@pytest.fixture(scope="module")
def pair(base):
    """Two recordings of the same hidden effects (different noise): fit and validate."""
    rng = np.random.default_rng(11)
    hidden = TermSet([draw_effect("seal_drag", rng), draw_effect("inertia", rng)])
    fit, _ = synthesize(base, hidden, 0.004, rng)
    val, _ = synthesize(base, hidden, 0.004, rng)
    return fit, val, hidden


def test_validate_writes_prediction_and_summary(pair, tmp_path, capsys):
    fit, val, hidden = pair
    a, b = write_csv(tmp_path / "fit.csv", fit), write_csv(tmp_path / "val.csv", val)
    out = tmp_path / "out"
    assert run_cli(["--no-physical", a, "--validate", b, "--out", out, "--no-progress"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert {e["name"] for e in s["effects"]} == {"seal_drag", "inertia"}
    v = s["validation"]
    assert {"n", "rmse_before_nm", "rmse_after_nm", "relative_error_before",
            "relative_error_after"} <= set(v)
    rows = np.genfromtxt(out / "validation" / "prediction.csv", delimiter=",", names=True)
    assert rows.dtype.names == ("t_s", "torque_meas_nm", "torque_pred_nm",
                                "torque_augmented_nm")
    assert v["n"] == rows.size == len(val)
    e_before = rows["torque_meas_nm"] - rows["torque_pred_nm"]
    e_after = rows["torque_meas_nm"] - rows["torque_augmented_nm"]
    assert v["rmse_before_nm"] == pytest.approx(np.sqrt(np.mean(e_before ** 2)))
    assert v["relative_error_after"] == pytest.approx(
        np.linalg.norm(e_after) / np.linalg.norm(rows["torque_meas_nm"]))
    assert v["rmse_after_nm"] < 1.3 * 0.004 < v["rmse_before_nm"]
    report = (out / "report.md").read_text()
    assert "Validation on a second recording" in report and "validation.png" in report
    assert (out / "validation.png").is_file()
    assert "validation on" in capsys.readouterr().out


def test_validate_file_with_missing_columns_exits_2(pair, tmp_path, capsys):
    fit, val, _ = pair
    a = write_csv(tmp_path / "fit.csv", fit)
    b = write_csv(tmp_path / "val.csv", val, columns=COLUMNS[:4])
    assert run_cli(["--no-physical",
                    a, "--validate", b, "--out", tmp_path / "o", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "val.csv" in err and "torque_meas_nm" in err


def test_non_finite_values_exit_2(pair, tmp_path, capsys):
    fit, _, _ = pair
    accel = np.zeros(len(fit))
    accel[7] = np.nan
    a = write_csv(tmp_path / "a.csv", fit, COLUMNS + ("nut_accel_rad_s2",),
                  extra={"nut_accel_rad_s2": accel})
    assert run_cli(["--no-physical", a, "--out", tmp_path / "o", "--no-progress"]) == 2
    assert "nut_accel_rad_s2 has non-finite values (first at line 9)" in capsys.readouterr().err


def test_acceleration_column_overrides_the_derived_one(pair, tmp_path):
    fit, _, _ = pair
    own = np.full(len(fit), 3.0)
    a = write_csv(tmp_path / "a.csv", fit, COLUMNS + ("nut_accel_rad_s2",),
                  extra={"nut_accel_rad_s2": own})
    assert run_cli(["--no-physical",
                    a, "--out", tmp_path / "o", "--no-progress", "--no-plots"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["acceleration"]["source"] == "csv column nut_accel_rad_s2"
    # a constant alpha is an offset in disguise: inertia is not named with it
    assert "inertia" not in {e["name"] for e in s["effects"]}


def test_too_short_to_derive_acceleration_exits_2(pair, tmp_path, capsys):
    fit, _, _ = pair
    n = len(fit)
    t = np.arange(n) * 0.02 + np.repeat(np.arange(math.ceil(n / 4)), 4)[:n] * 5.0
    rec = dataclasses.replace(fit, t_s=t)      # every 4 samples a 5 s gap: no segment of 5
    a = write_csv(tmp_path / "a.csv", rec)
    assert run_cli(["--no-physical", a, "--out", tmp_path / "o", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "too short to derive the acceleration" in err


def test_rows_out_of_time_order_are_refused(pair, tmp_path, capsys):
    """Shuffled rows gave a wrong verdict, reversed rows crashed: now both are refused."""
    fit, _, _ = pair
    rng = np.random.default_rng(0)
    for name, order in (("shuffled", rng.permutation(len(fit))),
                        ("reversed", np.arange(len(fit))[::-1])):
        a = write_csv(tmp_path / f"{name}.csv", fit.take(order))
        assert run_cli(["--no-physical", a, "--out", tmp_path / name, "--no-progress",
                        "--recompute-prediction"]) == 2
        err = capsys.readouterr().err
        assert "rows are not in time order" in err and "sort the file by t_s" in err


def test_consecutive_runs_are_accepted_and_said(pair, tmp_path):
    fit, _, _ = pair
    two = Recording(*(np.concatenate([getattr(fit, f), getattr(fit, f)]) for f in
                      ("t_s", "t_run_s", "nut_angle_rad", "nut_velocity_rad_s",
                       "axial_load_n", "torque_meas_nm", "torque_pred_nm", "converged")))
    a = write_csv(tmp_path / "runs.csv", two)
    assert run_cli(["--no-physical",
                    a, "--out", tmp_path / "o", "--no-progress", "--no-plots"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["input"]["runs"] == 2


def test_csv_with_a_byte_order_mark(pair, tmp_path):
    """A spreadsheet's BOM used to give 'lacks column(s) t_s ... has: t_s'."""
    fit, _, _ = pair
    a = write_csv(tmp_path / "bom.csv", fit, bom=True)
    assert a.read_bytes().startswith(b"\xef\xbb\xbf")
    assert run_cli(["--no-physical",
                    a, "--out", tmp_path / "o", "--no-progress", "--no-plots"]) == 0


def test_fit_that_does_not_improve_the_held_out_part_is_none(base):
    """A drag in the first 70 % only: fitted, but worse on the held-out part."""
    rng = np.random.default_rng(3)
    rec, _ = synthesize(base, TermSet(), 0.004, rng)
    n = len(rec)
    first = np.arange(n) < int(0.7 * n)
    drag = 0.05 * np.sign(rec.nut_velocity_rad_s) * np.where(first, 1.0, -1.0)
    rec = dataclasses.replace(rec, torque_meas_nm=rec.torque_meas_nm + drag)
    a = analyse(rec, SETTINGS)
    s = summary_of(a)
    assert s["verdict"] == "none" and s["effects"] == []
    assert "do not improve the held-out part" in s["reason"]
    assert "seal_drag" in {e["name"] for e in s["rejected_effects"]}
    assert a.rmse_after_nm == a.rmse_before_nm


def test_bag_with_baseline_zero(base, tmp_path):
    """--baseline zero: no model run; the terms are the whole measured torque."""
    rng = np.random.default_rng(5)
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.2}),
                      make_term("viscous_drag", {"c_nm_s_per_rad": 0.01})])
    r = base.recording
    meas = hidden.torque_nm(r.t_run_s, r.nut_angle_rad, r.nut_velocity_rad_s,
                            r.axial_load_n) + rng.normal(0, 0.003, len(r))
    bag = tmp_path / "bag"
    write_events(bag, with_measurement(base.events, meas), storage="sqlite3")
    assert run_cli(["--no-physical",
                    bag, "--baseline", "zero", "--out", tmp_path / "o", "--no-progress"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["identified_from_data_only"] and s["input"]["baseline"] == "zero"
    got = {e["name"]: e["params"] for e in s["effects"]}
    assert got["seal_drag"]["torque_nm"] == pytest.approx(0.2, rel=0.05)
    assert got["viscous_drag"]["c_nm_s_per_rad"] == pytest.approx(0.01, rel=0.05)
    assert "No model of this screw" in (tmp_path / "o" / "report.md").read_text()
    assert "--baseline zero" in (tmp_path / "o" / "augmented.yaml").read_text()


def test_replay_evaluates_inertia_with_the_causal_filter(base, tmp_path):
    """Live = replay: the runner's empirical part is J times AccelerationFilter's alpha."""
    cfg = tmp_path / "aug.yaml"
    base_section, _ = read_model_file(bundled_config("ball_screw.yaml"))
    inertia = make_term("inertia", {"j_kg_m2": 3e-4, "accel_cutoff_hz": 10.0, "max_gap_s": 0.1})
    write_model_file(cfg, base_section, TermSet([inertia]))
    r = base.recording
    bag = tmp_path / "bag"
    write_events(bag, with_measurement(base.events, r.torque_pred_nm), storage="sqlite3")
    replay(bag, tmp_path / "rep", config=cfg, progress=False)
    rows = np.genfromtxt(tmp_path / "rep" / "prediction.csv", delimiter=",", names=True)
    f = AccelerationFilter(10.0, 0.1)
    alpha = np.array([f.update(t, w) for t, w in zip(rows["t_s"], rows["nut_velocity_rad_s"])])
    assert np.abs(alpha).max() > 50.0
    assert np.allclose(rows["torque_empirical_nm"], 3e-4 * alpha, rtol=0, atol=1e-12)


def _lowpass(noise, rc):
    """First-order low-pass over samples: noise that is smooth at the sample rate."""
    out = np.empty_like(noise)
    acc = 0.0
    a = math.exp(-1.0 / rc)
    for i, e in enumerate(noise):
        acc = a * acc + (1 - a) * e
        out[i] = acc
    return out * math.sqrt((1 + a) / (1 - a))      # the same marginal std as ``noise``


def test_noise_of_smooth_data_holds_and_not_every_regime_is_significant(base):
    """
    A lag-1 MAD read 10x too little noise on a smooth real recording, and every
    regime was 'significant'.  Low-passed noise (correlation time ~8 samples) on a known
    effect: the estimate is within 25 % of the true std, the lag-1 one is not, and after the
    fit at most a few regimes stay flagged.
    """
    rng = np.random.default_rng(8)
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.03})])
    rec, white = synthesize(base, hidden, 0.006, rng)
    smooth = _lowpass(white, 8.0)
    rec = dataclasses.replace(rec, torque_meas_nm=rec.torque_meas_nm - white + smooth)
    a = analyse(rec, SETTINGS)
    s = summary_of(a)
    assert s["noise_std_nm"] == pytest.approx(np.std(smooth), rel=0.25)
    assert s["noise"]["std_lag1_nm"] < 0.5 * np.std(smooth)
    assert s["noise"]["autocorrelation_time_samples"] > 5
    assert [e["name"] for e in s["effects"]] == ["seal_drag"]
    assert len(s["regions_remaining"]) <= 2, s["regions_remaining"]


def test_stroke_position_is_named_on_a_travelling_trajectory():
    """Back and forth over 12 rev: a drag rising along the stroke is told from time."""
    rng = np.random.default_rng(4)
    t = np.arange(0, 60.0, 0.01)
    w = 8.0 * np.sin(2 * math.pi * t / 10.0) + 0.5 * np.sign(np.sin(2 * math.pi * t / 10.0))
    phi = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * 0.01)))
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.05}),
                      make_term("stroke_position", {"center_rad": float(phi.mean()),
                                                    "half_range_rad": 40.0, "p1_nm": 0.02})])
    meas = hidden.torque_nm(t, phi, w, 1000.0) + rng.normal(0, 0.003, t.size)
    rec = Recording(t, run_times(t), phi, w, np.full(t.size, 1000.0), meas, np.zeros(t.size),
                    np.ones(t.size, bool), {"input": "synthetic", "baseline": "zero"})
    a = analyse(rec, SETTINGS)
    assert set(a.terms.names) == {"seal_drag", "stroke_position"}, a.untested
    assert summary_of(a)["rmse_after_nm"] < 1.3 * 0.003
    assert any(r["variable"] == "stroke" for r in summary_of(a)["regions"])
