"""Shared fixtures: one model baseline for every synthetic recording of these tests."""

import numpy as np
import pytest

from bb_friction_ros.discrepancy.synthetic import (baseline, draw_effect, reference_trajectory,
                                                   synthesize)
from bb_friction_ros.empirical_terms import TermSet


@pytest.fixture(scope="session")
def base(request, tmp_path_factory):
    """Return the model's prediction on the reference trajectory (cached across runs)."""
    try:
        cache_dir = request.config.cache.mkdir("bb_friction_discrepancy")
    except AttributeError:          # pytest run with -p no:cacheprovider
        cache_dir = tmp_path_factory.mktemp("baseline")
    return baseline(reference_trajectory(), cache_dir=cache_dir)


@pytest.fixture(scope="module")
def pair(base):
    """
    Two recordings of the same hidden effects (different noise): fit and validate.

    The effects are viscous drag and inertia.  test_discrepancy_measured.py has a pair of its
    own (seal drag and inertia), which replaces this one there.
    """
    rng = np.random.default_rng(19)
    hidden = TermSet([draw_effect("viscous_drag", rng), draw_effect("inertia", rng)])
    fit, _ = synthesize(base, hidden, 0.004, rng)
    val, _ = synthesize(base, hidden, 0.004, rng)
    return fit, val, hidden
