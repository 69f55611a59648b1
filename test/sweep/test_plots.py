"""Plots: heatmaps for grids, histograms for Monte Carlo, the sensitivity bars."""

import numpy as np
import pyarrow.parquet as pq
import pytest

from bb_friction_ros.sweep.engine import run_sweep
from bb_friction_ros.sweep.plots import display_input, grid_medians
from bb_friction_ros.sweep.spec import spec_from_mapping

QUIET = {'progress': False, 'log': lambda msg: None}


def test_grid_with_draws_writes_every_plot(tmp_path, client):
    spec = spec_from_mapping({
        'model': 'linear_pair', 'options': {'method': 'analytical'}, 'batch_size': 50,
        'grid': {'theta_deg': [-2.0, 0.0, 2.0], 'rho': [-0.6, 0.6]},
        'random': {'samples': 8, 'seed': 1, 'variables': {
            'vertical_load_n': {'dist': 'uniform', 'low': 50.0, 'high': 150.0}}}})
    rep = run_sweep(spec, tmp_path, client=client, **QUIET)
    for name in ('grid_heatmaps.png', 'mc_histograms.png', 'sensitivity.png'):
        assert (tmp_path / name).stat().st_size > 1000
    table = pq.read_table(tmp_path / 'results.parquet')
    med = grid_medians(spec, table, 'f_b2b_n')
    assert med.shape == (3, 2)
    # contact at (theta, rho) = (+2, -0.6) and (-2, +0.6) only (Fig. 9)
    assert med[2, 0] > 0 and med[0, 1] > 0 and med[1, 0] == med[1, 1] == 0.0
    assert rep.summary['sensitivity']['by_output']


def test_display_units():
    label, v = display_input('errors.nut_lead_error_m', np.array([2e-6]))
    assert label.endswith('[um]') and v[0] == pytest.approx(2.0)
    label, v = display_input('theta_rad', np.array([np.pi / 180]))
    assert label == 'theta [deg]' and v[0] == pytest.approx(1.0)
