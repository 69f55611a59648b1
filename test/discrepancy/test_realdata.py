"""
The workflow on measured screw-drive recordings (RViMLab, MIT licence): real data first.

Data: A. Mablekos-Alexiou, L. da Cruz, C. Bergeles, "Friction-Inclusive Modeling of Sliding
Contact Transmission Systems in Robotics", IEEE T-RO 37(4), 1252-1267, 2021, recorded with a
Maxon EPOS.  Read from ``$BB_FRICTION_REALDATA`` or ``../shared/realdata`` (next to the repo or
its main checkout); the tests skip, saying so, when the recordings are absent.  The importer
itself is also tested on a 46-row excerpt kept in ``test/discrepancy/data``.

Per drive: fit on half of the steady-state runs and one start-stop run, validate on the
others with ``--validate`` (no refit).  Checked against the data themselves:
- the augmented model's validation relative error is no worse than the rigid-body
  least-squares reference (J alpha + c omega + T_c sign omega + T_0) that the same run fits
  on the same samples with the same alpha (recomputed here);
- the drag named (seal_drag, the mean of both directions) is the mean of the measured
  steady-state torque magnitudes within 15 %;
- the lifting/lowering difference is named (a direction asymmetry or an offset);
- the noise estimate is within a factor 1.5 of the measured steady-state torque scatter
  (the lag-1 estimate is 4x too small there);
- after the fit, fewer than a quarter of the regimes stay significant.
"""

import csv
import importlib.util
import json
from pathlib import Path
import statistics

import numpy as np
import pytest

from bb_friction_ros.cli import main as cli_main
from bb_friction_ros.discrepancy.data import load_recording
from bb_friction_ros.discrepancy.bandwidth import with_acceleration
from bb_friction_ros.discrepancy.reference import rigid_body_fit, rigid_body_relative_error
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.workflow import (SAME_FIT_RTOL, usable,
                                                  worse_than_reference)

TOOLS = Path(__file__).resolve().parents[2] / "tools" / "import_epos.py"
EXCERPT = Path(__file__).resolve().parent / "data" / "epos_driveNo3_steady_1rpm_excerpt.csv"


def _importer():
    spec = importlib.util.spec_from_file_location("import_epos", TOOLS)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _with_alpha(rec, summary):
    """The recording's usable samples with alpha at the run's chosen cut-off."""
    rec, _ = with_acceleration(rec, DiscrepancySettings(),
                               {"accel_cutoff_hz": summary["acceleration"]["cutoff_hz"]})
    return rec.take(usable(rec)[0])


def _rigid_body_on_all(fit, summary):
    """The reference as an engineer would fit it: least squares on every usable sample."""
    return rigid_body_fit(_with_alpha(fit, summary))


epos = _importer()
REALDATA, WHY_MISSING = epos.find_realdata()
needs_realdata = pytest.mark.skipif(REALDATA is None, reason=WHY_MISSING or "")


def test_epos_importer_on_the_excerpt(tmp_path, capsys):
    t, rpm, pct, skipped = epos.read_epos(EXCERPT)
    assert skipped and "was -8.9" in skipped[0][1]          # the hand-edited row is skipped
    assert t[0] == pytest.approx(0.256) and np.allclose(np.diff(t), 0.256)
    out = tmp_path / "x.csv"
    assert epos.main([str(EXCERPT), "--out", str(out), "--axial-load-n", "0.5"]) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == t.size and float(rows[0]["t_s"]) == 0.0
    # the authors' convention: velocity = -rpm pi/30, torque = -% 9.84e-3/100
    assert float(rows[1]["torque_meas_nm"]) == pytest.approx(-pct[1] * 9.84e-5)
    assert float(rows[1]["nut_velocity_rad_s"]) == pytest.approx(-rpm[1] * np.pi / 30)
    assert float(rows[0]["axial_load_n"]) == 0.5 and float(rows[0]["torque_pred_nm"]) == 0.0
    bad = tmp_path / "bad.csv"
    bad.write_text("a;b\n1;2\n")
    assert epos.main([str(bad), "--out", str(tmp_path / "y.csv")]) == 2
    assert "not an EPOS data-recorder export" in capsys.readouterr().err


@pytest.fixture(scope="module")
def drives(tmp_path_factory):
    """Import every drive once and run the workflow with --validate; return the results."""
    if REALDATA is None:
        pytest.skip(WHY_MISSING)
    root = REALDATA / "rvim_screw_drives" / "raw" / "experiments"
    out = {}
    for drive in ("driveNo1", "driveNo2", "driveNo3"):
        d = tmp_path_factory.mktemp(drive)
        fit, val = epos.import_rvim(root / drive, d, log=open("/dev/null", "w"))
        status = cli_main(["discrepancy", str(fit), "--validate", str(val), "--out",
                           str(d / "out"), "--no-plots", "--no-progress"])
        summary = json.loads((d / "out" / "summary.json").read_text())
        out[drive] = {"status": status, "summary": summary, "fit": fit, "val": val, "dir": d}
    return out


def _steady(drive):
    rows = list(csv.DictReader((REALDATA / "rvim_screw_drives" /
                                "steady_state_summary.csv").open()))
    return [r for r in rows if r["drive"] == drive]


@needs_realdata
@pytest.mark.parametrize("drive", ["driveNo1", "driveNo2", "driveNo3"])
def test_measured_drive_named_and_validated(drives, drive):
    res = drives[drive]
    s = res["summary"]
    assert res["status"] == 0 and s["verdict"] == "found"
    assert s["identified_from_data_only"]
    names = [e["name"] for e in s["effects"]]
    assert "seal_drag" in names
    v = s["validation"]
    assert set(v) >= {"n", "rmse_before_nm", "rmse_after_nm", "relative_error_before",
                      "relative_error_after"}
    assert v["relative_error_before"] == pytest.approx(1.0)     # no model: pred = 0
    assert v["relative_error_after"] < 0.25
    rows = list(csv.DictReader((res["dir"] / "out" / "validation" / "prediction.csv").open()))
    assert list(rows[0]) == ["t_s", "torque_meas_nm", "torque_pred_nm", "torque_augmented_nm"]
    assert len(rows) == v["n"]
    # no worse than the rigid-body least-squares reference, fitted in the same run on the
    # same samples with the same alpha; and the reference is recomputed here
    ref = v["reference_relative_error"]
    # no slack: driveNo2 (the reference's own terms chosen) equals it up to rounding
    assert v["relative_error_after"] <= ref * (1 + SAME_FIT_RTOL), (v["relative_error_after"], ref)
    worse = worse_than_reference(v["relative_error_after"], ref)
    assert worse == any("WORSE than the rigid-body reference" in w for w in s["warnings"])
    fit = load_recording(res["fit"])
    own = rigid_body_relative_error(_rigid_body_on_all(fit, s), _with_alpha(
        load_recording(res["val"]), s))
    assert own == pytest.approx(ref, rel=1e-9)
    assert "heldout" in s and s["heldout"]["reference_relative_error"] > 0
    # the drag is the mean of the two directions' measured steady torque
    steady = _steady(drive)
    mean_drag = statistics.mean(abs(float(r["mean_tau_2ndhalf_Nm"])) for r in steady)
    seal = next(e for e in s["effects"] if e["name"] == "seal_drag")["params"]["torque_nm"]
    speed = statistics.mean(abs(float(r["mean_w_2ndhalf_rad_s"])) for r in steady)
    visc = next((e["params"]["c_nm_s_per_rad"] for e in s["effects"]
                 if e["name"] == "viscous_drag"), 0.0)
    assert seal + visc * speed == pytest.approx(mean_drag, rel=0.15)
    # the noise: measured scatter of the torque in steady runs, not the lag-1 estimate
    scatter = statistics.median(float(r["std_tau_2ndhalf_Nm"]) for r in steady)
    assert scatter / 1.5 < s["noise_std_nm"] < scatter * 1.5, (s["noise"], scatter)
    # after the fit, most regimes agree with the noise
    assert len(s["regions_remaining"]) < 0.25 * len(s["regions"]) + 3


@needs_realdata
def test_lifting_and_lowering_differ_and_the_choice_is_explained(drives):
    """driveNo1: +2.5..3.2 vs -3.2..3.9 mN m; at standstill the motor holds 0 N m."""
    s = drives["driveNo1"]["summary"]
    names = [e["name"] for e in s["effects"]]
    assert "coulomb_asymmetry" in names or "offset" in names
    amb = s["ambiguities"]
    assert amb and amb[0]["pair"] == ["offset", "coulomb_asymmetry"]
    assert amb[0]["standstill_samples"] > 0 and amb[0]["statement"]
    e = next(e for e in s["effects"] if e["name"] in ("coulomb_asymmetry", "offset"))
    value = e["params"].get("delta_torque_nm", e["params"].get("torque_nm"))
    # (positive-direction drag) - (negative-direction drag): about -0.7 mN m
    steady = _steady("driveNo1")
    pos = statistics.mean(float(r["mean_tau_2ndhalf_Nm"]) for r in steady
                          if float(r["mean_w_2ndhalf_rad_s"]) > 0)
    neg = statistics.mean(-float(r["mean_tau_2ndhalf_Nm"]) for r in steady
                          if float(r["mean_w_2ndhalf_rad_s"]) < 0)
    expected = (pos - neg) if e["name"] == "coulomb_asymmetry" else (pos - neg) / 2
    assert value == pytest.approx(expected, rel=0.3, abs=1e-4)


@needs_realdata
def test_driveno2_gets_the_rigid_body_floor_and_equals_the_reference(drives):
    """
    driveNo2: its viscous drag brings a BIC gain of ~2.6, below the threshold of 10 a
    discovery needs; without a model of the drive the rigid-body terms need only plain BIC
    (rigid_body_bic_threshold), so it is kept and the model written is the reference's own
    (before: 0.1671 against 0.1652 on validation, held-out 0.138 against 0.136).
    """
    s = drives["driveNo2"]["summary"]
    names = {e["name"] for e in s["effects"]}
    assert {"viscous_drag", "seal_drag", "inertia"} <= names
    h = s["heldout"]
    assert h["relative_error_after"] <= h["reference_relative_error"] * (1 + SAME_FIT_RTOL)
    assert not s["warnings"]


@needs_realdata
def test_driveno3_cutoff_is_the_highest_the_fit_recording_cannot_tell_apart(drives):
    """
    driveNo3's fit recording holds only a slow start-stop run: the lowest CV error is at
    1.6 Hz, but every candidate up to the highest is within one standard error of it; the
    highest is used, and the faster validation run is predicted better than by the
    reference (at 1.6 Hz: 0.2045 against 0.226; the old fixed 10 Hz: 0.140 against 0.168).
    """
    acc = drives["driveNo3"]["summary"]["acceleration"]
    best = min(acc["candidates"], key=lambda c: c["cv_mse_nm2"])
    within = [c for c in acc["candidates"]
              if c["cv_mse_nm2"] <= best["cv_mse_nm2"] + acc["one_se_nm2"]]
    assert acc["cutoff_hz"] == max(c["cutoff_hz"] for c in within)
    assert acc["lowest_score_cutoff_hz"] == best["cutoff_hz"] < acc["cutoff_hz"]
    assert "within one standard error" in acc["statement"]
    v = drives["driveNo3"]["summary"]["validation"]
    assert v["relative_error_after"] < 0.9 * v["reference_relative_error"]
