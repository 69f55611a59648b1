"""Figs. 8-9 maps of the numerical model."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.linear_bearing.case_study import LinearPairCase
from invariants import check_linear_pair, paper_approx


def test_fig9_max_friction_increase():
    """Fig. 9(c): max (P_f + P_fB2B)/P_f (``paper.MAX_LOSS_RATIO``) at -+3 deg, rho = +-0.6."""
    case = LinearPairCase(load_linear_bearing())
    th = np.radians(np.linspace(*paper.FIGURES["fig8_9_theta_deg"], 7))
    rho = np.linspace(*paper.FIGURES["fig8_9_rho"], 7)
    g = case.numerical_grid(th, rho)
    assert g["converged"].all() and g["valid"].all()
    check_linear_pair(g)
    ratio = (g["p_f_w"] + g["p_b2b_w"]) / g["p_f_w"] * 100
    assert ratio.max() == paper_approx(paper.MAX_LOSS_RATIO)
    i, j = np.unravel_index(np.argmax(ratio), ratio.shape)
    assert abs(rho[i]) == pytest.approx(paper.FIGURES["fig8_9_rho"][1])
    assert abs(math.degrees(th[j])) == pytest.approx(paper.FIGURES["fig8_9_theta_deg"][1])
    assert np.sign(rho[i]) == -np.sign(th[j])
    # contact only where ball 1 is faster (Eq. 9), and the map is centrally symmetric
    assert np.all((g["f_b2b_n"] > 0) == (g["eps1"] > g["eps2"]))
    assert np.allclose(ratio, ratio[::-1, ::-1], rtol=1e-9)


def test_bottom_deviations_are_ordinary_inputs():
    """dbeta_BL/BR given directly equal the symmetric theta case; both at once are refused."""
    case = LinearPairCase(load_linear_bearing())
    th = math.radians(2.0)
    a = case.numerical(th, -0.6)
    b = case.numerical(0.0, -0.6, dbeta_bl_rad=-th, dbeta_br_rad=th)
    assert b.f_b2b_n == pytest.approx(a.f_b2b_n, rel=1e-12)
    assert b.eps == pytest.approx(a.eps, rel=1e-12)
    c = case.numerical(0.0, -0.6, dbeta_br_rad=th)          # an unset side is 0
    assert c.converged and c.eps != a.eps
    with pytest.raises(ValueError, match="theta_rad"):
        case.numerical(th, -0.6, dbeta_bl_rad=-th)
