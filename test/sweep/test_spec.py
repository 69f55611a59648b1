"""Sweep specs: parsing, units, sample numbering, per-sample seeding, refusal naming the key."""

import math

import numpy as np
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.sweep.spec import load_spec, spec_from_mapping


def grid_spec(**extra):
    data = {'model': 'linear_pair',
            'grid': {'theta_deg': {'start': -3, 'stop': 3, 'num': 7}, 'rho': [-0.6, 0.0, 0.6]}}
    data.update(extra)
    return spec_from_mapping(data)


def test_grid_is_full_factorial_in_si_with_last_axis_fastest():
    spec = grid_spec()
    assert spec.grid_shape == (7, 3) and spec.n_samples == 21
    cols = spec.sample_inputs(0, spec.n_samples)
    assert np.allclose(cols['theta_rad'], np.repeat(np.radians(np.linspace(-3, 3, 7)), 3))
    assert np.allclose(cols['rho'], np.tile([-0.6, 0.0, 0.6], 7))
    assert np.array_equal(cols['grid_index'], np.arange(21))
    assert np.all(cols['draw'] == 0)


def test_step_range_includes_stop():
    spec = grid_spec(grid={'vertical_load_n': {'start': 50, 'stop': 150, 'step': 25}})
    assert spec.grid[0].values == (50.0, 75.0, 100.0, 125.0, 150.0)


def test_draws_depend_only_on_seed_draw_and_name(linear_mc):
    """Any batch cut gives the same inputs; a new variable leaves the others' draws alone."""
    spec = linear_mc(samples=40)
    whole = spec.sample_inputs(0, 40)
    pieces = [spec.sample_inputs(a, b) for a, b in ((0, 7), (7, 33), (33, 40))]
    for name in spec.input_names:
        assert np.array_equal(whole[name], np.concatenate([p[name] for p in pieces]))
    more = linear_mc(samples=40, random={'samples': 40, 'seed': 3, 'variables': {
        'theta_deg': {'dist': 'normal', 'mean': 0.0, 'std': 1.5},
        'rho': {'dist': 'uniform', 'low': -0.6, 'high': 0.6},
        'dbeta_tr_deg': {'dist': 'normal', 'mean': 0.0, 'std': 0.5}}})
    extra = more.sample_inputs(0, 40)
    assert np.array_equal(extra['theta_rad'], whole['theta_rad'])
    assert np.array_equal(extra['rho'], whole['rho'])
    other_seed = linear_mc(samples=40, seed=4).sample_inputs(0, 40)
    assert not np.array_equal(other_seed['theta_rad'], whole['theta_rad'])


def test_distributions_in_si_and_their_moments(linear_mc):
    spec = linear_mc(samples=4000)
    cols = spec.sample_inputs(0, spec.n_samples)
    theta_deg = np.degrees(cols['theta_rad'])
    assert abs(theta_deg.mean()) < 0.1 and theta_deg.std() == pytest.approx(1.5, rel=0.05)
    assert cols['rho'].min() >= -0.6 and cols['rho'].max() <= 0.6


def test_grid_points_share_their_draws():
    """Common random numbers: draw k is the same at every grid point."""
    spec = spec_from_mapping({
        'model': 'linear_pair', 'grid': {'rho': [-0.6, 0.6]},
        'random': {'samples': 5, 'seed': 9,
                   'variables': {'theta_deg': {'dist': 'halfnormal', 'std': 1.0}}}})
    cols = spec.sample_inputs(0, spec.n_samples)
    assert np.array_equal(cols['theta_rad'][:5], cols['theta_rad'][5:])
    assert np.all(cols['theta_rad'] >= 0) and np.array_equal(cols['draw'], np.tile(range(5), 2))


def test_screw_dotted_names_edge_units_and_integer_fields():
    spec = spec_from_mapping({
        'model': 'whole_screw',
        'base': {'overrides': {'operation': {'n_steps': 10}}},
        'grid': {'errors.nut_lead_error_um': [-2, 2]},
        'random': {'samples': 3, 'seed': 1, 'variables': {
            'errors.theta_amplitude_deg': {'dist': 'halfnormal', 'std': 1.0},
            'track.n_balls': {'dist': 'integers', 'low': 35, 'high': 37}}}})
    assert spec.base.operation.n_steps == 10
    assert spec.grid[0].name == 'errors.nut_lead_error_m'
    assert spec.grid[0].values == pytest.approx((-2e-6, 2e-6))
    cols = spec.sample_inputs(0, spec.n_samples)
    assert cols['track.n_balls'].dtype == np.int64
    assert set(cols['track.n_balls']) <= {35, 36, 37}
    assert 'track.n_balls' in spec.config_names


def test_old_parameter_name_nut_speed_sweeps_nut_velocity_with_a_warning():
    with pytest.warns(FutureWarning, match=r"sweep\.grid\.operation\.nut_speed_rad_s: renamed "
                      r"to operation\.nut_velocity_rad_s"):
        spec = spec_from_mapping({'model': 'screw_pair',
                                  'grid': {'operation.nut_speed_rad_s': [-3.0, 3.0]}})
    assert spec.grid[0].name == 'operation.nut_velocity_rad_s'
    assert 'operation.nut_velocity_rad_s' in spec.config_names
    with pytest.raises(ConfigError, match="unknown parameter") as err:
        spec_from_mapping({'model': 'screw_pair', 'grid': {'operation.nut_spede': [1.0]}})
    assert 'nut_speed_rad_s' not in str(err.value)       # the old name is not advertised


def test_digest_tracks_what_changes_the_results():
    a, b = grid_spec(), grid_spec(name='renamed')
    assert a.digest() == b.digest()
    assert grid_spec(batch_size=3).digest() != a.digest()
    assert grid_spec(base={'overrides': {'friction_coefficient': 0.2}}).digest() != a.digest()


def test_load_spec_resolves_base_config_relative_to_the_spec(tmp_path, repo_root):
    (tmp_path / 'lb.yaml').write_text('linear_bearing:\n  friction_coefficient: 0.2\n')
    path = tmp_path / 'study.yaml'
    path.write_text('sweep:\n  model: linear_pair\n  base: {config: lb.yaml}\n'
                    '  grid: {rho: [0.1]}\n')
    spec = load_spec(path)
    assert spec.name == 'study' and spec.base.friction_coefficient == 0.2


def test_bundled_example_specs_load(repo_root):
    paths = sorted((repo_root / 'config' / 'sweeps').glob('*.yaml'))
    assert paths
    for path in paths:
        spec = load_spec(path)
        assert spec.n_samples >= 1


@pytest.mark.parametrize('data,key', [
    ({'model': 'linear_pairs'}, 'sweep.model'),
    ({'model': 'linear_pair', 'grids': {}}, 'sweep.grids'),
    ({'model': 'linear_pair', 'grid': {'thetta_deg': [1]}}, 'sweep.grid.thetta_deg'),
    ({'model': 'linear_pair', 'grid': {'theta_deg': []}}, 'sweep.grid.theta_deg'),
    ({'model': 'linear_pair', 'grid': {'theta_deg': {'start': 0, 'stop': 1, 'num': 0}}},
     'sweep.grid.theta_deg.num'),
    ({'model': 'linear_pair', 'grid': {'rho': ['a']}}, 'sweep.grid.rho[0]'),
    ({'model': 'linear_pair', 'grid': {'side_force_ratio': [0.1]}},
     'sweep.grid.side_force_ratio'),
    ({'model': 'linear_pair', 'grid': {'theta_deg': [1], 'dbeta_bl_deg': [1]}}, 'theta'),
    ({'model': 'linear_pair', 'grid': {'theta_deg': [1]},
      'random': {'samples': 2, 'seed': 0,
                 'variables': {'theta_rad': {'dist': 'normal', 'mean': 0, 'std': 1}}}},
     'theta_rad'),
    ({'model': 'linear_pair', 'random': {'samples': 0, 'seed': 0, 'variables': {}}},
     'sweep.random.samples'),
    ({'model': 'linear_pair', 'random': {'samples': 2, 'seed': -1, 'variables': {}}},
     'sweep.random.seed'),
    ({'model': 'linear_pair', 'random': {'samples': 2, 'seed': 1, 'variables': {
        'rho': {'dist': 'gauss'}}}}, 'sweep.random.variables.rho.dist'),
    ({'model': 'linear_pair', 'random': {'samples': 2, 'seed': 1, 'variables': {
        'rho': {'dist': 'normal', 'mean': 0, 'std': -1}}}}, 'sweep.random.variables.rho.std'),
    ({'model': 'linear_pair', 'random': {'samples': 2, 'seed': 1, 'variables': {
        'rho': {'dist': 'uniform', 'low': 0}}}}, 'sweep.random.variables.rho.high'),
    ({'model': 'whole_screw', 'random': {'samples': 2, 'seed': 1, 'variables': {
        'track.n_balls': {'dist': 'normal', 'mean': 36, 'std': 1}}}},
     'sweep.random.variables.track.n_balls.dist'),
    ({'model': 'whole_screw', 'grid': {'track.n_balls': [36.5]}}, 'sweep.grid.track.n_balls'),
    ({'model': 'linear_pair', 'outputs': ['torque_mean_nm']}, 'sweep.outputs'),
    ({'model': 'linear_pair', 'options': {'method': 'fem'}}, 'sweep.options.method'),
    ({'model': 'linear_pair', 'batch_size': 0}, 'sweep.batch_size'),
    ({'model': 'linear_pair', 'base': {'overrides': {'friction_coefficient': 2.0}}},
     'linear_bearing.friction_coefficient'),
    ({'model': 'whole_screw', 'base': {'overrides': {'track': {'n_ball': 3}}}},
     'ball_screw.track.n_ball'),
    ({'model': 'linear_pair', 'base': {'config': 'no/such/file.yaml'}}, 'no/such/file.yaml'),
])
def test_bad_spec_is_refused_with_the_key_named(data, key):
    with pytest.raises(ConfigError, match=key.replace('[', r'\[').replace(']', r'\]')):
        spec_from_mapping(data)


def test_angles_stay_si_inside():
    spec = grid_spec(grid={'theta_rad': [0.01]})
    assert spec.sample_inputs(0, 1)['theta_rad'][0] == 0.01
    assert math.isclose(grid_spec(grid={'theta_deg': [1.0]}).grid[0].values[0],
                        math.radians(1.0))
