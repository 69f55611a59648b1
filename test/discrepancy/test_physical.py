"""
Physical candidates (issue 21): model runs at trial values, and the selection with them.

The recordings are made by the project's own model (the replay path) with a physical
parameter that the config given to the workflow does not have, plus noise.
"""

import numpy as np
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.discrepancy import physical as ph
from bb_friction_ros.discrepancy import regimes
from bb_friction_ros.discrepancy import synthetic as sy
from bb_friction_ros.discrepancy.data import inputs_of, predict_events
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.workflow import adequacy, usable, with_acceleration
from bb_friction_ros.empirical_terms import TermSet
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


def test_bad_physical_setting_names_the_key():
    with pytest.raises(ConfigError, match=r"discrepancy.physical.theta_max_deg"):
        ph.load_physical_settings({"theta_max_deg": 0.0})
