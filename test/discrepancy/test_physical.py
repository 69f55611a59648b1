"""
Physical candidates (issue 21): model runs at trial values, and the selection with them.

The recordings are made by the project's own model (the replay path) with a physical
parameter that the config given to the workflow does not have, plus noise.
"""

import dataclasses
import math

import numpy as np
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.discrepancy import physical as ph
from bb_friction_ros.discrepancy import regimes
from bb_friction_ros.discrepancy import synthetic as sy
from bb_friction_ros.discrepancy.data import csv_events, inputs_of, predict_events
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.synthetic import draw_effect
from bb_friction_ros.discrepancy.workflow import (adequacy, analyse, run_discrepancy, usable,
                                                  with_acceleration)
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.node_parameters import NodeParameters

MODEL_RATE_HZ = 50.0
RUNNER = ph.runner_args(NodeParameters(model_rate_hz=MODEL_RATE_HZ))
# Issue 21's targets for a hidden parameter
THETA_TOLERANCE_DEG = 0.3
MU_RELATIVE_TOLERANCE = 0.05


@pytest.fixture(scope="module")
def cache(request, tmp_path_factory):
    try:
        return request.config.cache.mkdir("bb_friction_physical")
    except AttributeError:
        return tmp_path_factory.mktemp("physical")


def case(cache, hidden, terms=TermSet(), noise_nm=0.004, seed=1):
    rng = np.random.default_rng(seed)
    return sy.physical_case(sy.physical_trajectory(), hidden, terms, noise_nm, rng, cache,
                            MODEL_RATE_HZ)


def test_trial_runs_are_the_replay_path(cache):
    """The base run and a run at a trial value equal the replay path's prediction exactly."""
    hidden = {"errors": {"theta_amplitude_deg": 2.5}}
    rec, cfg, _ = case(cache, hidden)
    trials = ph.TrialRunner(rec, cfg, RUNNER)
    # the base run is the recording's own prediction (the replay path at the given config)
    assert np.array_equal(trials.base.total_nm, rec.torque_pred_nm)
    # step-only runs: at the config's own value, and at the hidden one, whose replay-path
    # prediction is the recording's measured torque without noise
    kind = ph.PHYSICAL["contact_angle_deviation"]
    same, hid = trials.run([(kind, 0.0), (kind, 2.5)])
    assert np.array_equal(same.total_nm, trials.base.total_nm)
    hidden_cfg = sy.model_config(cache, sy._deep_merge(sy.PHYSICAL_BASE_OVERRIDES, hidden))
    base = sy.baseline(sy.physical_trajectory(), hidden_cfg, MODEL_RATE_HZ, cache)
    preds, _ = predict_events(base.events, hidden_cfg,
                              NodeParameters(model_rate_hz=MODEL_RATE_HZ))
    assert np.array_equal(hid.total_nm, preds.column("torque_total_nm"))
    assert trials.runs == 3
    # B2B friction appears with the contact-angle deviation, and only with it
    assert np.all(trials.base.b2b_nm == 0.0) and np.mean(np.abs(hid.b2b_nm)) > 1e-3
    # the schedule: fewer steps than samples is allowed, never more
    assert len(trials.schedule.step_inputs) <= len(rec)


def analyse_physical(rec, cfg, settings=DiscrepancySettings()):
    rec_all, spec = with_acceleration(rec, settings)
    ok, _ = usable(rec_all)
    recu = rec_all.take(ok)
    n = len(recu)
    fit_mask = np.arange(n) < int(np.floor((1.0 - settings.holdout_fraction) * n))
    x_fit = inputs_of(recu, fit_mask)
    _, untested = adequacy(x_fit, n, settings)
    r = recu.torque_meas_nm - recu.torque_pred_nm
    noise = regimes.noise_model(r, settings.noise_max_lag, settings.noise_plateau_ratio,
                                recu.nut_velocity_rad_s, recu.t_s)
    return ph.select_with_physics(ph.PhysicsContext(cfg, RUNNER), rec_all, ok,
                                  fit_mask, r, x_fit, settings, tuple(untested),
                                  {"inertia": spec}, noise.tau)


def test_hidden_theta_amplitude_is_named(cache):
    """The issue's first case: theta 2.5 deg hidden (here 2.2, off the bracket's grid)."""
    rec, cfg, _ = case(cache, {"errors": {"theta_amplitude_deg": 2.2}}, seed=3)
    terms, trace, ctx, search = analyse_physical(rec, cfg)
    assert search.chosen is not None and search.chosen.kind.name == "contact_angle_deviation"
    assert abs(search.chosen.value - 2.2) <= THETA_TOLERANCE_DEG
    lo, hi = search.chosen.interval_95
    assert lo < search.chosen.value < hi
    assert len(terms) == 0, terms.names
    # the cost is visible: the base run plus one per trial
    assert search.runs == 1 + len(search.trials)
    effect = search.chosen.effect()
    assert effect["kind"] == "physical" and effect["units"] == {"theta_amplitude_deg": "deg"}


def test_hidden_theta_at_the_b2b_onset_is_named(cache):
    """
    theta 1.8 deg: at the B2B contact's onset the change is below the noise's std.

    On this drive the torque changes by 0.23 mN m rms at 1.5 deg and 3.9 at 2.0 deg: the
    RSS is flat over the bracket's 0 and 1.25 deg and steep at 2.5 deg, so a parabola through
    it never reached the value (hidden 1.67 and 1.82 deg were missed although the penalised
    BIC at the truth beat "none" by 46 and 166); the scale of the change does.
    """
    rec, cfg, noise = case(cache, {"errors": {"theta_amplitude_deg": 1.8}}, noise_nm=0.004,
                           seed=2)
    change = rec.torque_meas_nm - noise - rec.torque_pred_nm
    assert np.sqrt(np.mean(change ** 2)) < np.std(noise)      # below the noise, as claimed
    terms, trace, ctx, search = analyse_physical(rec, cfg)
    assert search.chosen is not None and search.chosen.kind.name == "contact_angle_deviation"
    assert abs(search.chosen.value - 1.8) <= THETA_TOLERANCE_DEG
    assert len(terms) == 0, terms.names


# A shorter drive for the end-to-end tests: every analysis makes ~17 model runs over it.
SHORT_S = 12.0


def short_case(cache, hidden, terms=TermSet(), noise_nm=0.004, seed=1):
    rng = np.random.default_rng(seed)
    return sy.physical_case(sy.physical_trajectory(SHORT_S), hidden, terms, noise_nm, rng,
                            cache, MODEL_RATE_HZ)


def write_csv(path, rec):
    cols = np.column_stack([rec.t_s, rec.nut_angle_rad, rec.nut_velocity_rad_s,
                            rec.axial_load_n, rec.torque_meas_nm, rec.torque_pred_nm])
    np.savetxt(path, cols, delimiter=",", fmt="%.17g", comments="",
               header="t_s,nut_angle_rad,nut_velocity_rad_s,axial_load_n,torque_meas_nm,"
                      "torque_pred_nm")
    return path


def test_hidden_theta_end_to_end_contract(cache, tmp_path):
    """summary.json effects, augmented.yaml's ball_screw section, report.md and its figure."""
    hidden = {"errors": {"theta_amplitude_deg": 2.6}}
    rec, cfg, noise = short_case(cache, hidden, seed=5)
    settings = dataclasses.replace(DiscrepancySettings(),
                                   physical=ph.PhysicalSettings(enabled=True))
    replay = NodeParameters(model_rate_hz=MODEL_RATE_HZ)
    status, summary = run_discrepancy(write_csv(tmp_path / "rec.csv", rec), tmp_path / "out",
                                      config=cfg, settings=settings, replay_settings=replay)
    assert status == 0 and summary["verdict"] == "found"
    effect = summary["effects"][0]
    assert effect["name"] == "contact_angle_deviation" and effect["kind"] == "physical"
    value = effect["params"]["theta_amplitude_deg"]
    assert abs(value - 2.6) <= THETA_TOLERANCE_DEG
    assert effect["units"] == {"theta_amplitude_deg": "deg"}
    lo, hi = effect["interval_95"]["theta_amplitude_deg"]
    assert lo < value < hi
    assert all(e["kind"] == "empirical" for e in summary["effects"][1:])
    p = summary["physical"]
    assert p["model_runs"] == 1 + len(p["trials"]) and p["model_run_wall_s"] > 0
    # augmented.yaml carries the value: the runner (replay, node) runs the calibrated physics
    augmented = tmp_path / "out" / "augmented.yaml"
    cfg_aug, _ = load_model_file(augmented)
    assert cfg_aug.errors.theta_amplitude_rad == pytest.approx(math.radians(value), rel=1e-12)
    cols = {"t_s": rec.t_s, "nut_angle_rad": rec.nut_angle_rad,
            "nut_velocity_rad_s": rec.nut_velocity_rad_s, "axial_load_n": rec.axial_load_n}
    preds, _ = predict_events(csv_events(cols, replay.nut_joint), augmented, replay)
    truth = rec.torque_meas_nm - noise
    gap_before = np.sqrt(np.mean((rec.torque_pred_nm - truth) ** 2))
    gap_after = np.sqrt(np.mean((preds.column("torque_total_nm") - truth) ** 2))
    assert gap_after < 0.2 * gap_before, (gap_before, gap_after)
    report = (tmp_path / "out" / "report.md").read_text()
    assert "Ball-to-ball contact from a contact-angle deviation of about" in report
    assert "B2B friction adds" in report and "model runs" in report
    assert (tmp_path / "out" / ph.B2B_FIGURE).is_file()


def test_hidden_mu_with_an_empirical_effect_on_top(cache):
    """mu 0.13 where the config says 0.1, plus a seal drag: both named, mu within 5 %."""
    rng = np.random.default_rng(11)
    seal = TermSet([draw_effect("seal_drag", rng)])
    rec, cfg, _ = short_case(cache, {"material": {"friction_coefficient": 0.13}}, seal,
                             seed=11)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    assert abs(choice.value / 0.13 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert a.terms.names == ("seal_drag",)
    # identifiability said out loud: mu against its near-twin load_dependent
    twins = [x for x in a.ambiguities if x["pair"] == ["friction_coefficient",
                                                       "load_dependent"]]
    assert twins and "load_dependent" in twins[0]["statement"]


def test_empirical_effects_only_name_no_physics(cache):
    """The config right, a seal and a viscous drag added: no physical parameter is named."""
    rng = np.random.default_rng(4)
    terms = TermSet([draw_effect("seal_drag", rng), draw_effect("viscous_drag", rng)])
    rec, cfg, _ = short_case(cache, {}, terms, seed=4)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    assert ph.chosen(a.physical) is None
    assert set(a.terms.names) == {"seal_drag", "viscous_drag"}


def test_bad_physical_setting_names_the_key():
    with pytest.raises(ConfigError, match=r"discrepancy.physical.theta_max_deg"):
        ph.load_physical_settings({"theta_max_deg": 0.0})
