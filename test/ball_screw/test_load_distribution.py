"""Elastic load distribution (ref. [19] set-up): rigid limit, load sum, power balance, mirror."""

import numpy as np
import pytest

from bb_friction_ros.ball_screw.load_distribution import (axial_order, bar_compliances,
                                                          compatibility_terms)
from bb_friction_ros.ball_screw.simulation import run_whole_screw
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import ConfigError
from bb_friction_ros.model_file import load_ball_screw
from invariants import check_step, SCREW_POWER_REL

STEPS = 30    # 108 deg of nut rotation: B2B groups form (active-set changes every step)


def _run(model, steps=STEPS, **overrides):
    cfg = load_ball_screw(overrides=overrides)
    screw = WholeScrew(cfg, model)
    return run_whole_screw(cfg, n_steps=steps, screw=screw)[0]


@pytest.fixture(scope="module")
def elastic_run(model):
    return _run(model, load_distribution="elastic")


def test_load_sum_equals_applied_load_every_step(elastic_run, config):
    w = config.operation.axial_load_n
    for r in elastic_run:
        assert r.converged
        assert r.ball_axial_loads_n.sum() == pytest.approx(w, rel=1e-9)


def test_power_balance_every_step(elastic_run):
    # Quasi-static bulk deformation does no work: drive power = groove + B2B losses, and
    # every other whole-screw invariant holds (test/invariants.py, SCREW_POWER_REL).
    for r in elastic_run:
        check_step(r)
        assert r.power_balance_error < SCREW_POWER_REL


def test_b2b_groups_form_with_elastic_bodies(elastic_run):
    assert max(r.n_groups for r in elastic_run) >= 3


def test_infinitely_stiff_shaft_and_nut_give_the_rigid_result(model):
    # E A -> 1e30 N: the bars' compliance vanishes, every ball sees the same nut
    # displacement, and the elastic system is the rigid one.  Both flange cases exercise the
    # nut terms.  Tolerance: solver tolerance 1e-10 relative to the force scale.
    rigid = _run(model, steps=12)
    for support in ("outer_surface", "flange_at_track_end"):
        stiff = _run(model, steps=12, load_distribution="elastic",
                     elastic={"shaft_axial_rigidity_n": 1e30, "nut_axial_rigidity_n": 1e30,
                              "nut_support": support})
        for a, b in zip(rigid, stiff):
            assert b.torque_total_nm == pytest.approx(a.torque_total_nm, rel=1e-7)
            assert b.torque_b2b_nm == pytest.approx(a.torque_b2b_nm, rel=1e-6, abs=1e-12)
            np.testing.assert_allclose(b.ball_axial_loads_n, a.ball_axial_loads_n,
                                       rtol=1e-7)


def test_loads_fall_away_from_the_loaded_end_and_mirror(model):
    # Without theta all balls are alike: the load is largest at the shaft's loaded end and
    # falls monotonically along the nut (bolted-joint behaviour), and moving the load to
    # the other end mirrors the distribution (identical balls, even spacing).
    loads = {}
    for end in ("track_start", "track_end"):
        r = _run(model, steps=1, load_distribution="elastic",
                 errors={"theta_amplitude_deg": 0.0},
                 elastic={"shaft_load_end": end})[0]
        order = axial_order(r.azimuth_rad)
        loads[end] = r.ball_axial_loads_n[order]
    start = loads["track_start"]
    assert np.all(np.diff(start) < 0.0)
    assert start[0] / start[-1] > 1.05        # visible, ~1.1 for Table 4 and ref. [19]
    np.testing.assert_allclose(loads["track_end"], start[::-1], rtol=1e-6)


def test_compatibility_terms_rigid_limit_and_selectors(config):
    el = config.elastic
    phi = np.linspace(0.0, 1.0, 5)
    c_s, c_n = bar_compliances(phi, config.geometry.lead_m, el)
    assert np.all(c_s > 0.0) and np.all(c_n == 0.0)       # nut held on its outer surface
    a, b = compatibility_terms(c_s, c_n, 1000.0, el, 10.0)
    np.testing.assert_allclose(a, 1000.0 * c_s / 1e-6)    # shaft loaded at the track start
    np.testing.assert_allclose(b, 10.0 * c_s / 1e-6)


@pytest.mark.parametrize("key, value", [("load_distribution", "flexible"),
                                        ("elastic", {"nut_support": "glued"}),
                                        ("elastic", {"shaft_load_end": "middle"}),
                                        ("elastic", {"shaft_axial_rigidity_n": 0.0})])
def test_bad_elastic_config_is_refused_by_name(key, value):
    with pytest.raises(ConfigError, match=key):
        load_ball_screw(overrides={key: value})
