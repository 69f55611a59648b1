"""Per-model runners: same numbers as the models they wrap; failures become statuses."""

import numpy as np
import pytest

from bb_friction_ros import paper
from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.config import load_linear_bearing
from bb_friction_ros.linear_bearing.case_study import LinearPairCase
from bb_friction_ros.sweep.models import (FAILED, INVALID, MODELS, NONCONVERGED, OK, evaluate,
                                          run_linear_pair, screw_model, stroke_statistics,
                                          with_changes)
from invariants import paper_approx

THETA = paper.TABLE1["theta_rad"]


def run(model_name, base, params, **options):
    model = MODELS[model_name]
    opts = {k: options.get(k, default) for k, (default, _) in model.options.items()}
    names = frozenset(n for n, p in model.parameters(base).items() if p.config_field)
    return evaluate(model, base, params, opts, names)


def test_linear_pair_is_the_case_study():
    """Table 3 (a): F_B2B of the numerical model, and Fig. 9's friction ratio."""
    cfg = load_linear_bearing()
    out, status, _ = run('linear_pair', cfg, {'theta_rad': THETA, 'rho': -0.6})
    ref = LinearPairCase(cfg).numerical(THETA, -0.6)
    assert status == OK
    assert out['f_b2b_n'] == ref.f_b2b_n == paper_approx(paper.F_B2B_NUM)
    assert out['eps_diff'] == pytest.approx(ref.eps[0] - ref.eps[1])
    assert out['friction_ratio'] == pytest.approx((ref.p_f_w + ref.p_b2b_w) / ref.p_f_w)
    an, _, _ = run('linear_pair', cfg, {'theta_rad': THETA, 'rho': -0.6}, method='analytical')
    assert an['f_b2b_n'] == paper_approx(paper.F_B2B_AN)


def test_independent_bottom_deviations_reduce_to_theta():
    """dbeta_BL = -theta, dbeta_BR = +theta through the bottom path gives the theta result."""
    cfg = load_linear_bearing()
    via_theta, _ = run_linear_pair(cfg, {'theta_rad': THETA, 'rho': -0.6,
                                         'dbeta_tr_rad': 0.01}, {'method': 'numerical'})[:2]
    via_bottom, _ = run_linear_pair(cfg, {'dbeta_bl_rad': -THETA, 'dbeta_br_rad': THETA,
                                          'rho': -0.6, 'dbeta_tr_rad': 0.01},
                                    {'method': 'numerical'})[:2]
    assert via_bottom == via_theta
    skewed, _ = run_linear_pair(cfg, {'dbeta_bl_rad': -THETA, 'dbeta_br_rad': 0.5 * THETA,
                                      'rho': -0.6}, {'method': 'numerical'})[:2]
    assert skewed['f_b2b_n'] != via_theta['f_b2b_n']


def test_config_fields_per_sample_and_their_range_check():
    cfg = load_linear_bearing()
    out, status, _ = run('linear_pair', cfg, {'theta_rad': THETA, 'rho': -0.6,
                                              'vertical_load_n': 200.0})
    doubled = LinearPairCase(with_changes(cfg, {'vertical_load_n': 200.0}, 'linear_bearing'))
    assert status == OK and out['f_b2b_n'] == doubled.numerical(THETA, -0.6).f_b2b_n
    out, status, reason = run('linear_pair', cfg, {'theta_rad': THETA,
                                                   'friction_coefficient': -0.1})
    assert status == FAILED and out == {}
    assert 'linear_bearing.friction_coefficient' in reason


def test_two_point_contact_is_reported_not_dropped():
    """Near two-point contact the solver stops: status and reason say so, numbers are null."""
    out, status, reason = run('linear_pair', load_linear_bearing(), {'theta_rad': THETA,
                                                                     'rho': -0.95})
    assert status == NONCONVERGED and out == {}
    assert 'two-point' in reason and 'converge' in reason


def test_converged_but_invalid_keeps_its_numbers(monkeypatch):
    from bb_friction_ros.linear_bearing import case_study

    def flagged(self, *args):
        res = original(self, *args)
        res.valid, res.notes = False, ('ball 1: contact(s) BR unloaded (two-point contact)',)
        return res
    original = case_study.LinearPairCase.numerical
    monkeypatch.setattr(case_study.LinearPairCase, 'numerical', flagged)
    out, status, reason = run('linear_pair', load_linear_bearing(), {'theta_rad': THETA,
                                                                     'rho': -0.6})
    assert status == INVALID and 'two-point' in reason
    assert out['f_b2b_n'] == paper_approx(paper.F_B2B_NUM)


def test_nonconverged_sample_has_no_numbers(monkeypatch):
    from bb_friction_ros.linear_bearing import case_study

    def stuck(self, *args):
        res = original(self, *args)
        res.converged, res.notes = False, ('solver did not converge',)
        return res
    original = case_study.LinearPairCase.numerical
    monkeypatch.setattr(case_study.LinearPairCase, 'numerical', stuck)
    out, status, reason = run('linear_pair', load_linear_bearing(), {'theta_rad': THETA})
    assert status == NONCONVERGED and out == {} and 'converge' in reason


def test_screw_pair_is_the_module():
    cfg = load_ball_screw()
    out, status, _ = run('screw_pair', cfg, {'operation.module_theta2_rad': THETA})
    ref = solve_two_ball_module(screw_model(cfg), 0.0, THETA, cfg.operation.module_axial_load_n)
    assert status == OK and out['f_b2b_n'] == ref.f_b2b_n > 0


def test_screw_model_is_shared_by_configs_that_differ_in_errors_only():
    cfg = load_ball_screw()
    other = with_changes(cfg, {'errors.theta_phase_rad': 1.0}, 'ball_screw')
    assert screw_model(other) is screw_model(cfg)
    assert screw_model(with_changes(cfg, {'geometry.ball_oversize_m': 1e-6},
                                    'ball_screw')) is not screw_model(cfg)


def test_whole_screw_short_stroke():
    cfg = load_ball_screw(overrides={'operation': {'n_steps': 12, 'duration_s': 0.12}})
    out, status, reason = run('whole_screw', cfg, {'errors.theta_amplitude_rad': THETA})
    assert status == OK, reason
    assert out['torque_min_nm'] <= out['torque_mean_nm'] <= out['torque_max_nm']
    # a contact group holds two balls or more
    assert out['torque_b2g_mean_nm'] > 0 and 0 <= out['max_groups'] <= cfg.track.n_balls // 2
    _, status, reason = run('whole_screw', cfg, {}, settle_steps=12)
    assert status == FAILED and 'settle_steps' in reason
    _, status, reason = run('whole_screw', cfg, {'track.n_balls': 100})
    assert status == FAILED and 'n_balls' in reason


def test_stroke_statistics():
    t = np.array([9.0, 1.0, 1.2, 0.8, 1.0])         # a start-up spike, then +-20 %
    b2b = np.array([0.0, 0.1, 0.3, 0.0, 0.1])
    s = stroke_statistics(t, t - b2b, b2b, [0, 1, 2, 0, 1], [0, 2, 3, 0, 2],
                          [0, 1, 1, 0, 1], [1e-9] * 5, settle_steps=1)
    assert s['torque_mean_nm'] == pytest.approx(1.0)
    assert s['torque_band_rel'] == pytest.approx(0.4)
    assert s['torque_dev_max_rel'] == pytest.approx(0.2)
    assert s['b2b_share_max'] == pytest.approx(0.3 / 0.9)
    assert s['max_group_size'] == 3 and s['f_b2b_max_n'] == 2.0
    assert stroke_statistics(t, t, 0 * t, t, [1] * 5, [1] * 5, t)['torque_max_nm'] == 9.0
