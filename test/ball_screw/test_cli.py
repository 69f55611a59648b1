"""CLI contracts of screw-pair and screw-sim."""

import argparse
import csv
import json

import pytest

from bb_friction_ros.ball_screw.cli import add_screw_pair_parser, add_screw_sim_parser


def _run(argv):
    parser = argparse.ArgumentParser(prog="bb-friction")
    sub = parser.add_subparsers(dest="command")
    add_screw_pair_parser(sub)
    add_screw_sim_parser(sub)
    args = parser.parse_args(argv)
    return args.func(args)


def test_screw_pair_json(capsys):
    rc = _run(["screw-pair", "--theta1-deg", "0", "--theta2-deg", "2", "--axial-load-n",
               "50", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert set(out) == {"f_b2b_n", "friction_increase", "torque_nm", "torque_no_b2b_nm",
                        "loss_w", "converged", "solve_time_s"}
    assert out["converged"] is True
    assert out["torque_nm"] > out["torque_no_b2b_nm"] > 0.0


def test_bad_config_refused(capsys, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("ball_screw:\n  geometry:\n    lead_mm: -3\n")
    rc = _run(["screw-pair", "--config", str(bad), "--json"])
    assert rc == 2
    assert "ball_screw.geometry.lead_mm" in capsys.readouterr().err


def test_screw_sim_outputs(tmp_path, capsys):
    rc = _run(["screw-sim", "--out", str(tmp_path), "--steps", "4"])
    assert rc == 0
    with open(tmp_path / "timeseries.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4
    for col in ("t_s", "nut_angle_rad", "torque_total_nm", "torque_b2g_nm", "torque_b2b_nm",
                "n_groups", "drive_power_w", "loss_w"):
        assert col in rows[0]
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in ("peak_b2b_share", "peak_b2b_nut_angle_deg", "max_groups",
                "step_time_median_s", "max_power_balance_error"):
        assert key in summary
    assert (tmp_path / "fig20_ball_distance.png").stat().st_size > 0
    assert (tmp_path / "fig21_torque_split.png").stat().st_size > 0


@pytest.mark.parametrize("argv", [["screw-sim"]])
def test_screw_sim_requires_out(argv):
    with pytest.raises(SystemExit):
        _run(argv)
