"""screw-pair / screw-sim on bad or hard input."""

import json

import numpy as np
import pytest

from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.cli import main


def _strict_json(text):
    """Parse JSON as a strict reader does: NaN and Infinity are not JSON."""
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def _pair(capsys, *argv):
    rc = main(["screw-pair", *argv, "--json"])
    return rc, _strict_json(capsys.readouterr().out)


def test_screw_pair_high_load_deterministic(capsys):
    """4 runs at 1000 N used to give 4 different answers (a one-ball state read as two)."""
    outs = []
    for _ in range(4):
        rc, out = _pair(capsys, "--axial-load-n", "1000")
        out.pop("solve_time_s")
        outs.append((rc, out))
    assert all(o == outs[0] for o in outs)
    rc, out = outs[0]
    if not out["converged"]:
        assert rc == 1
        assert all(out[k] is None for k in ("f_b2b_n", "friction_increase", "torque_nm",
                                            "torque_no_b2b_nm", "loss_w"))


def test_screw_pair_nonconverged_is_null(capsys, tmp_path):
    """A solve that stops unconverged prints null numbers and exits 1."""
    cfg = tmp_path / "short.yaml"
    cfg.write_text("ball_screw:\n  solver:\n    max_iterations: 1\n")
    rc, out = _pair(capsys, "--config", str(cfg))
    assert rc == 1
    assert out["converged"] is False
    assert [out[k] for k in ("f_b2b_n", "friction_increase", "torque_nm",
                             "torque_no_b2b_nm", "loss_w")] == [None] * 5


def test_cold_solve_failure_keeps_ball_count():
    """A failed load continuation used to return one ball's state for n balls."""
    model = ScrewModel(load_ball_screw(None, {"solver": {"max_iterations": 1}}))
    free = model.cold_solve(np.array([0.0, 0.03]), 0.0, 0.0, 1.0, 1000.0)
    assert not free.converged
    assert free.x.shape == (2, 6)


def test_kernel_refuses_mismatched_arrays():
    """The unchecked kernel must not be handed arrays of other sizes."""
    model = ScrewModel(load_ball_screw(None))
    solver = model.solver
    if not solver.use_kernel:
        pytest.skip("numba kernel not available")
    x = model.ball.rolling_guess(1, 1.0)
    centres = model.ball.arc_centres(np.zeros(2), 0.0, 0.0)
    with pytest.raises(ValueError, match="1 ball states, 2 centres"):
        solver.solve(x, 0.0, centres, 1.0, 100.0, 50.0, np.array([0]), np.array([1]),
                     np.array([True]))


@pytest.mark.parametrize("load", ["0", "-0", "1e-7"])
def test_screw_pair_zero_load_is_zero_friction(capsys, load):
    """Below solver.min_axial_load_n (no preload) friction is zero, valid JSON."""
    rc, out = _pair(capsys, "--axial-load-n", load)
    assert rc == 0
    assert out["converged"] is True
    assert out["f_b2b_n"] == out["torque_nm"] == out["loss_w"] == 0.0
    assert out["friction_increase"] == 0.0


def test_screw_sim_steps_keeps_the_step_size(tmp_path, capsys):
    """--steps N runs N steps of the configured size, as --help says."""
    import csv
    cfg = load_ball_screw(None)
    dt = cfg.operation.duration_s / cfg.operation.n_steps
    assert main(["screw-sim", "--out", str(tmp_path), "--steps", "2"]) == 0
    with open(tmp_path / "timeseries.csv") as fh:
        t = [float(r["t_s"]) for r in csv.DictReader(fh)]
    assert t == pytest.approx([dt, 2 * dt], rel=1e-9)
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["screw-sim", "--help"])
    assert "configured step size" in capsys.readouterr().out


@pytest.mark.parametrize("spelling, value", [("module_theta1_rad", "0.01"),
                                             ("module_theta1_deg", "0.5")])
def test_screw_pair_flag_overrides_either_spelling(tmp_path, capsys, spelling, value):
    """--theta1-deg with a file that sets theta1 in SI used to be 'given twice'."""
    cfg = tmp_path / "pair.yaml"
    cfg.write_text(f"ball_screw:\n  operation:\n    {spelling}: {value}\n"
                   "    module_theta2_deg: 2\n")
    rc, flagged = _pair(capsys, "--config", str(cfg), "--theta1-deg", "1")
    assert rc == 0
    rc, plain = _pair(capsys, "--theta1-deg", "1", "--theta2-deg", "2")
    flagged.pop("solve_time_s"), plain.pop("solve_time_s")
    assert flagged == plain


def test_screw_pair_bad_flag_named(capsys):
    """An out-of-range flag value is refused by the flag's name, exit 2."""
    assert main(["screw-pair", "--theta1-deg", "20"]) == 2
    assert "--theta1-deg 20" in capsys.readouterr().err
