"""Mitigation advisor: matched carriage deviations null B2B friction (Table 2/3 case b)."""

import math

import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import ConfigError, load_linear_bearing
from bb_friction_ros.sweep.advisor import advise, format_advice
from invariants import paper_approx

THETA = paper.TABLE1["theta_rad"]


def test_matched_carriage_nulls_b2b_friction():
    result = advise(load_linear_bearing(), -THETA, THETA, [-0.6, 0.6])
    (station,) = result['stations']
    assert station['matched_dbeta_tr_rad'] == -THETA
    assert station['matched_dbeta_tl_rad'] == THETA
    before, after = station['cases'][0]['before'], station['cases'][0]['after']
    assert before['f_b2b_n'] == paper_approx(paper.F_B2B_NUM)        # Table 3 (a)
    assert after['f_b2b_n'] == 0.0 and abs(after['eps_diff']) < 1e-9  # Table 2/3 (b)
    assert after['friction_ratio'] == pytest.approx(1.0)
    assert station['cases'][1]['before']['f_b2b_n'] == 0.0            # rho > 0: no contact
    assert any('F_B2B 0.0000 N' in line for line in format_advice(result))


def test_several_stations_get_one_carriage_too():
    result = advise(load_linear_bearing(), [-THETA, -0.5 * THETA], [THETA, 1.5 * THETA])
    single = result['single_carriage']
    assert single['dbeta_tr_rad'] == pytest.approx(-0.75 * THETA)
    assert single['dbeta_tl_rad'] == pytest.approx(1.25 * THETA)
    worst_before = max(c['before']['f_b2b_n'] for s in result['stations'] for c in s['cases'])
    worst_after = max(c['after']['f_b2b_n'] for c in single['cases'])
    assert worst_after < 0.05 * worst_before


@pytest.mark.parametrize('args,key', [
    (([0.0, 0.1], [0.0]), '--dbeta-br-deg'),
    (([math.nan], [0.0]), '--dbeta-bl-deg'),
    (([0.0], [0.0], [1.5]), '--rho'),
])
def test_bad_input_names_the_flag(args, key):
    with pytest.raises(ConfigError, match=key):
        advise(load_linear_bearing(), *args)
