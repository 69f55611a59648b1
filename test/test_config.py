"""Validated configuration: units at the edges, refusal naming the key and the reason."""

import math
import re

import pytest

from bb_friction_ros import paper
from bb_friction_ros.config import ConfigError, load_linear_bearing, parse_number, si_key


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


@pytest.mark.parametrize("text,needle", [
    # badly shaped files are refused by name, never a traceback
    ("- 1\n- 2\n", "expected a mapping of keys at top level, got list"),
    ("just a string\n", "expected a mapping of keys at top level, got str"),
    ("1: 2\n", "linear_bearing: key 1 is not a name"),
    ("linear_bearing:\n  1: 2\n", "linear_bearing: key 1 is not a name"),
    ("linear_bearing: [1]\n", "linear_bearing: expected a mapping, got list"),
    ("linear_bearing: abc\n", "linear_bearing: expected a mapping, got str"),
    ("linear_bearing:\n  map_nodes: 4096.5\n", "linear_bearing.map_nodes: must be an integer"),
    ("linear_bearing:\n  ball_radius_m: [1]\n", "ball_radius_m: expected a number"),
    ("linear_bearing:\n  conformity: 0.55\n  conformity: 0.6\n",
     "line 3: key 'conformity' given twice (first at line 2)"),
    ("linear_bearing:\n  conformity: 0.55\nlinear_bearing:\n  conformity: 0.6\n",
     "line 3: key 'linear_bearing' given twice"),
])
def test_badly_shaped_config_is_refused_by_name(tmp_path, text, needle):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(needle)):
        load_linear_bearing(p)


def test_binary_config_is_refused(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_bytes(bytes(range(256)))
    with pytest.raises(ConfigError, match="not a text file"):
        load_linear_bearing(p)


def test_integral_float_is_an_integer_field(tmp_path):
    """``map_nodes: 4096.0`` (or YAML 1.1's ``4.096e3`` string) is the integer 4096."""
    p = tmp_path / "lb.yaml"
    p.write_text("linear_bearing:\n  map_nodes: 4.096e3\n")
    value = load_linear_bearing(p).map_nodes
    assert value == 4096 and isinstance(value, int)


@pytest.mark.parametrize("key,text,si", [
    # YAML 1.1 reads 1e1 as a string; parse it, then convert the unit
    ("groove_velocity_m_s", "groove_velocity_mm_s: 1e1", 10e-3),
    ("nominal_contact_angle_rad", "nominal_contact_angle_deg: 4e1", math.radians(40.0)),
    ("ball_radius_m", "ball_radius_mm: 5e0", 5e-3),
    ("youngs_modulus_pa", "youngs_modulus_pa: 2.1e11", 2.1e11),
])
def test_exponent_strings_get_the_unit_factor(tmp_path, key, text, si):
    p = tmp_path / "lb.yaml"
    p.write_text(f"linear_bearing:\n  {text}\n")
    assert getattr(load_linear_bearing(p), key) == pytest.approx(si, rel=1e-12)


def test_one_edge_unit_parser():
    """si_key resolves the edge units for config fields and dotted sweep parameters alike."""
    assert si_key("theta_deg", {"theta_rad"}) == ("theta_rad", pytest.approx(math.pi / 180))
    assert si_key("errors.x_um", {"errors.x_m"}) == ("errors.x_m", 1e-6)
    assert si_key("v_mm_s", {"v_m_s", "v_m"}) == ("v_m_s", 1e-3)
    assert si_key("v_m_s", {"v_m_s"}) == ("v_m_s", 1.0)
    assert si_key("colour", {"theta_rad"}) is None
    assert parse_number("1e1", "k") == 10.0
    for bad in (True, "fast", None, [1]):
        with pytest.raises(ConfigError, match="k: expected a number"):
            parse_number(bad, "k")


# --- more balls than fit on the track -------------------------------------------------------

def _crowded_track(tmp_path, n_balls=40):
    path = tmp_path / "crowded.yaml"
    path.write_text(f"ball_screw:\n  track:\n    n_balls: {n_balls}\n")
    return path


def test_more_balls_than_fit_is_refused_at_validation(tmp_path):
    """Two turns hold 37 balls of Table 4 (37.84 B2B separations); 38 and 40 are refused."""
    from bb_friction_ros.ball_screw.geometry import b2b_contact_separation
    from bb_friction_ros.ball_screw.parameters import ScrewGeometry
    from bb_friction_ros.model_file import load_ball_screw
    g = ScrewGeometry()
    capacity = 4.0 * math.pi / b2b_contact_separation(g.ball_radius_m, g.lead_m,
                                                      g.pitch_radius_m)
    assert 37 < capacity < 38
    assert load_ball_screw(_crowded_track(tmp_path, 37)).track.n_balls == 37
    for n in (38, 40):
        with pytest.raises(ConfigError, match=r"ball_screw\.track\.n_balls: .*at most 37 fit"):
            load_ball_screw(_crowded_track(tmp_path, n))
    with pytest.raises(ConfigError, match=r"761\.1 deg of track"):
        load_ball_screw(_crowded_track(tmp_path, 40))
    # more turns make room
    assert load_ball_screw(overrides={"track": {"n_balls": 40, "loaded_turns": 2.5}})


def test_more_balls_than_fit_exits_2_everywhere(tmp_path, capsys, ros_context):
    """screw-sim, replay and friction_node refuse it naming the key: exit 2, no traceback."""
    from bb_friction_ros.bags import write_events
    from bb_friction_ros.cli import main
    from bb_friction_ros.node import main as node_main
    from recordings import short_recording
    path = _crowded_track(tmp_path)
    write_events(tmp_path / "bag", short_recording())
    params = tmp_path / "params.yaml"
    params.write_text(f"friction_node:\n  ros__parameters:\n    config_file: '{path}'\n")
    runs = {
        "screw-sim": lambda: main(["screw-sim", "--config", str(path),
                                   "--out", str(tmp_path / "sim")]),
        "replay": lambda: main(["replay", str(tmp_path / "bag"), "--config", str(path),
                                "--out", str(tmp_path / "rep"), "--no-progress"]),
        "friction_node": lambda: node_main(["friction_node", "--ros-args", "--params-file",
                                            str(params)]),
    }
    for name, run in runs.items():
        assert run() == 2, name
        err = capsys.readouterr().err
        assert "ball_screw.track.n_balls" in err and "Traceback" not in err, (name, err)


# --- config files must be regular files of bounded size ------------------------------------

def test_oversized_config_is_refused_naming_the_file(tmp_path):
    """A 5 MiB file (a YAML comment: valid and empty) is refused, not read as no settings."""
    from bb_friction_ros.config import MAX_CONFIG_BYTES, load_yaml
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * (MAX_CONFIG_BYTES + 1) + "\n")
    with pytest.raises(ConfigError, match=re.escape(f"{big}: larger than 4 MiB")):
        load_yaml(big)
    fits = tmp_path / "fits.yaml"
    fits.write_text("# " + "x" * (MAX_CONFIG_BYTES - 10) + "\n")
    assert load_yaml(fits) == {}


def test_fifo_config_is_refused_without_blocking(tmp_path):
    """A FIFO as --config is refused at once; without the check the reader would block."""
    import os
    import threading
    from bb_friction_ros.config import load_yaml
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    outcome = []

    def read():
        try:
            load_yaml(fifo)
            outcome.append("read")
        except ConfigError as exc:
            outcome.append(str(exc))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(10.0)
    if reader.is_alive():           # blocked: give it an EOF so that the thread ends
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        reader.join(10.0)
        pytest.fail("load_yaml blocked on a FIFO")
    assert outcome == [f"{fifo}: is a FIFO (named pipe), not a regular file; a config must "
                       "be a file"]


@pytest.mark.parametrize("target,kind", [("/dev/zero", "a character device"),
                                         (None, "a directory")])
def test_device_or_directory_config_exits_2_naming_it(tmp_path, target, kind):
    """`--config /dev/zero` was read until memory ran out; now refused at once (exit 2).

    Run in a child with its address space capped at 4 GiB, so that a regression fails
    (MemoryError) instead of exhausting the machine.
    """
    import resource
    import subprocess
    import sys
    target = target or str(tmp_path)

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))

    proc = subprocess.run([sys.executable, "-m", "bb_friction_ros.cli", "screw-sim",
                           "--config", target, "--out", str(tmp_path / "sim")],
                          capture_output=True, text=True, timeout=300, preexec_fn=cap)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert f"{target}: is {kind}, not a regular file" in proc.stderr
    assert "Traceback" not in proc.stderr
