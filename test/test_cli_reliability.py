"""Bad --out paths and bad numeric flags: exit 2, naming them."""

import pytest

from bb_friction_ros.cli import main

# Every sub-command that writes into --out, with the least other arguments it needs.
WRITERS = {
    "replay": ["replay", "BAG"],
    "screw-sim": ["screw-sim", "--steps", "1"],
    "make-demo-bag": ["make-demo-bag"],
    "discrepancy": ["discrepancy", "BAG"],
    "reproduce": ["reproduce", "--grid", "2"],
    "demo": ["demo"],
    "sweep": ["sweep", "SPEC"],
}


@pytest.fixture
def a_file(tmp_path):
    path = tmp_path / "a_file"
    path.write_text("not a directory\n")
    return path


def _argv(name, tmp_path, out):
    bag = tmp_path / "bag"
    bag.mkdir(exist_ok=True)
    return [str(bag) if a == "BAG" else str(tmp_path / "spec.yaml") if a == "SPEC" else a
            for a in WRITERS[name]] + ["--out", str(out)]


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_out_is_a_file(name, tmp_path, a_file, capsys):
    """--out naming a file: exit 2, the path named, no traceback."""
    assert main(_argv(name, tmp_path, a_file)) == 2
    err = capsys.readouterr().err
    reason = "exists already" if name == "make-demo-bag" else "is a file"
    assert str(a_file) in err and reason in err and "Traceback" not in err


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_out_below_a_file(name, tmp_path, a_file, capsys):
    """--out inside a file (cannot be created): exit 2 naming the file in the way."""
    assert main(_argv(name, tmp_path, a_file / "sub")) == 2
    assert f"{a_file} is a file" in capsys.readouterr().err


def test_out_not_writable(tmp_path, monkeypatch, capsys):
    """A directory without write permission is refused up front (checked by os.access)."""
    import os
    real = os.access
    locked = tmp_path / "locked"
    locked.mkdir()
    monkeypatch.setattr(os, "access", lambda p, m: False if str(p) == str(locked)
                        else real(p, m))
    assert main(["screw-sim", "--steps", "1", "--out", str(locked / "run")]) == 2
    assert f"{locked} is not writable" in capsys.readouterr().err


def test_make_demo_bag_refuses_existing_bag(tmp_path, capsys):
    """make-demo-bag over an existing bag: exit 2 naming it (rosbags' WriterError before)."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert main(["make-demo-bag", "--out", str(bag)]) == 2
    assert f"{bag}: exists already" in capsys.readouterr().err
    assert (bag / "metadata.yaml").read_text() == "rosbag2_bagfile_information: {}\n"


def test_late_oserror_names_the_file(tmp_path, monkeypatch, capsys):
    """An OSError during the run (disk full, say) is exit 2 naming the file, no traceback."""
    from bb_friction_ros.ball_screw import simulation

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device", str(tmp_path / "out" / "x.csv"))
    monkeypatch.setattr(simulation, "write_outputs", full_disk)
    assert main(["screw-sim", "--steps", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "x.csv: No space left on device" in err


@pytest.mark.parametrize("argv, flag", [
    (["reproduce", "--grid", "0"], "--grid"),
    (["reproduce", "--grid", "-3"], "--grid"),
    (["reproduce", "--grid", "1"], "--grid"),
    (["reproduce", "--grid", "x"], "--grid"),
    (["demo", "--speed", "0"], "--speed"),
    (["demo", "--speed", "-1"], "--speed"),
    (["demo", "--speed", "nan"], "--speed"),
    (["demo", "--speed", "inf"], "--speed"),
])
def test_bad_numeric_flags_refused_by_name(argv, flag, tmp_path, capsys):
    """--grid 0/-3 and --speed 0/negative/NaN were tracebacks or half-runs."""
    with pytest.raises(SystemExit) as exc:
        main(argv + ["--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# --- one error base, real disk-full failures -----------------------------------------------

# Runs the CLI in a child whose file-size limit makes a write fail mid-run as a full disk does
# (EFBIG from write(), no filename on the error).  SIGXFSZ is ignored so the write returns an
# error instead of killing the process.
_LIMITED_CLI = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
from bb_friction_ros.cli import main
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
sys.exit(main(sys.argv[2:]))
"""
# Small enough that the outputs do not fit (prediction.csv of 2000 samples is ~300 kB),
# large enough for anything written before them.
FILE_SIZE_LIMIT_B = 48 * 1024


@pytest.fixture(scope="module")
def long_bag(tmp_path_factory):
    """A 2 s reversing recording at 1 kHz with a measured torque (2000 nut_state samples)."""
    from bb_friction_ros.bags import write_events
    from recordings import model_friction, short_recording
    bag = tmp_path_factory.mktemp("disk") / "bag"
    write_events(bag, short_recording(state_rate_hz=1000.0, segment_s=1.0,
                                      measured=model_friction))
    return bag


@pytest.mark.parametrize("args, limit", [
    (["replay", "BAG", "--no-progress"], FILE_SIZE_LIMIT_B),
    (["replay", "BAG", "--no-progress", "--no-bag"], FILE_SIZE_LIMIT_B),
    (["discrepancy", "BAG", "--no-progress", "--no-physical"], FILE_SIZE_LIMIT_B),  # PNGs
    (["discrepancy", "BAG", "--no-progress", "--no-plots", "--no-physical"], 8 * 1024)],
    ids=["replay", "replay-no-bag", "discrepancy", "discrepancy-no-plots"])
def test_disk_full_mid_run_exits_2_naming_the_output_directory(args, limit, long_bag,
                                                               tmp_path):
    """A write that really fails (file-size limit) is exit 2 naming --out, no traceback."""
    import subprocess
    import sys
    out = tmp_path / "out"
    argv = [str(long_bag) if a == "BAG" else a for a in args] + ["--out", str(out)]
    run = subprocess.run([sys.executable, "-c", _LIMITED_CLI, str(limit)] + argv,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    # EFBIG's text: the limit really bit (a partly written file may be removed by an
    # atomic writer, so the file sizes prove nothing)
    assert str(out) in run.stderr and "File too large" in run.stderr


def test_the_same_run_without_the_limit_succeeds(long_bag, tmp_path):
    """Control for the test above: with no file-size limit the same replay exits 0."""
    import subprocess
    import sys
    import resource
    run = subprocess.run([sys.executable, "-c", _LIMITED_CLI, str(resource.RLIM_INFINITY),
                          "replay", str(long_bag), "--no-progress", "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr


def test_a_bug_in_a_cli_path_shows_a_traceback_and_exits_1(tmp_path, monkeypatch):
    """A ValueError that is not bad user input (a bug) is not turned into exit 2."""
    import subprocess
    import sys
    code = ("import sys, numpy as np\n"
            "from bb_friction_ros import replay\n"
            "def buggy(*a, **k):\n"
            "    np.zeros(3) + np.zeros(4)   # a numpy ValueError: a bug, not bad input\n"
            "replay.replay = buggy\n"
            "from bb_friction_ros.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    bag = tmp_path / "bag"
    bag.mkdir()
    run = subprocess.run([sys.executable, "-c", code, "replay", str(bag), "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    assert "Traceback" in run.stderr and "operands could not be broadcast" in run.stderr


def test_every_input_error_is_a_bbfriction_error():
    """The CLI's exit-2 rule covers every input error class of the package (one base)."""
    from bb_friction_ros.bags import BagError
    from bb_friction_ros.cli import OutputPathError
    from bb_friction_ros.config import BBFrictionError, ConfigError
    from bb_friction_ros.discrepancy.data import InputProblem
    from bb_friction_ros.discrepancy.workflow import InsufficientData
    from bb_friction_ros.replay import NothingAccepted
    from bb_friction_ros.runner import InputError
    for cls in (BagError, OutputPathError, ConfigError, InputProblem, InsufficientData,
                NothingAccepted, InputError):
        assert issubclass(cls, BBFrictionError), cls
    assert issubclass(BBFrictionError, ValueError)   # callers catching ValueError still do


def test_an_input_error_in_a_cli_path_exits_2_with_its_message(tmp_path, monkeypatch, capsys):
    """Any BBFrictionError raised under a command (not only ConfigError) is exit 2."""
    from bb_friction_ros.ball_screw import simulation
    from bb_friction_ros.config import BBFrictionError

    def bad_input(*args, **kwargs):
        raise BBFrictionError("x.csv: column t_s never advances")
    monkeypatch.setattr(simulation, "write_outputs", bad_input)
    assert main(["screw-sim", "--steps", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "x.csv: column t_s never advances" in err and "Traceback" not in err


def test_ros_log_dir_that_cannot_be_made_is_named_with_the_fix(tmp_path):
    from bb_friction_ros.interface import ros_log_dir, ros_log_dir_problem
    assert "set ROS_LOG_DIR" in ros_log_dir_problem({"HOME": "/dev/null"})
    assert ros_log_dir({"ROS_HOME": str(tmp_path)}) == str(tmp_path / "log")
    assert ros_log_dir_problem({"ROS_LOG_DIR": str(tmp_path / "new" / "log")}) is None


def test_node_with_an_unwritable_home_names_ros_log_dir():
    """rclpy.init's RCLError said neither where it wanted to log nor how to move it."""
    import os
    import subprocess
    import sys
    env = dict(os.environ, HOME="/dev/null")
    env.pop("ROS_LOG_DIR", None)
    env.pop("ROS_HOME", None)
    run = subprocess.run([sys.executable, "-m", "bb_friction_ros.node_entry"], env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert "ROS_LOG_DIR" in run.stderr and "Traceback" not in run.stderr


def test_ctrl_c_during_the_demo_exits_130_without_a_traceback(tmp_path):
    import signal
    import subprocess
    import sys
    proc = subprocess.Popen([sys.executable, "-m", "bb_friction_ros.cli", "demo", "--out",
                             str(tmp_path / "demo")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:            # the node is playing the recording
            if "playing it through" in line:
                break
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err and "terminate" not in err
