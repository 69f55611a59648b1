"""Shared files of the servo-test tests: a loop, a short reversal spec, a terms-only axis."""

import pytest

from bb_friction_ros.config import bundled_config

LOOP = """\
loop:
  rate_hz: 1000.0
  position_gain_per_s: 100.0
  velocity_gain_nm_s_per_rad: 0.125
  velocity_integral_gain_nm_per_rad: 5.0
  torque_limit_nm: 5.0
  velocity_feedforward: 1.0
  acceleration_feedforward: 1.0
  encoder_counts_per_rev: 1048576
plant:
  inertia_kg_m2: 2.0e-4
"""

SHORT_REVERSAL = """\
reference:
  kind: reversal
  speeds_rev_s: [1.0]
  stroke_rev: 0.5
  accel_rev_s2: 20.0
  axial_load_n: 1500.0
"""


@pytest.fixture
def loop_file(tmp_path):
    """Return the path of a valid LOOP.yaml."""
    p = tmp_path / "loop.yaml"
    p.write_text(LOOP)
    return p


@pytest.fixture
def short_spec(tmp_path):
    """Return the path of a 1.3 s reversal spec at 1 rev/s."""
    p = tmp_path / "reversal.yaml"
    p.write_text(SHORT_REVERSAL)
    return p


@pytest.fixture(scope="session")
def axis_model():
    """Return the bundled terms-only axis model (inertia, viscous, Coulomb, Stribeck)."""
    return bundled_config("servo/axis_terms.yaml")
