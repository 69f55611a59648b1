"""
The command on real inputs: rosbag2 in both storage formats, CSV, and the augmented config.

These run the model over the recording (the replay path), so they share one recording with
two hidden effects and keep their number small.
"""

import argparse
import json

import numpy as np
import pytest
import yaml

from bb_friction_ros.bags import with_measurement, write_events
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.config import ConfigError
from bb_friction_ros.discrepancy.cli import add_discrepancy_parser
from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.empirical_terms import load_terms, TermSet
from bb_friction_ros.replay import replay

HIDDEN = ("viscous_drag", "lead_error")
NOISE_NM = 0.004


def run_cli(argv):
    """Run ``bb-friction discrepancy ...`` as the main CLI does (ConfigError: status 2)."""
    parser = argparse.ArgumentParser(prog="bb-friction")
    add_discrepancy_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["discrepancy"] + [str(a) for a in argv])
    try:
        return args.func(args)
    except ConfigError as exc:
        print(f"bb-friction: config error: {exc}")
        return 2


@pytest.fixture(scope="module")
def recording(base, tmp_path_factory):
    """Bags (sqlite3 and mcap) of the reference trajectory with two hidden effects."""
    rng = np.random.default_rng(42)
    hidden = TermSet([draw_effect(n, rng) for n in HIDDEN])
    rec, noise = synthesize(base, hidden, NOISE_NM, rng)
    events = with_measurement(base.events, rec.torque_meas_nm)
    root = tmp_path_factory.mktemp("bags")
    bags = {}
    for storage in ("sqlite3", "mcap"):
        bags[storage] = root / storage
        write_events(bags[storage], events, storage=storage)
    hold = np.arange(len(rec)) >= int(np.floor(0.7 * len(rec)))
    return {"bags": bags, "hidden": hidden, "rec": rec, "events": events,
            "noise_rms": float(np.sqrt(np.mean(noise[hold] ** 2)))}


def check_found(summary, noise_rms):
    assert summary["verdict"] == "found"
    assert {e["name"] for e in summary["effects"]} == set(HIDDEN)
    reducible = summary["rmse_before_nm"] - noise_rms
    assert summary["rmse_after_nm"] <= summary["rmse_before_nm"] - 0.8 * reducible
    assert summary["regions"]


@pytest.fixture(scope="module")
def sqlite_out(recording, tmp_path_factory):
    out = tmp_path_factory.mktemp("sqlite_out")
    assert run_cli([recording["bags"]["sqlite3"], "--out", out, "--no-progress"]) == 0
    return out


def test_sqlite_bag_report_summary_and_augmented_config(recording, sqlite_out):
    summary = json.loads((sqlite_out / "summary.json").read_text())
    check_found(summary, recording["noise_rms"])
    assert summary["input"]["prediction_source"] == "model (replay path)"
    raw = yaml.safe_load((sqlite_out / "augmented.yaml").read_text())
    assert load_terms(raw["empirical_terms"]).names == tuple(
        e["name"] for e in summary["effects"])
    load_ball_screw(sqlite_out / "augmented.yaml")           # the base config part is valid
    report = (sqlite_out / "report.md").read_text()
    assert "Verdict: found" in report and "Held-out part, per regime" in report
    for png in ("residual_where.png", "heldout_before_after.png", "time_series.png"):
        assert (sqlite_out / png).stat().st_size > 10_000


def test_mcap_bag(recording, tmp_path, capsys):
    out = tmp_path / "out"
    assert run_cli(["--no-physical",
                    recording["bags"]["mcap"], "--out", out, "--no-progress", "--no-plots",
                    "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    check_found(summary, recording["noise_rms"])
    assert not (out / "time_series.png").exists()


def test_csv_with_and_without_a_prediction(recording, tmp_path):
    rep = replay(recording["bags"]["sqlite3"], tmp_path / "replay", progress=False)
    assert rep["samples"] == len(recording["rec"])
    csv_path = tmp_path / "replay" / "prediction.csv"
    assert run_cli(["--no-physical", csv_path, "--out", tmp_path / "reuse", "--no-plots"]) == 0
    reused = json.loads((tmp_path / "reuse" / "summary.json").read_text())
    check_found(reused, recording["noise_rms"])
    assert "reused" in reused["input"]["prediction_source"]
    # the replay's own columns, minus the prediction: the model is run on the CSV inputs
    rows = np.genfromtxt(csv_path, delimiter=",", names=True)
    bare = tmp_path / "bare.csv"
    cols = ["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_meas_nm"]
    np.savetxt(bare, np.column_stack([rows[c] for c in cols]), delimiter=",",
               header=",".join(cols), comments="", fmt="%.17g")
    assert run_cli(["--no-physical", bare, "--out", tmp_path / "recomputed", "--no-plots"]) == 0
    recomputed = json.loads((tmp_path / "recomputed" / "summary.json").read_text())
    assert recomputed["input"]["prediction_source"].startswith("model")
    assert recomputed["rmse_before_nm"] == pytest.approx(reused["rmse_before_nm"], rel=1e-6)
    assert [e["name"] for e in recomputed["effects"]] == [e["name"] for e in reused["effects"]]


def test_augmented_config_closes_the_gap_in_replay(recording, sqlite_out, tmp_path):
    """Replay with augmented.yaml adds the terms; the workflow then finds nothing left."""
    augmented = sqlite_out / "augmented.yaml"
    bag = recording["bags"]["sqlite3"]
    before = json.loads((sqlite_out / "summary.json").read_text())
    rep = replay(bag, tmp_path / "replay", config=augmented, progress=False)
    assert rep["rmse_nm"] < 1.3 * recording["noise_rms"] < before["rmse_before_nm"]
    rows = np.genfromtxt(tmp_path / "replay" / "prediction.csv", delimiter=",", names=True)
    terms = load_terms(yaml.safe_load(augmented.read_text())["empirical_terms"])
    expected = terms.torque_nm(rows["t_s"] - rows["t_s"][0], rows["nut_angle_rad"],
                               rows["nut_velocity_rad_s"], rows["axial_load_n"])
    assert np.allclose(rows["torque_empirical_nm"], expected, rtol=0, atol=1e-12)
    assert run_cli(["--no-physical",
                    bag, "--config", augmented, "--out", tmp_path / "again", "--no-plots",
                    "--no-progress"]) == 0
    again = json.loads((tmp_path / "again" / "summary.json").read_text())
    assert again["verdict"] == "none"
    kept = yaml.safe_load((tmp_path / "again" / "augmented.yaml").read_text())
    assert kept["empirical_terms"] == yaml.safe_load(augmented.read_text())["empirical_terms"]


def test_too_short_bag_exits_2_with_what_is_missing(recording, tmp_path, capsys):
    head = recording["events"][:150]
    write_events(tmp_path / "short", head)
    assert run_cli(["--no-physical",
                    tmp_path / "short", "--out", tmp_path / "out", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "cannot tell" in err and "too short" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["verdict"] == "none" and summary["missing"]
    assert "too short" in (tmp_path / "out" / "report.md").read_text()


def test_bag_without_measured_torque_and_missing_input(recording, tmp_path, capsys):
    events = [e for e in recording["events"] if e.kind != "measured_torque"]
    write_events(tmp_path / "nomeas", events)
    assert run_cli(["--no-physical", tmp_path / "nomeas", "--out", tmp_path / "o"]) == 2
    assert "no measured torque" in capsys.readouterr().err
    assert run_cli(["--no-physical", tmp_path / "nope", "--out", tmp_path / "o"]) == 2
    assert "no such bag or CSV" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,nut_angle_rad\n0,0\n")
    assert run_cli(["--no-physical", bad, "--out", tmp_path / "o"]) == 2
    assert "lacks column(s) nut_velocity_rad_s" in capsys.readouterr().err


def test_bad_settings_file_names_the_key(recording, tmp_path, capsys):
    settings = tmp_path / "s.yaml"
    settings.write_text("discrepancy:\n  max_terms: 0\n")
    csv_path = tmp_path / "x.csv"
    csv_path.write_text("t_s,nut_angle_rad,nut_velocity_rad_s,axial_load_n,torque_meas_nm\n")
    assert run_cli(["--no-physical",
                    csv_path, "--out", tmp_path / "o", "--settings", settings]) == 2
    assert "discrepancy.max_terms" in capsys.readouterr().out
