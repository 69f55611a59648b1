"""The bb-friction CLI: JSON contract keys, readable table, bad input, reproduce report."""

import json

import pytest

from bb_friction_ros import paper
from bb_friction_ros.cli import main
from invariants import paper_approx

LINEAR_KEYS = {"eps", "f_b2b_n", "p_f_w", "p_b2b_w", "converged", "solve_time_s"}


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("model", ["numerical", "analytical"])
def test_linear_json_contract(capsys, model):
    """--json prints exactly one JSON object with the documented keys."""
    code, out, _ = run(capsys, "linear", "--theta-deg", "2", "--rho", "-0.6", "--ny-n", "100",
                       "--mu", "0.1", "--v-mm-s", "10", "--model", model, "--json")
    assert code == 0
    obj = json.loads(out)
    assert LINEAR_KEYS <= set(obj)
    assert len(obj["eps"]) == 2 and obj["converged"] is True
    assert obj["f_b2b_n"] == paper_approx(paper.F_B2B_NUM if model == "numerical"
                                          else paper.F_B2B_AN)


def test_linear_table_and_case_b(capsys):
    """Readable output; the matched case (b) prints no contact force."""
    code, out, _ = run(capsys, "linear", "--dbeta-tr-deg", "-2", "--dbeta-tl-deg", "2")
    assert code == 0 and "F_B2B" in out and "0.0000 N" in out


@pytest.mark.parametrize("argv,key", [(["--rho", "1.2"], "side_force_ratio"),
                                      (["--mu", "-0.1"], "friction_coefficient"),
                                      (["--theta-deg", "nan"], "--theta-deg")])
def test_linear_bad_input_names_the_field(capsys, argv, key):
    """Bad input is refused with exit code 2 and the offending field named."""
    code, _, err = run(capsys, "linear", *argv)
    assert code == 2 and key in err


def test_reproduce_writes_report(tmp_path, capsys):
    """reproduce writes report.md, reproduction.json (paper, ours, deviation) and the PNGs."""
    code, _, _ = run(capsys, "reproduce", "--out", str(tmp_path), "--grid", "5")
    assert code == 0
    data = json.loads((tmp_path / "reproduction.json").read_text())
    rows = data["Linear ball bearing (Sec. 2)"]
    assert {"paper", "ours", "deviation"} <= set(rows[0])
    by_key = {r["quantity"]: r for r in rows}
    assert by_key["f_an"]["paper"] == paper.F_B2B_AN.value
    assert by_key["f_an"]["ours"] == paper_approx(paper.F_B2B_AN)
    # each row shows the tolerance of paper.py and whether it is met
    assert by_key["f_an"]["tolerance"] == "+-1 %" and by_key["f_an"]["within_tolerance"]
    assert by_key["t_num"]["tolerance"] == "" and by_key["t_num"]["within_tolerance"] is None
    screw = {r["quantity"]: r for r in data["Ball screw (Sec. 3)"]}
    gap = screw["Table 5 (a) F_B2B, theta2 = 2 deg"]      # a number not reached is shown so
    assert gap["source"] == paper.SCREW_F_B2B_A.source and gap["target"] is False
    assert gap["within_tolerance"] == paper.SCREW_F_B2B_A.within(gap["ours"])
    for name in ("fig05_friction_maps", "fig08_velocity_difference",
                 "fig09_b2b_force_and_loss", "fig10_relative_displacement"):
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000
    report = (tmp_path / "report.md").read_text()
    assert "| f_num |" in report and "| (+-10 %) |" in report
    # Ball screw: both load distributions, and the whole theta-amplitude sweep
    # with the calibrated amplitude and its figure.
    screw = {r["quantity"] for r in data["Ball screw (Sec. 3)"]}
    for dist in ("rigid", "elastic"):
        assert f"Fig. 21 peak B2B torque / ball-groove torque ({dist})" in screw
    theta = data["Ball screw: the unstated theta amplitude of Fig. 19 (sweep)"]
    cal = {r["quantity"]: r for r in theta}
    assert cal["theta amplitude at peak share 49.6 % (elastic)"]["ours"] == \
        pytest.approx(3.44, abs=0.05)
    assert sum(r["quantity"].startswith("sweep ") for r in theta) == 26
    assert (tmp_path / "fig21_theta_sweep.png").stat().st_size > 10_000
    assert (tmp_path / "elastic" / "fig21_torque_split.png").exists()
    assert {"Load range: largest contact load", "Load range: largest axial load"} <= screw


def test_every_documented_command_is_registered(capsys):
    """The documented commands (users script them) are all reachable from main."""
    from bb_friction_ros.cli import build_parser
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert {"linear", "reproduce", "screw-pair", "screw-sim", "replay", "node", "demo",
            "make-demo-bag", "discrepancy", "sweep", "screw-verdict",
            "linear-mitigate"} <= set(sub.choices)
