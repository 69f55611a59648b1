"""The sub-commands: exit codes, refusal naming the key, resume across invocations."""

import argparse
import json

import pytest
import yaml

from bb_friction_ros.config import ConfigError
from bb_friction_ros.sweep.cli import add_sweep_parsers


def parse(*argv):
    parser = argparse.ArgumentParser(prog='bb-friction')
    add_sweep_parsers(parser.add_subparsers(dest='command'))
    return parser.parse_args(list(argv))


def call(*argv):
    args = parse(*argv)
    return args.func(args)


def test_bad_spec_raises_config_error_naming_the_key(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump({'sweep': {'model': 'linear_pair', 'random': {
        'samples': 10, 'seed': 1, 'variables': {'rho': {'dist': 'normal', 'mean': 0}}}}}))
    with pytest.raises(ConfigError, match='sweep.random.variables.rho.std'):
        call('sweep', str(path), '--out', str(tmp_path / 'out'))
    with pytest.raises(ConfigError, match='--workers'):
        call('sweep', str(path), '--out', str(tmp_path / 'out'), '--workers', '0')


def test_workers_and_scheduler_exclude_each_other():
    with pytest.raises(SystemExit):
        parse('sweep', 's.yaml', '--out', 'o', '--workers', '2', '--scheduler', 'tcp://x:1')


def test_sweep_stops_then_resumes_with_exit_codes(tmp_path, cluster, capsys):
    path = tmp_path / 'grid.yaml'
    path.write_text(yaml.safe_dump({'sweep': {
        'model': 'linear_pair', 'batch_size': 4,
        'grid': {'theta_deg': [-2.0, -1.0, 1.0, 2.0], 'rho': [-0.6, 0.6]}}}))
    common = ('sweep', str(path), '--out', str(tmp_path / 'out'), '--scheduler',
              cluster.scheduler_address, '--no-progress', '--no-plots')
    assert call(*common, '--max-samples', '1') == 3
    assert not (tmp_path / 'out' / 'results.parquet').exists()
    assert call(*common) == 0
    assert '8 samples (8 ok' in capsys.readouterr().out
    summary = json.loads((tmp_path / 'out' / 'summary.json').read_text())
    assert summary['n_samples'] == 8 and summary['invocations'] == 2


def test_linear_mitigate_json(capsys):
    assert call('linear-mitigate', '--dbeta-bl-deg', '-2', '--dbeta-br-deg', '2', '--rho',
                '-0.6', '--json') == 0
    result = json.loads(capsys.readouterr().out)
    case = result['stations'][0]['cases'][0]
    assert case['before']['f_b2b_n'] > 3.9 and case['after']['f_b2b_n'] == 0.0


@pytest.mark.parametrize('flag', ['--max-in-flight', '--connect-timeout-s', '--memory-limit-mib'])
@pytest.mark.parametrize('value', ['0', '-1', 'nan', 'x'])
def test_run_settings_must_be_positive(flag, value, capsys):
    """The run settings are refused by their flag when not > 0."""
    with pytest.raises(SystemExit) as exc:
        parse('sweep', 's.yaml', '--out', 'o', flag, value)
    assert exc.value.code == 2 and flag in capsys.readouterr().err


def test_memory_limit_flag_reaches_the_check(tmp_path):
    path = tmp_path / 'grid.yaml'
    path.write_text(yaml.safe_dump({'sweep': {'model': 'linear_pair',
                                              'grid': {'rho': [-0.6, 0.0, 0.6]}}}))
    with pytest.raises(ConfigError, match=r'3 samples .*--memory-limit-mib'):
        call('sweep', str(path), '--out', str(tmp_path / 'out'), '--memory-limit-mib', '1e-6')
    assert not (tmp_path / 'out').exists()
