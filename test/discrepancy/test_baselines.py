"""
The model and the zero baseline: the model file of --baseline zero, and the two recordings.

- a --baseline zero augmented.yaml says physics: none and replays to the reported RMSE;
- --validate refuses recordings of different baselines; the summary states both;
- a reused prediction.csv with torque_empirical_nm needs the --config that made it;
- a model file with no ball-screw values is refused: test/test_model_file.py.
"""

import dataclasses
import json

import numpy as np
import pytest
import yaml

from bb_friction_ros.bags import with_measurement, write_events
from bb_friction_ros.empirical_terms import make_term, TermSet
from bb_friction_ros.replay import replay

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv


def _zero_baseline_bag(base, tmp_path):
    """A bag whose measured torque is the model's plus viscous and seal drag (the demo's)."""
    rng = np.random.default_rng(23)
    r = base.recording
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.03}),
                      make_term("viscous_drag", {"c_nm_s_per_rad": 0.004})])
    meas = r.torque_pred_nm + hidden.torque_nm(r.t_run_s, r.nut_angle_rad,
                                               r.nut_velocity_rad_s, r.axial_load_n)
    meas = meas + rng.normal(0.0, 0.005, len(r))
    bag = tmp_path / "bag"
    write_events(bag, with_measurement(base.events, meas), storage="sqlite3")
    return bag


def test_zero_baseline_model_file_replays_to_the_reported_rmse(base, tmp_path):
    """
    The augmented.yaml of --baseline zero holds the whole torque.

    Replayed on top of the ball-screw model it counted friction twice (RMSE 0.245 against the
    reported 0.021 N m); it now says ``physics: none`` and the runner predicts the terms alone.
    """
    bag = _zero_baseline_bag(base, tmp_path)
    out = tmp_path / "o"
    assert run_cli(["--no-physical", bag, "--baseline", "zero", "--out", out, "--no-progress",
                    "--no-plots"]) == 0
    s = json.loads((out / "summary.json").read_text())
    aug = out / "augmented.yaml"
    assert yaml.safe_load(aug.read_text())["physics"] == "none"
    rep = replay(bag, tmp_path / "rep", config=aug, progress=False)
    rows = np.genfromtxt(tmp_path / "rep" / "prediction.csv", delimiter=",", names=True)
    # terms alone: the total is exactly the empirical part
    assert np.array_equal(rows["torque_pred_nm"], rows["torque_empirical_nm"])
    hold = np.arange(rows.size) >= int(np.floor(0.7 * rows.size))
    e = rows["torque_meas_nm"] - rows["torque_pred_nm"]
    rmse_hold = float(np.sqrt(np.mean(e[hold] ** 2)))
    # the reported held-out RMSE (of the fit part's terms) and replay's, of the terms refitted
    # on all samples: the same to 10 %; double counting gave 4-12x
    assert rmse_hold == pytest.approx(s["rmse_after_nm"], rel=0.1)
    assert rep["samples"] == rows.size


def test_validate_refuses_mixed_baselines(pair, tmp_path, capsys):
    """A model-baseline fit validated on a zero-prediction CSV: refused, not compared."""
    fit, val, _ = pair
    a = write_csv(tmp_path / "fit.csv", fit)
    zero = dataclasses.replace(val, torque_pred_nm=np.zeros(len(val)))
    b = write_csv(tmp_path / "val0.csv", zero)
    assert run_cli(["--no-physical", a, "--validate", b, "--out", tmp_path / "o", "--no-progress",
                    "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "different baselines" in err and str(a) in err and str(b) in err
    # the same pair with --baseline zero is one baseline: accepted, and said per recording
    assert run_cli(["--no-physical", a, "--validate", b, "--out", tmp_path / "z", "--no-progress",
                    "--no-plots", "--baseline", "zero"]) == 0
    s = json.loads((tmp_path / "z" / "summary.json").read_text())
    assert s["input"]["baseline"] == "zero" and s["validation"]["baseline"] == "zero"
    c = write_csv(tmp_path / "val.csv", val)
    assert run_cli(["--no-physical", a, "--validate", c, "--out", tmp_path / "m", "--no-progress",
                    "--no-plots"]) == 0
    s = json.loads((tmp_path / "m" / "summary.json").read_text())
    assert s["input"]["baseline"] == "model" and s["validation"]["baseline"] == "model"


def test_reused_prediction_with_terms_needs_their_config(base, tmp_path, capsys):
    """
    Replay's prediction.csv of an augmented model, analysed with the bundled config, used
    to write augmented.yaml without the earlier terms (replay 11x worse).
    """
    bag = _zero_baseline_bag(base, tmp_path)
    first = tmp_path / "first"
    assert run_cli(["--no-physical", bag, "--out", first, "--no-progress", "--no-plots"]) == 0
    aug = first / "augmented.yaml"
    replay(bag, tmp_path / "rep", config=aug, progress=False)
    pred = tmp_path / "rep" / "prediction.csv"
    assert run_cli(["--no-physical", pred, "--out", tmp_path / "lost", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "torque_empirical_nm" in err and "--config" in err
    other = tmp_path / "other.yaml"
    raw = yaml.safe_load(aug.read_text())
    raw["empirical_terms"][0]["params"] = {
        k: 1.5 * v for k, v in raw["empirical_terms"][0]["params"].items()}
    other.write_text(yaml.safe_dump(raw))
    assert run_cli(["--no-physical",
                    pred, "--config", other, "--out", tmp_path / "wrong", "--no-plots"]) == 2
    assert "another model file" in capsys.readouterr().err
    assert run_cli(["--no-physical",
                    pred, "--config", aug, "--out", tmp_path / "kept", "--no-plots"]) == 0
    kept = yaml.safe_load((tmp_path / "kept" / "augmented.yaml").read_text())
    assert kept["empirical_terms"][:2] == yaml.safe_load(aug.read_text())["empirical_terms"]


def test_without_a_model_stribeck_and_pre_rolling_enter_only_with_the_coulomb_level():
    """
    Without a model of the drive a Stribeck excess or a pre-rolling build-up shapes
    seal_drag's Coulomb level and is tried only with it; with a model (the physics carries
    the Coulomb level) every subset is tried.
    """
    from bb_friction_ros.discrepancy.selection import admissible, Candidate, RIGID_BODY_TERMS

    def subset(*names):
        return tuple(Candidate(n, ()) for n in names)

    for shaper in ("stribeck", "pre_rolling"):
        assert not admissible(subset(shaper, "viscous_drag"), RIGID_BODY_TERMS)
        assert admissible(subset(shaper, "seal_drag"), RIGID_BODY_TERMS)
        assert admissible(subset(shaper, "viscous_drag"), ())
    assert admissible(subset("viscous_drag", "offset"), RIGID_BODY_TERMS)
