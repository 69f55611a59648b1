"""Issue 13 findings 21 and 22: bad --out paths and bad numeric flags, exit 2 by name."""

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
    """Finding 22: --grid 0/-3 and --speed 0/negative/NaN were tracebacks or half-runs."""
    with pytest.raises(SystemExit) as exc:
        main(argv + ["--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    assert f"argument {flag}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
