"""Torque-fluctuation verdict: the criterion, the interval, and a short whole-screw run."""

import json

import numpy as np
import pyarrow as pa
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.sweep.spec import spec_from_mapping
from bb_friction_ros.sweep.verdict import (run_verdict, variation, verdict_rows, verdict_specs,
                                           wilson_interval)

QUIET = {'progress': False, 'plots': False, 'log': lambda msg: None}


def table(mean, tmax, tmin, status=None):
    n = len(mean)
    mean, tmax, tmin = (np.asarray(v, dtype=float) for v in (mean, tmax, tmin))
    dev = np.maximum(tmax - mean, mean - tmin) / np.abs(mean)
    return pa.table({'torque_mean_nm': mean, 'torque_max_nm': tmax, 'torque_min_nm': tmin,
                     'torque_dev_max_rel': dev, 'status': status or ['ok'] * n})


def screw_spec(samples=4, **extra):
    data = {'model': 'whole_screw', 'base': {'overrides': {
        'operation': {'n_steps': 6, 'duration_s': 0.06}}},
        'random': {'samples': samples, 'seed': 2, 'variables': {
            'errors.theta_amplitude_deg': {'dist': 'uniform', 'low': 0.5, 'high': 3.0}}}}
    data.update(extra)
    return spec_from_mapping(data, default_name='screw')


def test_variation_about_own_mean_or_a_reference():
    t = table([1.0, 1.0, 2.0], [1.1, 1.5, 2.2], [0.95, 1.0, 1.0], ['ok', 'ok', 'failed'])
    assert np.allclose(variation(t)[:2], [0.1, 0.5]) and np.isnan(variation(t)[2])
    assert np.allclose(variation(t, reference_torque_nm=1.2)[:2], [0.25 / 1.2, 0.3 / 1.2])


def test_wilson_interval():
    lo, hi = wilson_interval(0, 100)
    assert lo == pytest.approx(0.0, abs=1e-12) and hi == pytest.approx(0.0370, abs=1e-4)
    lo, hi = wilson_interval(50, 100)
    assert (lo, hi) == pytest.approx((0.4038, 0.5962), abs=1e-4)
    assert wilson_interval(0, 0) is None


def test_verdict_rows_count_failures_and_missing():
    spec = screw_spec(samples=4)
    nominal = table([1.0], [1.05], [0.97])
    tol = table([1.0] * 4, [1.05, 1.4, 1.1, 1.0], [1.0] * 4, ['ok', 'ok', 'ok', 'failed'])
    (row,) = verdict_rows(spec, nominal, tol, band_rel=0.2)
    assert row['nominal_pass'] is True and row['nominal_variation_rel'] == pytest.approx(0.05)
    assert (row['n_with_result'], row['n_fail'], row['n_missing']) == (3, 1, 1)
    assert row['p_fail'] == pytest.approx(1 / 3)
    assert row['p_fail_if_missing_fail'] == pytest.approx(2 / 4)
    (row,) = verdict_rows(spec, nominal, tol, band_rel=0.01)
    assert row['nominal_pass'] is False


def test_verdict_needs_the_whole_screw_and_tolerances():
    with pytest.raises(ConfigError, match='sweep.model'):
        verdict_specs(spec_from_mapping({'model': 'screw_pair'}))
    with pytest.raises(ConfigError, match='sweep.random'):
        verdict_specs(spec_from_mapping({'model': 'whole_screw'}))
    nominal, tol = verdict_specs(screw_spec(outputs=['max_groups']))
    assert nominal.variables == () and nominal.samples == 1
    assert {'torque_dev_max_rel', 'max_groups'} <= set(tol.outputs)


def test_short_whole_screw_verdict(tmp_path, cluster):
    spec = screw_spec(samples=3)
    result = run_verdict(spec, tmp_path, band_rel=0.5, scheduler=cluster.scheduler_address,
                         **QUIET)
    assert json.loads((tmp_path / 'verdict.json').read_text()) == result
    (row,) = result['rows']
    assert row['n_builds'] == 3 and row['n_with_result'] + row['n_missing'] == 3
    assert result['nominal_pass'] in (True, False)
    assert (tmp_path / 'nominal' / 'results.parquet').exists()
    assert (tmp_path / 'tolerance' / 'results.parquet').exists()
    with pytest.raises(ConfigError, match='--band-pct'):
        run_verdict(spec, tmp_path, band_rel=0.0, scheduler=cluster.scheduler_address, **QUIET)
