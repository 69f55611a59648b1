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
    # a sub-step solved tighter than the answered steps: a mistake, not a choice
    ({"solver": {"substep_tolerance": 1e-9}}, "ball_screw.solver.substep_tolerance"),
])
def test_bad_config_names_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_ball_screw(overrides=override)


def test_edge_units_converted():
    cfg = load_ball_screw(overrides={"errors": {"theta_amplitude_deg": 1.5},
                                     "geometry": {"ball_oversize_um": 2.0}})
    assert cfg.errors.theta_amplitude_rad == pytest.approx(math.radians(1.5))
    assert cfg.geometry.ball_oversize_m == pytest.approx(2e-6)


def test_nut_velocity_is_signed_and_so_named():
    # omega_N is signed (its sign sets the direction of friction): *_velocity_*, as in the
    # node, the runner and the bags.
    cfg = load_ball_screw(overrides={"operation": {"nut_velocity_rad_s": -3.0}})
    assert cfg.operation.nut_velocity_rad_s == -3.0


def test_old_name_nut_speed_is_read_as_nut_velocity_with_a_warning(tmp_path):
    # Files written before the rename keep working; the warning names both keys.
    p = tmp_path / "old.yaml"
    p.write_text("ball_screw:\n  operation:\n    nut_speed_rad_s: -3.0\n")
    with pytest.warns(FutureWarning, match=r"ball_screw\.operation\.nut_speed_rad_s: renamed "
                      r"to nut_velocity_rad_s"):
        cfg = load_ball_screw(p)
    assert cfg.operation.nut_velocity_rad_s == -3.0
    # both spellings at once is ambiguous: refused, naming the key
    with pytest.warns(FutureWarning), pytest.raises(ConfigError, match="given twice"):
        load_ball_screw(overrides={"operation": {"nut_velocity_rad_s": 1.0,
                                                 "nut_speed_rad_s": 3.0}})
    with pytest.warns(FutureWarning), pytest.raises(ConfigError,
                                                    match=r"operation\.nut_speed_rad_s"):
        load_ball_screw(overrides={"operation": {"nut_speed_rad_s": 1e9}})
