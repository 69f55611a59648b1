"""Reading recordings: damaged bags are clear errors naming the file (issue 13 finding 17)."""

import pytest

from bb_friction_ros.bags import BagError, Event, measured_torque_at, read_events, \
    write_events
from bb_friction_ros.cli import main


def _bag(tmp_path, storage, n=400):
    events = [Event("axial_load", 0.0, value=1500.0)] + [
        Event("nut_state", 0.001 * (k + 1), ("nut_joint",), (0.006 * k,), (6.0,))
        for k in range(n)]
    write_events(tmp_path / "bag", events, storage=storage)
    (data,) = [p for p in (tmp_path / "bag").iterdir() if p.name != "metadata.yaml"]
    return tmp_path / "bag", data


def _truncate(path):
    raw = path.read_bytes()
    path.write_bytes(raw[:len(raw) // 2])


def _corrupt(path):
    raw = bytearray(path.read_bytes())
    for k in range(len(raw) // 3, len(raw) // 3 + 64):
        raw[k] ^= 0x5A
    path.write_bytes(bytes(raw))


DAMAGE = {
    "truncated": _truncate,
    "corrupt bytes": _corrupt,
}
METADATA = {
    "truncated metadata.yaml": lambda p: p.write_text(p.read_text()[:120]),
    "garbage metadata.yaml": lambda p: p.write_bytes(b"\x00\xff{{[: not yaml ]]\x01"),
    "empty metadata.yaml": lambda p: p.write_text(""),
}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damaged_storage_file_is_exit_2_naming_it(tmp_path, capsys, storage, damage):
    bag, data = _bag(tmp_path, storage)
    DAMAGE[damage](data)
    code = main(["replay", str(bag), "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    if code == 0:
        # corrupt bytes may land in a float of a message: undetectable, and harmless to read
        assert damage == "corrupt bytes"
        return
    assert code == 2, err
    assert str(bag) in err and "Traceback" not in err
    assert "damaged" in err or "not a readable rosbag2" in err


@pytest.mark.parametrize("damage", sorted(METADATA))
def test_damaged_metadata_is_exit_2_naming_it(tmp_path, capsys, damage):
    bag, _ = _bag(tmp_path, "mcap", n=10)
    METADATA[damage](bag / "metadata.yaml")
    assert main(["replay", str(bag), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(bag / "metadata.yaml") in err and "damaged metadata" in err


def test_a_directory_without_metadata_is_not_a_bag(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(BagError, match="no metadata.yaml"):
        read_events(tmp_path / "bag")


def test_measured_torque_is_aligned_run_by_run():
    """Issue 13 finding 6: the same stamps in two passes keep their own measurements."""
    meas = [Event("measured_torque", t, value=v) for t, v in
            [(0.0, 1.0), (1.0, 2.0), (0.0, 10.0), (1.0, 20.0)]]
    got = measured_torque_at(meas, [0.0, 0.5, 1.0, 0.25, 0.5, 2.0])
    assert got[:5].tolist() == [1.0, 1.5, 2.0, 12.5, 15.0]
    assert got[5] != got[5]                      # after the pass's last measurement: NaN
    assert measured_torque_at([], [0.0]) is None
