"""Shared fixtures: one small in-process Dask cluster per test session, bound to 127.0.0.1."""

import logging

import pytest
import yaml

from bb_friction_ros.sweep.spec import spec_from_mapping


@pytest.fixture(scope='session')
def cluster():
    """Two single-threaded in-process workers (processes=False: starts in well under 1 s)."""
    from distributed import LocalCluster
    cl = LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol='tcp://',
                      host='127.0.0.1', dashboard_address='127.0.0.1:0',
                      silence_logs=logging.ERROR)
    try:
        yield cl
    finally:
        cl.close()


@pytest.fixture
def client(cluster):
    """Client of the session cluster, closed after the test."""
    from distributed import Client
    c = Client(cluster)
    try:
        yield c
    finally:
        c.close()


@pytest.fixture
def write_spec(tmp_path):
    """Write a spec mapping as YAML under tmp_path and return its path."""
    def write(mapping, name='spec.yaml'):
        path = tmp_path / name
        path.write_text(yaml.safe_dump({'sweep': mapping}))
        return path
    return write


@pytest.fixture
def linear_mc():
    """Return a factory of small linear-pair Monte Carlo specs (numerical model)."""
    def make(samples=24, seed=3, batch_size=5, **extra):
        data = {'model': 'linear_pair', 'batch_size': batch_size,
                'random': {'samples': samples, 'seed': seed, 'variables': {
                    'theta_deg': {'dist': 'normal', 'mean': 0.0, 'std': 1.5},
                    'rho': {'dist': 'uniform', 'low': -0.6, 'high': 0.6}}}}
        data.update(extra)
        return spec_from_mapping(data, default_name='linear_mc')
    return make
