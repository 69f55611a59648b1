"""The analytical model outside its range says so."""

import json
import math

import numpy as np
import pytest

from bb_friction_ros.cli import main
from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.linear_bearing.case_study import LinearPairCase


def _strict_json(text):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_linear_analytical_overflow_is_not_a_result(capsys):
    """N_y = 1e308 N overflowed to Infinity/NaN with converged/valid true and exit 0."""
    rc = main(["linear", "--model", "analytical", "--ny-n", "1e308", "--json"])
    out = _strict_json(capsys.readouterr().out)
    assert rc == 3
    assert out["converged"] is False and out["valid"] is False
    assert out["f_b2b_n"] is None and out["p_f_w"] is None
    assert any("not finite" in n for n in out["notes"])


@pytest.mark.parametrize("theta_deg", [89.99, 30.0])
def test_linear_analytical_two_point_contact_agrees_with_numerical(capsys, theta_deg):
    """At theta = 89.99 deg the analytical model said valid where the numerical one did not."""
    cfg = load_linear_bearing()
    case = LinearPairCase(cfg)
    theta = math.radians(theta_deg)
    num = case.numerical(theta, cfg.side_force_ratio)
    assert any("two-point" in n for n in num.notes)
    ana = case.analytical(theta, cfg.side_force_ratio)
    assert ana.valid is False
    assert any("two-point" in n for n in ana.notes)
    main(["linear", "--model", "analytical", "--theta-deg", str(theta_deg), "--json"])
    assert _strict_json(capsys.readouterr().out)["valid"] is False


def test_analytical_validity_grid_equals_scalar_calls():
    """The vectorised four-point check gives the scalar calls' verdicts, inside and out."""
    case = LinearPairCase(load_linear_bearing())
    th = np.radians(np.array([0.0, 2.0, 20.0, 40.0, 60.0]))
    rho = np.array([-0.9, -0.6, 0.0, 0.6])
    grid = case.analytical(th[None, :], rho[:, None])
    scalar = [[case.analytical(t, r).valid for t in th] for r in rho]
    assert grid["valid"].tolist() == scalar
    assert grid["valid"][1, 1]           # Table 1 case (a): four-point, valid
    assert not grid["valid"].all()


def test_table1_case_stays_valid():
    """The paper's case (a) (theta = 2 deg, rho = -0.6) is inside the analytical model."""
    cfg = load_linear_bearing()
    res = LinearPairCase(cfg).analytical(math.radians(2.0), -0.6)
    assert res.valid and res.converged and res.notes == ()
