"""Sensitivity measures and the summary statistics, on data with a known answer."""

import math

import numpy as np
import pytest

from bb_friction_ros.sweep.report import first_order_index, output_statistics, sensitivity


def test_linear_model_recovers_src_and_ranking():
    rng = np.random.default_rng(0)
    x1, x2, x3 = rng.normal(size=(3, 2000))
    y = 3.0 * x1 - 1.0 * x2 + 0.0 * x3
    s = sensitivity({'x1': x1, 'x2': x2, 'x3': x3}, y)
    assert s['r2_linear'] == pytest.approx(1.0)
    assert s['src']['x1'] == pytest.approx(3 / math.sqrt(10), rel=0.05)
    assert s['src']['x2'] == pytest.approx(-1 / math.sqrt(10), rel=0.1)
    assert s['first_order']['x1'] == pytest.approx(0.9, abs=0.05)
    assert s['first_order']['x3'] < 0.02
    assert s['spearman']['x1'] > 0.9 > -0.1 > s['spearman']['x2']


def test_first_order_index_sees_a_non_monotone_effect():
    """y = x1^2: a rank correlation of zero, but x1 explains everything."""
    rng = np.random.default_rng(1)
    x1, x2 = rng.normal(size=(2, 4000))
    y = x1 ** 2
    s = sensitivity({'x1': x1, 'x2': x2}, y)
    assert abs(s['spearman']['x1']) < 0.05
    assert s['first_order']['x1'] > 0.9 and s['first_order']['x2'] < 0.02


def test_first_order_index_on_grid_values_uses_their_levels():
    x = np.repeat([0.0, 1.0, 2.0], 50)
    assert first_order_index(x, x * 2.0) == pytest.approx(1.0)
    pure_interaction = np.tile([-1.0, 1.0], 75) * np.repeat([-1.0, 1.0], 75)
    assert first_order_index(np.repeat([-1.0, 1.0], 75), pure_interaction) == 0.0


def test_output_statistics():
    stats = output_statistics(np.array([np.nan, *range(101)], dtype=float))
    assert stats['n'] == 101 and stats['q50'] == 50.0 and stats['q05'] == 5.0
    assert stats['min'] == 0.0 and stats['max'] == 100.0
    assert output_statistics(np.array([np.nan])) == {'n': 0}
