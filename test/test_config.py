"""Validated configuration: units at the edges, refusal naming the key and the reason."""

import math

import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import ConfigError, load_linear_bearing


def test_defaults_are_table1():
    """Built-in defaults are the paper's Table 1 and Sec. 2.4 case, in SI."""
    cfg = load_linear_bearing()
    for key, printed in paper.TABLE1.items():
        if key != "theta_rad":            # a case-study input, not a bearing property
            assert getattr(cfg, key) == pytest.approx(printed, rel=1e-15), key
    assert cfg.k_f == paper.K_F.value


def test_edge_units_convert(tmp_path):
    """*_deg and *_mm keys in YAML become the SI fields."""
    p = tmp_path / "lb.yaml"
    p.write_text("linear_bearing:\n  ball_radius_mm: 4\n  nominal_contact_angle_deg: 40\n")
    cfg = load_linear_bearing(p)
    assert cfg.ball_radius_m == pytest.approx(4e-3)
    assert cfg.nominal_contact_angle_rad == pytest.approx(math.radians(40))


@pytest.mark.parametrize("text,needle", [
    ("linear_bearing:\n  conformity: 0.45\n", "linear_bearing.conformity: must be > 0.5"),
    ("linear_bearing:\n  colour: red\n", "linear_bearing.colour: unknown key"),
    ("linear_bearing:\n  friction_coefficient: fast\n", "friction_coefficient: expected"),
    ("linear_bearing:\n  ball_radius_m: .inf\n", "ball_radius_m: must be finite"),
    ("linear_bearing: [1, 2\n", "not valid YAML"),
    ("linear_bearing:\n  ball_radius_m: 0.005\n  ball_radius_mm: 5\n", "given twice"),
])
def test_bad_config_names_key_and_reason(tmp_path, text, needle):
    """A bad config refuses to load; the message names the key and why."""
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=needle.replace("(", r"\(").replace(".", r"\.")):
        load_linear_bearing(p)


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_linear_bearing(tmp_path / "nope.yaml")


def test_bundled_config_is_table1(repo_root):
    """config/linear_bearing.yaml loads (YAML 1.1 '2.1e11' included) and equals the defaults."""
    assert load_linear_bearing(repo_root / "config" / "linear_bearing.yaml") == \
        load_linear_bearing()
