"""The model file (ball-screw config + empirical terms): one reader, one writer, bad shapes."""

import re

import pytest

from bb_friction_ros.ball_screw.parameters import BallScrewConfig
from bb_friction_ros.config import ConfigError
from bb_friction_ros.empirical_terms import make_term, TermSet
from bb_friction_ros.model_file import (load_ball_screw, load_model_file, read_model_file,
                                        write_model_file)


def test_bundled_config_has_no_terms(repo_root):
    cfg, terms = load_model_file(repo_root / "config" / "ball_screw.yaml")
    assert cfg == BallScrewConfig() and len(terms) == 0


def test_written_model_file_reads_back(tmp_path):
    """write_model_file and load_model_file agree: the config and the terms round-trip."""
    terms = TermSet([make_term("viscous_drag", {"c_nm_s_per_rad": 0.004}),
                     make_term("seal_drag", {"torque_nm": 0.03})])
    path = write_model_file(tmp_path / "augmented.yaml", {"track": {"n_balls": 30}}, terms,
                            "# a header\n")
    assert path.read_text().startswith("# a header\n")
    cfg, back = load_model_file(path)
    assert cfg.track.n_balls == 30 and back.to_list() == terms.to_list()
    assert read_model_file(path)[0] == {"track": {"n_balls": 30}}


def test_flat_file_with_terms(tmp_path):
    """Without a ``ball_screw`` key the sections sit at top level, next to the terms."""
    p = tmp_path / "flat.yaml"
    p.write_text("track: {n_balls: 30}\nempirical_terms:\n"
                 "  - {name: seal_drag, params: {torque_nm: 0.01}}\n")
    cfg, terms = load_model_file(p)
    assert cfg.track.n_balls == 30 and terms.names == ("seal_drag",)
    assert load_ball_screw(p) == cfg


@pytest.mark.parametrize("text,needle", [
    # each was a traceback (or silently ignored) before
    ("1: 2\n", "ball_screw: key 1 is not a name"),
    ("ball_screw:\n  track: {n_balls: 37.7}\n", "ball_screw.track.n_balls: must be an integer"),
    ("ball_screw:\n  operation: {n_steps: 200.5}\n",
     "ball_screw.operation.n_steps: must be an integer"),
    ("ball_screw: [1]\n", "ball_screw: expected a mapping, got list"),
    ("ball_screw: abc\n", "ball_screw: expected a mapping, got str"),
    ("ball_screw:\n  track: [1]\n", "ball_screw.track: expected a mapping, got list"),
    ("ball_screw:\n  track: {1: 2}\n", "ball_screw.track: key 1 is not a name"),
    ("- ball_screw\n", "expected a mapping of keys at top level, got list"),
    ("ball_screw\n", "expected a mapping of keys at top level, got str"),
    ("ball_screw:\n  track: {n_balls: 30}\n  track: {n_balls: 31}\n",
     "line 3: key 'track' given twice"),
    ("ball_screw:\n  solver:\n    map_polar_nodes: 160.5\n",
     "ball_screw.solver.map_polar_nodes: must be an integer"),
    ("ball_screw: {track: {n_balls: 30}}\nempirical_terms: {name: seal_drag}\n",
     "empirical_terms: expected a list"),
])
def test_badly_shaped_model_file_is_refused_by_name(tmp_path, text, needle):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(needle)):
        load_model_file(p)


def test_binary_model_file_is_refused(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ConfigError, match="not a text file"):
        load_model_file(p)


def test_exponent_string_with_edge_unit(tmp_path):
    """``module_theta2_deg: 2e0`` is 2 degrees, not refused as 2 rad."""
    p = tmp_path / "m.yaml"
    p.write_text("ball_screw:\n  operation: {module_theta2_deg: 2e0}\n")
    assert load_ball_screw(p).operation.module_theta2_rad == pytest.approx(0.0349065850398866)


@pytest.mark.parametrize("text", [
    "", "\n# only a comment\n", "ball_screw:\n", "ball_screw: {}\n", "ball_screw: null\n",
    "empirical_terms:\n  - {name: seal_drag, params: {torque_nm: 0.01}}\n",
    "ball_screw:\nempirical_terms:\n  - {name: seal_drag, params: {torque_nm: 0.01}}\n",
])
def test_model_file_without_ball_screw_values_is_refused(tmp_path, text):
    """An empty or truncated model file used to run silently as the paper's screw."""
    p = tmp_path / "truncated.yaml"
    p.write_text(text)
    for load in (load_model_file, load_ball_screw):
        with pytest.raises(ConfigError, match=re.escape(f"{p}: no ball-screw values")):
            load(p)


def test_truncated_config_refused_by_replay_and_node_runner(tmp_path):
    """The runner the node and replay build refuses it too, naming the file."""
    from bb_friction_ros.runner import build_runner
    p = tmp_path / "ball_screw.yaml"
    p.write_text("ball_screw:\n")
    with pytest.raises(ConfigError, match=re.escape(str(p))):
        build_runner(p, 100.0)
