"""Hertz contact: Table 1 and the classical limits."""

import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.contact.hertz import HertzContact, effective_modulus
from invariants import paper_approx

TABLE1 = {k: paper.TABLE1[k]
          for k in ("ball_radius_m", "conformity", "youngs_modulus_pa", "poisson_ratio")}


def test_table1_psi():
    """Table 1: Psi (tolerance and reason: ``paper.PSI``)."""
    hz = HertzContact.ball_in_straight_groove(**TABLE1)
    assert hz.psi(TABLE1["ball_radius_m"]) == paper_approx(paper.PSI)


def test_table1_b_over_a():
    """b/a for conf 0.56: Hamrock-Brewe's fit k = 1.0339 (R_y/R_x)^0.636 is good to ~3 %."""
    hz = HertzContact.ball_in_straight_groove(**TABLE1)
    r_b = TABLE1["ball_radius_m"]
    r_across = 1.0 / (1.0 / r_b - 1.0 / (2 * 0.56 * r_b))
    assert hz.ellipticity == pytest.approx(1.0 / (1.0339 * (r_across / r_b) ** 0.636), rel=0.03)
    assert hz.ellipticity == pytest.approx(0.2321, abs=1e-4)   # our exact value, regression


def test_ball_on_flat_limit():
    """Equal curvatures give a circle: a = (3 Q R / (4 E*))^(1/3), delta = a^2 / R."""
    r, q = 5e-3, 100.0
    e_star = effective_modulus(210e9, 0.28)
    hz = HertzContact.from_curvatures(1.0 / r, 1.0 / r, e_star)
    a, b = hz.semi_axes(q)
    assert hz.ellipticity == 1.0
    assert a == pytest.approx((3 * q * r / (4 * e_star)) ** (1 / 3), rel=1e-9)
    assert hz.approach(q) == pytest.approx(a * a / r, rel=1e-6)


def test_load_balance_and_stiffness():
    """Integral of the Hertz pressure is the load; stiffness is d(load)/d(approach)."""
    hz = HertzContact.ball_in_straight_groove(**TABLE1)
    q = np.array([1.0, 50.0, 500.0])
    a, b = hz.semi_axes(q)
    assert np.allclose(2.0 / 3.0 * math.pi * a * b * hz.peak_pressure(q), q, rtol=1e-12)
    d = hz.approach(q)
    assert np.allclose(hz.load_from_approach(d), q, rtol=1e-12)
    h = 1e-9 * d
    fd = (hz.load_from_approach(d + h) - hz.load_from_approach(d - h)) / (2 * h)
    assert np.allclose(hz.stiffness(q), fd, rtol=1e-6)


def test_groove_wider_than_ball_refused():
    """A groove tighter than the ball has no Hertz solution: refused, not a silent number."""
    with pytest.raises(ValueError, match="curv"):
        HertzContact.ball_in_straight_groove(5e-3, 0.45, 210e9, 0.28)


def _scipy_ellipse(ratio):
    """k, E(e), K(e) computed directly with scipy (as hertz did before the table cache)."""
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipk

    def residual(k):
        m = 1.0 - k * k
        return (ellipe(m) / k ** 2 - ellipk(m)) / (ellipk(m) - ellipe(m)) - ratio

    k = brentq(residual, 1e-6, 1.0 - 1e-12, xtol=1e-15, rtol=1e-15)
    return k, float(ellipe(1.0 - k * k)), float(ellipk(1.0 - k * k))


@pytest.mark.parametrize("conformity", [0.52, 0.56, 0.6])
def test_cached_ellipse_constants_are_scipys_bit_for_bit(conformity, tmp_path, monkeypatch):
    """
    The Hertz constants come from the table cache (scipy stays off the node's start-up):
    built in an empty cache and read back from disk, they are scipy's values exactly.
    """
    from bb_friction_ros.contact import friction_maps as fm
    from bb_friction_ros.contact import hertz
    monkeypatch.setenv("BB_FRICTION_CACHE", str(tmp_path))
    r_b = TABLE1["ball_radius_m"]
    ratio = (1.0 / r_b) / (1.0 / r_b - 1.0 / (2 * conformity * r_b))
    want = _scipy_ellipse(ratio)
    for _ in range(2):              # built, then from disk
        monkeypatch.setattr(fm, "_IN_PROCESS", {})
        assert hertz._ellipse(ratio) == want
    assert len(list(tmp_path.glob("hertz-ellipse-*.npz"))) == 1
