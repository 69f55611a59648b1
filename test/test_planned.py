"""
bb-friction feedforward: friction along a planned trajectory, each row at its own time.
"""

import csv
import json

import numpy as np
import pytest
import yaml

from bb_friction_ros.bags import Event, write_events
from bb_friction_ros.cli import main
from bb_friction_ros.config import bundled_config
from bb_friction_ros.planned import planned_feedforward, PlannedSettings

LOAD_N = 1500.0


def _plan(n=600, rate_hz=1000.0, rest_s=0.05):
    """Rest, then a sine of nut velocity: out, reversal, back (1 rev/s peak)."""
    t = np.arange(n) / rate_hz
    w = np.where(t < rest_s, 0.0, 2 * np.pi * np.sin(2 * np.pi * (t - rest_s) / 0.5))
    phi = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) / rate_hz)))
    return t, phi, w, np.full(n, LOAD_N)


def _model(tmp_path, terms):
    doc = yaml.safe_load(open(bundled_config("ball_screw.yaml")))
    doc["empirical_terms"] = terms
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _csv(path, t, phi, w, load):
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n"])
        out.writerows(zip(t, phi, w, load))
    return path


@pytest.fixture(scope="module")
def plain():
    return planned_feedforward(*_plan(), bundled_config("ball_screw.yaml"))


def test_friction_has_the_planned_motions_sign_and_standstill_gets_zero(plain):
    t, _, w, _ = _plan()
    moving = w != 0.0
    assert np.all(plain.torque_ff_nm[moving] * w[moving] > 0.0)
    resting = ~moving & ~plain.breakaway
    assert np.all(plain.torque_ff_nm[resting] == 0.0)
    assert plain.converged.all()
    # the model's own total and its parts agree to its solver tolerance (2.6e-8 N m here)
    parts = plain.torque_b2g_nm + plain.torque_b2b_nm + plain.torque_empirical_nm
    assert parts == pytest.approx(plain.torque_ff_nm, abs=1e-7)


def test_breakaway_comes_before_a_planned_start_in_its_direction(plain):
    t, _, w, _ = _plan()
    first = int(np.argmax(w != 0.0))
    rows = np.flatnonzero(plain.breakaway)
    lead = PlannedSettings().breakaway_lead_s
    assert rows.size and rows.max() == first - 1
    assert np.all(t[first] - t[rows] <= lead + 1e-12)
    assert np.all(plain.torque_ff_nm[rows] * np.sign(w[first]) > 0.0)
    # about the model's friction an instant into the motion (no viscous part yet)
    assert plain.torque_ff_nm[rows[-1]] == pytest.approx(plain.torque_ff_nm[first], rel=0.05)


def test_each_rows_torque_belongs_to_its_own_time():
    """The value at row k is the same whether the plan ends at k or goes on: no hold, no delay."""
    config = bundled_config("ball_screw.yaml")
    t, phi, w, load = _plan(n=300)
    whole = planned_feedforward(t, phi, w, load, config)
    for k in (120, 181, 299):
        cut = planned_feedforward(t[:k + 1], phi[:k + 1], w[:k + 1], load[:k + 1], config)
        assert cut.torque_ff_nm[-1] == whole.torque_ff_nm[k]


def test_only_friction_terms_are_fed_forward(tmp_path, plain):
    """Inertia (the loop feeds J alpha itself), offset: left out; seal drag: in."""
    model = _model(tmp_path, [
        {"name": "inertia", "params": {"j_kg_m2": 0.01, "accel_cutoff_hz": 50.0,
                                       "max_gap_s": 0.05}},
        {"name": "offset", "params": {"torque_nm": 0.5}},
        {"name": "seal_drag", "params": {"torque_nm": 0.04}}])
    ff = planned_feedforward(*_plan(), model)
    t, _, w, _ = _plan()
    moving = w != 0.0
    assert ff.terms_in == ("seal_drag",) and ff.terms_out == ("inertia", "offset")
    assert ff.torque_ff_nm[moving] == pytest.approx(
        plain.torque_ff_nm[moving] + 0.04 * np.sign(w[moving]), abs=1e-12)


def test_pre_rolling_builds_up_from_zero_at_a_planned_reversal(tmp_path, plain):
    model = _model(tmp_path, [{"name": "pre_rolling",
                               "params": {"torque_nm": 0.25, "travel_rad": 0.01}}])
    ff = planned_feedforward(*_plan(), model)
    t, _, w, _ = _plan()
    moving = w != 0.0
    assert np.all(ff.torque_ff_nm[moving] * w[moving] >= 0.0)
    rev = int(np.flatnonzero((np.sign(w[1:]) != np.sign(w[:-1])) & (w[:-1] != 0.0))[0]) + 1
    after = np.abs(ff.torque_ff_nm[rev:rev + 60])
    assert after[0] < 0.2 * abs(plain.torque_ff_nm[rev + 1])
    assert after[-1] == pytest.approx(abs(plain.torque_ff_nm[rev + 59]), rel=0.02)
    assert ff.friction_cut > 0


def test_cli_writes_the_contract_files_and_a_bag_gives_the_same(tmp_path):
    t, phi, w, load = _plan(n=200)
    assert main(["feedforward", str(_csv(tmp_path / "plan.csv", t, phi, w, load)),
                 "--out", str(tmp_path / "a")]) == 0
    rows = list(csv.DictReader(open(tmp_path / "a" / "feedforward.csv")))
    assert len(rows) == t.size
    assert list(rows[0])[:5] == ["t_s", "torque_ff_nm", "torque_b2g_nm", "torque_b2b_nm",
                                 "torque_empirical_nm"]
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["complete"] is True and s["rows"] == t.size
    events = []
    for k in range(t.size):
        events.append(Event("axial_load", float(t[k]), value=float(load[k])))
        events.append(Event("nut_state", float(t[k]), ("nut_joint",), (float(phi[k]),),
                            (float(w[k]),)))
    write_events(tmp_path / "bag", events)
    assert main(["feedforward", str(tmp_path / "bag"), "--out", str(tmp_path / "b")]) == 0
    again = list(csv.DictReader(open(tmp_path / "b" / "feedforward.csv")))
    assert [r["torque_ff_nm"] for r in again] == [r["torque_ff_nm"] for r in rows]


@pytest.mark.parametrize("edit, needle", [
    (lambda c: c.replace("axial_load_n", "load"), "lacks column(s) axial_load_n"),
    (lambda c: c.replace("\n0.002,", "\n0.0005,", 1), "t_s: row 2"),
    (lambda c: c.replace("\n0.003,", "\n0.003,nan,", 1).replace("nan,0.0", "nan", 1),
     "not finite"),
], ids=["missing_column", "time_not_increasing", "non_finite"])
def test_bad_plans_exit_2_naming_the_field(tmp_path, capsys, edit, needle):
    t, phi, w, load = _plan(n=20)
    path = _csv(tmp_path / "plan.csv", t, phi, w, load)
    path.write_text(edit(path.read_text()))
    assert main(["feedforward", str(path), "--out", str(tmp_path / "o")]) == 2
    assert needle in capsys.readouterr().err


def test_playback_gives_each_rows_torque_at_its_time_and_nothing_outside():
    from bb_friction_ros.feedforward import PlannedPlayback
    play = PlannedPlayback()
    assert play.torque_at_time(1.0) == 0.0 and play.status == "empty"
    play.set_plan([1.0, 1.001, 1.002], [0.0, 0.2, 0.3])
    assert play.torque_at_time(1.001) == 0.2 and play.status == "planned"
    assert play.torque_at_time(1.0015) == pytest.approx(0.25)
    assert play.torque_at_time(0.999) == 0.0 and play.status == "before"
    assert play.torque_at_time(1.003) == 0.0 and play.status == "after"
    # a new plan replaces the old one from its start on
    play.set_plan([1.0015, 1.0025], [-0.1, -0.2])
    assert play.torque_at_time(1.001) == 0.2 and play.torque_at_time(1.0025) == -0.2
    with pytest.raises(ValueError, match="times must increase"):
        play.set_plan([2.0, 2.0], [0.0, 0.0])
    assert play.torque_at_time(1.0025) == -0.2          # the old plan stays


def test_playback_of_the_cli_output_reproduces_every_row(tmp_path):
    from bb_friction_ros.feedforward import PlannedPlayback
    t, phi, w, load = _plan(n=150)
    assert main(["feedforward", str(_csv(tmp_path / "plan.csv", t, phi, w, load)),
                 "--out", str(tmp_path / "a")]) == 0
    rows = list(csv.DictReader(open(tmp_path / "a" / "feedforward.csv")))
    play = PlannedPlayback()
    play.set_plan([float(r["t_s"]) for r in rows], [float(r["torque_ff_nm"]) for r in rows])
    assert [play.torque_at_time(float(r["t_s"])) for r in rows] == \
        [float(r["torque_ff_nm"]) for r in rows]
