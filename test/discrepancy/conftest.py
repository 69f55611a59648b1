"""Shared fixtures: one model baseline for every synthetic recording of these tests."""

import pytest

from bb_friction_ros.discrepancy.synthetic import baseline, reference_trajectory


@pytest.fixture(scope="session")
def base(request, tmp_path_factory):
    """Return the model's prediction on the reference trajectory (cached across runs)."""
    try:
        cache_dir = request.config.cache.mkdir("bb_friction_discrepancy")
    except AttributeError:          # pytest run with -p no:cacheprovider
        cache_dir = tmp_path_factory.mktemp("baseline")
    return baseline(reference_trajectory(), cache_dir=cache_dir)
