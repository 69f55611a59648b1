"""
What the paper's ball-screw numbers can and cannot say: Table 5's
conventions, the theta sense, and the Fig. 21 features that no unstated choice moves.

The reference figures 2.08 / 3.12 N, 36 %/N and 1.29 are those of an independent
investigation of the same model (docs/assumptions_ball_screw.md); the paper's come from
``bb_friction_ros.paper``.
"""

import dataclasses
import math

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.ball_screw import reproduce as rp
from bb_friction_ros.ball_screw.simulation import run_whole_screw

# The independent investigation's figures, printed to 3 significant digits: half a unit of
# the last digit.
INVESTIGATION_BOTH_N = (2.08, 3.12)
PRINTED_3SD_N = 0.005
INVESTIGATION_PER_NEWTON_PCT = 36.0      # "about 36 %/N"
INVESTIGATION_FLIPPED_RATIO = 1.29       # printed to 2 decimals; ours 1.296
# Scaling W and E* together is an exact similarity of the model: the solver's tolerance
# (1e-10 on the scaled residual) bounds the difference; 1e-6 leaves room for the friction
# maps' interpolation.
SIMILARITY_REL = 1e-6
SENS = rp._SENSITIVITY


@pytest.fixture(scope="module")
def rows(model, config):
    return {r["quantity"]: r for r in rp.table5_rows(model, config)}


def test_both_conventions_together_scale_every_force_by_two(rows):
    """The labelled sensitivity row: 50 N on each ball with E/(1-nu^2), run, not written."""
    default = (rows["Table 5 (a) F_B2B, theta2 = 2 deg"],
               rows["Table 5 (b) F_B2B, theta2 = 3 deg"])
    increase = (rows["Sec. 3.3 friction increase (a)"], rows["Sec. 3.3 friction increase (b)"])
    for tag, ref, base, inc in zip("ab", INVESTIGATION_BOTH_N, default, increase):
        row = rows[SENS + f"Table 5 ({tag}) F_B2B if 50 N on EACH ball and E* = E/(1-nu^2)"]
        assert row["ours"] == pytest.approx(ref, abs=PRINTED_3SD_N)
        assert row["force_scale"] == pytest.approx(
            rp.PER_BALL_LOAD_FACTOR, rel=SIMILARITY_REL)
        assert row["ours"] == pytest.approx(2 * base["ours"], rel=SIMILARITY_REL)
        # the same increase as the default: W/E* is unchanged
        assert row["friction_increase_pct"] == pytest.approx(inc["ours"], abs=1e-4)
        assert row["paper"] == getattr(paper, f"SCREW_F_B2B_{tag.upper()}").value


def test_no_single_convention_reproduces_force_and_increase(rows):
    """Each convention alone moves the increase out of the paper's band (docs)."""
    for name in ("Table 5 (a) F_B2B if 50 N on EACH ball", "Table 5 (a) F_B2B if E* = E/(1-nu^2)"):
        row = rows[SENS + name]
        assert not paper.SCREW_F_B2B_A.within(row["ours"])
        assert not paper.SCREW_FRICTION_INCREASE_A.within(row["friction_increase_pct"])


def test_friction_increase_per_newton_is_fixed_by_the_spin(rows):
    """~36 %/N in both cases (different theta and force), against the paper's 20.4 / 20.8."""
    a = rows["Table 5 (a) friction increase per newton of F_B2B"]
    b = rows["Table 5 (b) friction increase per newton of F_B2B"]
    assert a["ours"] == pytest.approx(INVESTIGATION_PER_NEWTON_PCT, abs=0.5)
    # theta2 2 -> 3 deg changes F_B2B by 50 % but the increase per newton by < 1 %
    assert b["ours"] == pytest.approx(a["ours"], rel=0.01)
    assert a["paper"] == pytest.approx(20.4, abs=0.05)
    assert a["ours"] / a["paper"] > 1.7     # the gap no force scaling of the B2B alone closes


def test_theta_sense_is_confirmed_by_the_ratio(rows):
    """(b)/(a): 1.503 with the default sense (paper 1.505), 1.29 with the flipped one."""
    assert paper.SCREW_F_B2B_RATIO.holds(rows["Table 5 F_B2B ratio (b)/(a)"]["ours"])
    flipped = rows[SENS + "Table 5 F_B2B ratio (b)/(a), flipped theta sense"]["ours"]
    assert flipped == pytest.approx(INVESTIGATION_FLIPPED_RATIO, abs=0.01)
    assert not paper.SCREW_F_B2B_RATIO.within(flipped)


def _torques(cfg, n_steps):
    res, _ = run_whole_screw(cfg, n_steps=n_steps)
    assert all(r.converged for r in res)
    return (np.array([r.torque_b2b_nm for r in res]),
            np.array([r.torque_b2g_nm for r in res]))


N_STEPS = 100      # 360 deg: past the Fig. 21 peak; the claims hold step by step


def test_force_scaling_leaves_the_fig21_share_unchanged(config):
    """W and E* x2 double both torques: the B2B share of Fig. 21 does not move (docs)."""
    cfg = dataclasses.replace(config, load_distribution="rigid")
    b2b, b2g = _torques(cfg, N_STEPS)
    scaled = dataclasses.replace(
        rp._with_modulus(cfg, rp.MODULUS_CONVENTION_FACTOR),
        operation=dataclasses.replace(cfg.operation, axial_load_n=2 * cfg.operation.axial_load_n))
    b2b2, b2g2 = _torques(scaled, N_STEPS)
    assert b2b.max() > 0.3 * b2g.max()
    np.testing.assert_allclose(b2g2, 2 * b2g, rtol=SIMILARITY_REL)
    np.testing.assert_allclose(b2b2 / b2g2, b2b / b2g, atol=SIMILARITY_REL)


def test_theta_phase_matters_only_modulo_360_over_37(config):
    """Screw-fixed theta, rigid nut, zero-length tube: phase + 360/37 deg is the same run."""
    cfg = dataclasses.replace(config, load_distribution="rigid")
    n = cfg.track.n_balls

    def with_phase(deg):
        return dataclasses.replace(cfg, errors=dataclasses.replace(
            cfg.errors, theta_phase_rad=math.radians(deg)))

    b2b, b2g = _torques(cfg, N_STEPS)
    same_b2b, same_b2g = _torques(with_phase(360.0 / n), N_STEPS)
    np.testing.assert_allclose(same_b2b, b2b, atol=SIMILARITY_REL * b2b.max())
    np.testing.assert_allclose(same_b2g, b2g, rtol=SIMILARITY_REL)
    half_b2b, _ = _torques(with_phase(180.0 / n), N_STEPS)    # half the period: another run
    assert np.max(np.abs(half_b2b - b2b)) > 0.01 * b2b.max()


def test_step_size_does_not_reach_the_paper_s_return_to_zero(config, model):
    """Half the paper's 3.6 deg step: B2B still returns to 0 at 266-288 deg, not 306 (docs)."""
    rows = {r["quantity"]: r for r in rp.step_size_rows(config, model)}
    zero = next(r for q, r in rows.items() if q.startswith(
        "Fig. 21 nut angle where B2B torque returns to 0"))
    assert "1.8 deg steps" in zero["quantity"]
    assert 266.0 <= zero["ours"] <= 288.0
    assert zero["paper"] == paper.B2B_ZERO_NUT_ANGLE.value
