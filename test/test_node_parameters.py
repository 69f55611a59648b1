"""The node's parameters, defined once: the node and replay refuse the same values."""

import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.node_parameters import load_params_file, node_parameters, NodeParameters


def test_bundled_params_file_is_the_defaults(repo_root):
    assert load_params_file(repo_root / "config" / "friction_node.yaml") == NodeParameters()


BAD_VALUES = [   # replay used to accept the first two, and "fast" crashed it
    ("model_rate_hz", 5000.0, "model_rate_hz: must be <= 2000.0 Hz"),
    ("model_rate_hz", 100, "model_rate_hz: expected a double"),
    ("model_rate_hz", "fast", "model_rate_hz: expected a double"),
    ("max_axial_load_n", 0.5, "max_axial_load_n: must be >= 1.0 N"),
    ("queue_size", 256.0, "queue_size: expected an integer"),
    ("queue_size", True, "queue_size: expected an integer"),
    ("reliable_qos", 1, "reliable_qos: expected a bool"),
    ("nut_joint", 3, "nut_joint: expected a string"),
    ("model_rate_hz", float("nan"), "model_rate_hz: must be finite"),
    # an empty joint name matches nothing, every input would be rejected
    ("nut_joint", "", "nut_joint: must be a non-empty joint name"),
    ("nut_joint", "  ", "nut_joint: must be a non-empty joint name"),
    # the answer-age bound and the look-ahead profile's shape
    ("max_answer_age_s", 0.0, "max_answer_age_s: must be >= 0.0001 s"),
    ("max_answer_age_s", 1, "max_answer_age_s: expected a double"),
    ("profile_horizon_periods", 1.0, "profile_horizon_periods: must be >= 2.0"),
    ("profile_points", 1, "profile_points: must be >= 2"),
    # the angle schedule
    ("model_step_deg", 0.0, "model_step_deg: must be >= 0.05 deg"),
    ("model_step_deg", 3, "model_step_deg: expected a double"),
    ("model_step_deg", 40.0, "max_model_step_deg: must be >= model_step_deg = 40 deg"),
    ("max_model_step_deg", 1.0, "max_model_step_deg: must be >= model_step_deg"),
    # the GIL switch interval (sys.setswitchinterval refuses <= 0 itself)
    ("gil_switch_interval_s", 0.0, "gil_switch_interval_s: must be >= 1e-05 s"),
    ("gil_switch_interval_s", 1, "gil_switch_interval_s: expected a double"),
]


@pytest.mark.parametrize("name,value,needle", BAD_VALUES)
def test_params_file_is_checked_as_the_node_checks_it(tmp_path, name, value, needle):
    p = tmp_path / "params.yaml"
    p.write_text("friction_node:\n  ros__parameters:\n"
                 f"    {name}: {value!r}\n".replace("'", '"').replace("nan", ".nan"))
    with pytest.raises(ConfigError, match=needle):
        load_params_file(p)
    with pytest.raises(ConfigError, match=needle):
        node_parameters({name: value})


def test_replay_cli_refuses_what_the_node_refuses(tmp_path, capsys):
    from bb_friction_ros.cli import main
    p = tmp_path / "params.yaml"
    p.write_text("friction_node:\n  ros__parameters:\n    model_rate_hz: 100\n")
    assert main(["replay", str(tmp_path / "no_bag"), "--params-file", str(p), "--out",
                 str(tmp_path / "out")]) == 2
    assert "model_rate_hz: expected a double" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "no_bag"), "--model-rate-hz", "5000", "--out",
                 str(tmp_path / "out")]) == 2
    assert "model_rate_hz: must be <= 2000.0 Hz" in capsys.readouterr().err


def test_unknown_parameter_is_refused_by_name():
    with pytest.raises(ConfigError, match="friction_node.rate: not a parameter"):
        node_parameters({"rate": 1.0})


def test_replay_warns_about_an_unknown_parameter(tmp_path, capsys):
    """A misspelt key in a params file is named, not silently ignored."""
    from bb_friction_ros.cli import main
    p = tmp_path / "params.yaml"
    p.write_text("friction_node:\n  ros__parameters:\n    queue_sise: 10\n"
                 "    use_sim_time: false\n")
    assert main(["replay", str(tmp_path / "no_bag"), "--params-file", str(p), "--out",
                 str(tmp_path / "out")]) == 2      # no bag: refused after the warning
    err = capsys.readouterr().err
    assert "unknown parameter friction_node.queue_sise ignored" in err
    assert "use_sim_time" not in err
