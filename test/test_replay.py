"""Bags in both storage formats and the replay command."""

import csv
import json

import pytest

from bb_friction_ros.bags import Event, read_events, write_events
from bb_friction_ros.cli import main
from recordings import short_recording


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bag_round_trip_keeps_log_order(tmp_path, storage):
    """Both storage formats give back the events in log order, backwards stamps included."""
    events = [Event("axial_load", 0.0, value=1500.0),
              Event("nut_state", 0.01, ("nut_joint",), (0.1,), (6.0,)),
              Event("measured_torque", 0.01, value=0.2),
              Event("nut_state", 0.005, ("nut_joint",), (0.2,), (6.0,))]
    write_events(tmp_path / "bag", events, storage=storage, log_times_s=[0, 1, 2, 3])
    back, counts = read_events(tmp_path / "bag")
    assert back == events
    assert counts == {"/nut_state": 2, "/axial_load": 1, "/measured_torque": 1}


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_replay_writes_prediction_summary_and_plots(tmp_path, capsys, storage):
    events = short_recording()
    write_events(tmp_path / "bag", events, storage=storage)
    code = main(["replay", str(tmp_path / "bag"), "--out", str(tmp_path / "out"),
                 "--no-progress"])
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "out" / "prediction.csv")))
    n_states = sum(e.kind == "nut_state" for e in events)
    assert len(rows) == n_states
    assert list(rows[0]) == ["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                             "torque_pred_nm", "torque_b2b_nm", "torque_meas_nm"]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["messages"]["/nut_state"] == n_states
    assert summary["rejected"] == {} and summary["nonconverged_steps"] == 0
    assert summary["rmse_nm"] > 0 and summary["speed_vs_realtime"] > 0
    assert (tmp_path / "out" / "replay_torque_and_groups.png").stat().st_size > 10_000
    # friction opposes motion: the predicted torque has the sign of the nut speed
    for r in rows:
        if abs(float(r["nut_velocity_rad_s"])) > 1.0:
            assert float(r["torque_pred_nm"]) * float(r["nut_velocity_rad_s"]) > 0


def test_replay_counts_rejected_inputs(tmp_path):
    """Bad messages in a bag are counted with their reason, and the rest is replayed."""
    events = [Event("nut_state", 0.0, ("nut_joint",), (0.0,), (6.0,)),       # before a load
              Event("axial_load", 0.0, value=1500.0),
              Event("nut_state", 0.01, ("nut_joint",), (0.06,), (6.0,)),
              Event("nut_state", 0.02, ("wrong",), (0.12,), (6.0,)),
              Event("axial_load", 0.02, value=float("nan")),
              Event("nut_state", 0.03, ("nut_joint",), (float("nan"),), (6.0,)),
              Event("nut_state", 0.04, ("nut_joint",), (0.24,), (6.0,))]
    write_events(tmp_path / "bag", events)
    from bb_friction_ros.replay import replay
    summary = replay(tmp_path / "bag", tmp_path / "out", progress=False)
    assert summary["samples"] == 2
    assert summary["rejected"] == {"no_load_yet": 1, "wrong_joint": 1, "non_finite": 2}


def test_replay_of_a_missing_bag_is_a_clear_error(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "no such bag" in capsys.readouterr().err
