"""Config: YAML equals the built-in defaults; bad input is refused naming the key."""

import math
from pathlib import Path

import pytest

from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.config import ConfigError

YAML = Path(__file__).resolve().parents[2] / "config" / "ball_screw.yaml"


def test_yaml_matches_defaults():
    assert load_ball_screw(YAML) == load_ball_screw()


def test_table4_values_si(config):
    g = config.geometry
    assert g.ball_radius_m == pytest.approx(2.778e-3)
    assert g.lead_m == pytest.approx(20e-3)
    assert g.nominal_contact_angle_rad == pytest.approx(math.pi / 4)
    assert config.material.youngs_modulus_pa == pytest.approx(210e9)


@pytest.mark.parametrize("override, key", [
    ({"geometry": {"ball_radius_mm": -1.0}}, "ball_screw.geometry.ball_radius_mm"),
    ({"errors": {"theta_amp_deg": 1.0}}, "ball_screw.errors.theta_amp_deg"),
    ({"material": {"poisson_ratio": 0.7}}, "ball_screw.material.poisson_ratio"),
    ({"track": {"n_balls": 1}}, "ball_screw.track.n_balls"),
])
def test_bad_config_names_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_ball_screw(overrides=override)


def test_edge_units_converted():
    cfg = load_ball_screw(overrides={"errors": {"theta_amplitude_deg": 1.5},
                                     "geometry": {"ball_oversize_um": 2.0}})
    assert cfg.errors.theta_amplitude_rad == pytest.approx(math.radians(1.5))
    assert cfg.geometry.ball_oversize_m == pytest.approx(2e-6)
