"""
Shared fixtures: one model baseline for every synthetic recording of these tests.

The model's own parameters are tried as candidates by default (about 20 model runs over a
recording).  Tests of inputs, outputs, baselines and the empirical terms pass ``--no-physical``:
what they check does not depend on the candidate set, and it keeps ``make test`` within its
time.  The physical candidates are tested in test_physical.py, the default (on, or skipped
without a model) in test_outputs.py, the end-to-end default run in test_discrepancy_inputs.py
(``sqlite_out``) and on the measured drives in test_realdata.py.
"""

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
