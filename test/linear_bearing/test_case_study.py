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
