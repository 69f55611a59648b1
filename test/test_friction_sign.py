"""
A model whose friction follows the motion is refused wherever a model is loaded.

Friction has the sign of the nut velocity (the torque the drive spends on it).  A model file
fitted to a measurement of the opposite sign (a negative load coefficient that overturns the
physics) would make the node, replay and every controller feeding it forward push the axis
along its motion.
"""

import pytest
import yaml

from bb_friction_ros.bags import write_events
from bb_friction_ros.cli import main
from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner, FrictionSignError

from recordings import short_recording


def _model(tmp_path, terms, physics=None):
    doc = yaml.safe_load(open(bundled_config("ball_screw.yaml")))
    doc["empirical_terms"] = terms
    if physics:
        doc = {"physics": physics, **doc}
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_bundled_model_has_friction_of_the_right_sign():
    build_runner(bundled_config("ball_screw.yaml"), 100.0)


def test_load_coefficient_that_overturns_the_physics_is_refused(tmp_path):
    """The figure of a reversed motor current on the demo bag: k = -3.5e-4 N m/N."""
    bad = _model(tmp_path, [{"name": "load_dependent", "params": {"k_nm_per_n": -3.5e-4}}])
    with pytest.raises(FrictionSignError, match="follows the motion"):
        build_runner(bad, 100.0)


def test_load_coefficient_that_only_corrects_the_physics_is_kept(tmp_path):
    """A friction coefficient a little too high in the model: a small negative k is fine."""
    ok = _model(tmp_path, [{"name": "load_dependent", "params": {"k_nm_per_n": -2e-5}}])
    build_runner(ok, 100.0)


@pytest.mark.parametrize("terms", [
    [{"name": "seal_drag", "params": {"torque_nm": 0.05}},
     {"name": "thermal_drift", "params": {"delta_torque_nm": -0.08, "time_constant_s": 60.0}}],
    [{"name": "seal_drag", "params": {"torque_nm": 0.05}},
     {"name": "stroke_position",
      "params": {"center_rad": 0.0, "half_range_rad": 100.0, "p1_nm": 0.08}}],
], ids=["warmed_up", "along_the_stroke"])
def test_terms_alone_that_turn_negative_somewhere_are_refused(tmp_path, terms):
    """physics: none: where a drift or the stroke polynomial overturns the seal drag."""
    with pytest.raises(FrictionSignError):
        build_runner(_model(tmp_path, terms, physics="none"), 100.0)


def test_gravity_offset_alone_is_not_friction_and_is_kept(tmp_path):
    build_runner(_model(tmp_path, [{"name": "seal_drag", "params": {"torque_nm": 0.05}},
                                   {"name": "offset", "params": {"torque_nm": -2.0}}],
                        physics="none"), 100.0)


def test_replay_refuses_the_model_naming_the_file(tmp_path, capsys):
    bad = _model(tmp_path, [{"name": "load_dependent", "params": {"k_nm_per_n": -3.5e-4}}])
    write_events(tmp_path / "bag", short_recording())
    assert main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--config", str(bad), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "follows the motion" in err
    assert not (tmp_path / "out" / "prediction.csv").exists()


def test_node_refuses_to_start_with_the_model(tmp_path, capsys):
    from bb_friction_ros.node import main as node_main
    bad = _model(tmp_path, [{"name": "load_dependent", "params": {"k_nm_per_n": -3.5e-4}}])
    params = tmp_path / "params.yaml"
    params.write_text(f"friction_node:\n  ros__parameters:\n    config_file: '{bad}'\n")
    assert node_main(["friction_node", "--ros-args", "--params-file", str(params)]) == 2
    err = capsys.readouterr().err
    assert "follows the motion" in err and "Traceback" not in err
