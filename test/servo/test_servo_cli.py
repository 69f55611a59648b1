"""
``bb-friction servo-test``: the output contract (summary.json, modes/<mode>.csv with
``none`` always, report.md, plots) and the bad inputs (exit 2, the field or file named).
"""

import csv
import json

import numpy as np
import pytest

from bb_friction_ros.cli import main
from bb_friction_ros.config import bundled_config

CONTRACT_COLUMNS = ["t_s", "nut_angle_ref_rad", "nut_angle_rad", "torque_command_nm",
                    "torque_friction_nm"]


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_outputs_follow_the_contract_and_none_always_runs(tmp_path, capsys, loop_file,
                                                          short_spec, axis_model):
    out = tmp_path / "out"
    code, stdout, _ = run(capsys, "servo-test", short_spec, "--loop", loop_file, "--config",
                          axis_model, "--out", out, "--modes", "model", "coulomb_viscous",
                          "--no-progress")
    assert code == 0
    assert sorted(p.name for p in (out / "modes").iterdir()) == \
        ["coulomb_viscous.csv", "model.csv", "none.csv"]
    with open(out / "modes" / "none.csv") as fh:
        header = next(csv.reader(fh))
    assert header[:5] == CONTRACT_COLUMNS
    s = json.loads((out / "summary.json").read_text())
    for name in ("none", "model", "coulomb_viscous"):
        m = s["modes"][name]
        for key in ("following_error_rms_um", "following_error_max_um", "reversal_glitch_um",
                    "cruise_rms_um"):
            assert key in m
        assert len(m["reversal_glitch_um"]) == 1    # one reversal of the reference
        assert m["counters"]["feedforward_wrong_sign"] == 0
    # friction feedforward must shrink the error of a loop without it
    assert s["modes"]["model"]["following_error_rms_um"] \
        < s["modes"]["none"]["following_error_rms_um"]
    report = (out / "report.md").read_text()
    assert "**Verdict:**" in report and s["verdict"] in stdout
    assert (out / "following_error.png").stat().st_size > 10_000
    assert (out / "reversals.png").exists()


def test_measured_loop_is_compared_with_the_rigid_body_reference(tmp_path, capsys,
                                                                 loop_file, short_spec,
                                                                 axis_model):
    import dataclasses
    from bb_friction_ros.servo.reference import load_reference
    from bb_friction_ros.servo.settings import load_settings
    from bb_friction_ros.servo.synthetic import closed_loop_recording
    s = load_settings(loop_file)
    ref = load_reference(short_spec, 1000.0, [0.02])
    rec, cal = tmp_path / "rec.csv", tmp_path / "cal.csv"
    closed_loop_recording(rec, ref, s, axis_model, pulse_nm=0.05, torque_noise_nm=0.002)
    two = dataclasses.replace(ref, axes=[dataclasses.replace(ref.axes[0],
                                                             ref_rad=ref.axes[0].ref_rad * 2)])
    closed_loop_recording(cal, two, s, axis_model, torque_noise_nm=0.002, seed=1)
    code, stdout, _ = run(capsys, "servo-test", rec, "--loop", loop_file, "--config",
                          axis_model, "--out", tmp_path / "out", "--modes", "none",
                          "--calibration", cal, "--measured-loop", "--no-progress",
                          "--no-plots")
    assert code == 0
    ml = json.loads((tmp_path / "out" / "summary.json").read_text())["measured_loop"]
    assert set(ml["none"]) == {"angle", "velocity", "torque", "torque_by_phase"}
    # the phases split the torque's error: moving^2 + standing^2 = torque^2
    phase = ml["none"]["torque_by_phase"]
    assert phase["moving"] ** 2 + phase["standing"] ** 2 == \
        pytest.approx(ml["none"]["torque"] ** 2, rel=1e-9)
    assert ml["rigid_body"] is not None and "least squares" in ml["rigid_body_source"]
    # the plant is the model file: only the torque sensor's noise separates the two
    assert ml["none"]["torque"] < 0.05
    assert ml["none_torque_error_at_most_rigid_body"] is True
    assert "measured loop" in stdout


def _write(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize("case, needle", [
    ("missing_reference", "nut_angle_ref_rad"),
    ("no_inertia", "plant.inertia_kg_m2"),
    ("gain_out_of_range", "loop.velocity_feedforward"),
    ("missing_gain", "loop.velocity_gain_nm_s_per_rad: missing"),
    ("measured_channels", "nut_angle_rad, torque_meas_nm"),
    ("unknown_mode", "unknown mode 'fancy'"),
    ("bad_spec_kind", "reference.kind"),
    ("wrong_rate", "not the loop period"),
])
def test_bad_input_exits_2_naming_the_field(tmp_path, capsys, loop_file, short_spec,
                                            axis_model, case, needle):
    rec = _write(tmp_path / "rec.csv", "t_s,nut_angle_ref_rad\n" + "".join(
        f"{k * 1e-3},{k * 1e-4}\n" for k in range(20)))
    loop, config, extra = loop_file, axis_model, []
    text = loop_file.read_text()
    if case == "missing_reference":
        rec = _write(tmp_path / "bad.csv", "t_s,nut_angle_rad\n0,0\n0.001,0\n0.002,0\n")
    elif case == "no_inertia":
        loop = _write(tmp_path / "l.yaml", text.replace("  inertia_kg_m2: 2.0e-4\n", ""))
        config = bundled_config("ball_screw.yaml")
    elif case == "gain_out_of_range":
        loop = _write(tmp_path / "l.yaml", text.replace("velocity_feedforward: 1.0",
                                                        "velocity_feedforward: 1.5"))
    elif case == "missing_gain":
        loop = _write(tmp_path / "l.yaml", text.replace(
            "  velocity_gain_nm_s_per_rad: 0.125\n", ""))
    elif case == "measured_channels":
        extra = ["--measured-loop"]
    elif case == "unknown_mode":
        extra = ["--modes", "fancy"]
    elif case == "bad_spec_kind":
        rec = _write(tmp_path / "s.yaml", short_spec.read_text().replace("reversal", "zigzag"))
    elif case == "wrong_rate":
        rec = _write(tmp_path / "r.csv", "t_s,nut_angle_ref_rad\n" + "".join(
            f"{k * 2e-3},0\n" for k in range(20)))
    out = tmp_path / "out"
    code, _, err = run(capsys, "servo-test", rec, "--loop", loop, "--config", config,
                       "--out", out, "--no-progress", *extra)
    assert code == 2, err
    assert needle in err
    assert not out.exists()                 # nothing written before the inputs are checked


def test_node_mode_runs_the_real_node_in_real_time_and_measures_its_coverage(
        tmp_path, capsys, loop_file, axis_model):
    spec = _write(tmp_path / "s.yaml", "reference:\n  kind: reversal\n  speeds_rev_s: [1.0]\n"
                  "  stroke_rev: 0.25\n  accel_rev_s2: 20.0\n")
    out = tmp_path / "out"
    code, _, err = run(capsys, "servo-test", spec, "--loop", loop_file, "--config",
                       axis_model, "--out", out, "--modes", "node", "--no-progress",
                       "--no-plots")
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    node = s["modes"]["node"]["node"]
    n = len(list(csv.reader(open(out / "modes" / "node.csv")))) - 1
    assert node["cycles"] == n and sum(node["statuses"].values()) == n
    assert 0.0 <= node["coverage"] <= 1.0 and node["profiles"] > 0
    assert node["diagnostics"]["received_nut_state"] > 0
    assert s["modes"]["node"]["counters"]["feedforward_wrong_sign"] == 0


def test_node_planned_mode_sends_the_reference_as_a_joint_trajectory_and_equals_planned(
        tmp_path, capsys, loop_file, axis_model):
    """
    The reference through the real node as a JointTrajectory: one answer with every point,
    the feedforward played back equal to the offline ``planned`` mode's to rounding.
    """
    spec = _write(tmp_path / "s.yaml", "reference:\n  kind: reversal\n  speeds_rev_s: [1.0]\n"
                  "  stroke_rev: 0.25\n  accel_rev_s2: 20.0\n")
    out = tmp_path / "out"
    code, _, err = run(capsys, "servo-test", spec, "--loop", loop_file, "--config",
                       axis_model, "--out", out, "--modes", "planned", "node_planned",
                       "--no-progress", "--no-plots")
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    node = s["modes"]["node_planned"]["node"]
    assert node["diagnostics"]["planned_published"] == 1

    def column(name):
        with open(out / "modes" / f"{name}.csv") as f:
            return np.array([float(r["torque_feedforward_nm"]) for r in csv.DictReader(f)])

    a, b = column("planned"), column("node_planned")
    assert a.size == b.size == node["points"]
    assert np.any(a != 0.0)
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)
    assert s["modes"]["node_planned"]["timing"] == "commanded"
    assert s["modes"]["node_planned"]["counters"]["feedforward_wrong_sign"] == 0
