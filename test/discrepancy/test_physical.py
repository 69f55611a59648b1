"""
Physical candidates: model runs at trial values, and the selection with them.

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
# The targets set for a hidden parameter
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


def test_coarse_step_keeps_the_smooth_changes(cache):
    """
    The smooth candidates' search steps 4x coarser: their change must survive it, theta's not.

    A change of mu or of the preload scales or shifts every contact's force, smoothly in the
    nut angle; theta's B2B change is a sequence of contacts closing at ball configurations,
    which a coarser step places a step early or late.  The change at the coarse step (against
    a base run at the same step) is compared with the replay step's: within 3 % rms for mu
    and the preload (measured 0.5-1.4 %), more than 10 % off for theta (measured 25-35 %) -
    which is why theta is searched at the replay step.
    """
    rec, cfg, _ = case(cache, {})
    fine = ph.TrialRunner(rec, cfg, RUNNER)
    coarse = ph.TrialRunner(rec, cfg, RUNNER, coarse_factor=4)
    trials = [(ph.PHYSICAL["friction_coefficient"], 0.085),
              (ph.PHYSICAL["preload"], 2.5),
              (ph.PHYSICAL["contact_angle_deviation"], 2.5)]
    for (kind, v), f, c in zip(trials, fine.run(trials), coarse.run(trials)):
        assert c.coarse == kind.smooth and not f.coarse
        if not kind.smooth:
            # not coarse at all: the very same run
            assert np.array_equal(c.total_nm, f.total_nm)
            c = ph.TrialRunner(rec, cfg, ph.coarse_args(RUNNER, 4)).run([(kind, v)])[0]
        err = np.sqrt(np.mean((c.delta_nm - f.delta_nm) ** 2)) / \
            np.sqrt(np.mean(f.delta_nm ** 2))
        assert (err < 0.03) if kind.smooth else (err > 0.10), (kind.name, err)
    # the coarse base run is counted once, with the coarse runs
    assert coarse.coarse_runs == 1 + 2 and coarse.runs == 1 + 1 + 3


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
    """The first case asked for: theta 2.5 deg hidden (here 2.2, off the bracket's grid)."""
    rec, cfg, _ = case(cache, {"errors": {"theta_amplitude_deg": 2.2}}, seed=3)
    terms, trace, ctx, search = analyse_physical(rec, cfg)
    assert search.chosen is not None and search.chosen.kind.name == "contact_angle_deviation"
    assert abs(search.chosen.value - 2.2) <= THETA_TOLERANCE_DEG
    lo, hi = search.chosen.interval_95
    assert lo < search.chosen.value < hi
    assert len(terms) == 0, terms.names
    # the cost is visible: the base run, the coarse base run (the smooth candidates' search
    # steps coarser) and one per trial
    coarse = sum(t["coarse"] for t in search.trials)
    assert coarse > 0 and search.coarse_runs == coarse + 1
    assert search.runs == 2 + len(search.trials)
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


def analysed(cache, hidden, effects, seed):
    """The workflow with physical candidates on ``short_case``, ``effects`` drawn by ``seed``."""
    rng = np.random.default_rng(seed)
    terms = TermSet([draw_effect(name, rng) for name in effects])
    rec, cfg, _ = short_case(cache, hidden, terms, seed=seed)
    return analyse(rec, DiscrepancySettings(),
                   ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))


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
    # the base runs (the replay step's, and the coarse step's) and one per trial
    assert p["model_runs"] == 2 + len(p["trials"]) and p["model_run_wall_s"] > 0
    assert p["coarse_runs"] == 1 + sum(t["coarse"] for t in p["trials"])
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
    a = analysed(cache, {"material": {"friction_coefficient": 0.13}}, ["seal_drag"], 11)
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    assert abs(choice.value / 0.13 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert a.terms.names == ("seal_drag",)
    # identifiability said out loud: mu against its near-twin load_dependent
    twins = [x for x in a.ambiguities if x["pair"] == ["friction_coefficient",
                                                       "load_dependent"]]
    assert twins and "load_dependent" in twins[0]["statement"]


def test_mu_with_load_dependent_on_top_is_reported_as_two_readings(cache):
    """
    mu 0.075 and a hidden load_dependent: mu's change is nearly seal_drag + load_dependent.

    So mu 0.075 + load_dependent and mu ~0.09 + seal_drag fit nearly alike.  The search
    profiled mu without its twin and named mu 0.091 + seal_drag (22 % off) with a 95 %
    interval of 0.091-0.092 that left the truth out.  Now the twin's reading is followed
    too (its profile with load_dependent in place of seal_drag): mu 0.076 with
    load_dependent, within the threshold of the first, so the value is reported ambiguous
    and its interval covers both readings and the truth.
    """
    a = analysed(cache, {"material": {"friction_coefficient": 0.075}}, ["load_dependent"], 1)
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    readings = [x for x in a.ambiguities if "values" in x]
    assert len(readings) == 1
    values = readings[0]["values"]["friction_coefficient"]
    terms = readings[0]["terms"]
    # one reading with load_dependent, and it is the hidden value
    with_twin = [v for v, t in zip(values, terms) if "load_dependent" in t]
    assert with_twin and abs(with_twin[0] / 0.075 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert not readings[0]["separated"]
    lo, hi = choice.interval_95
    assert lo <= 0.075 <= hi and lo <= min(values) and max(values) <= hi
    # the twin's profile was followed with model runs of its own
    assert any(t.get("twin_held") == "load_dependent" for t in a.physical.trials)


def test_empirical_effects_only_name_no_physics(cache):
    """The config right, a seal and a viscous drag added: no physical parameter is named."""
    a = analysed(cache, {}, ["seal_drag", "viscous_drag"], 4)
    assert ph.chosen(a.physical) is None
    assert set(a.terms.names) == {"seal_drag", "viscous_drag"}


def test_bad_physical_setting_names_the_key():
    with pytest.raises(ConfigError, match=r"discrepancy.physical.theta_max_deg"):
        ph.load_physical_settings({"theta_max_deg": 0.0})


def _outcome(kind, terms, score):
    return ph.Outcome(None if kind is None else ph.PHYSICAL[kind], None,
                      type("Terms", (), {"names": tuple(terms)})(), [], None, score)


def test_tie_is_a_one_for_one_swap_with_the_twin_within_the_threshold():
    """_tie: the parameter takes its twin's place, no term "none" lacks, within bic_threshold."""
    s = DiscrepancySettings()
    none = _outcome(None, ["load_dependent", "seal_drag"], -1000.0)
    mu = "friction_coefficient"
    # within the threshold, in place of the twin, with none's other terms or fewer
    assert ph._tie(_outcome(mu, ["seal_drag"], -1000.0 + 0.5 * s.bic_threshold), none, s)
    assert ph._tie(_outcome(mu, [], -1000.0 + 0.9 * s.bic_threshold), none, s)
    # the data tell them apart: the twin better by the threshold or more
    assert not ph._tie(_outcome(mu, ["seal_drag"], -1000.0 + s.bic_threshold), none, s)
    # not one for one: a term "none" does not need, or the twin kept beside the parameter
    assert not ph._tie(_outcome(mu, ["stribeck"], -1001.0), none, s)
    assert not ph._tie(_outcome(mu, ["load_dependent"], -999.0), none, s)
    # "none" without the twin: nothing to tie with (the preload's twin is seal_drag)
    assert not ph._tie(_outcome(mu, [], -999.0), _outcome(None, ["seal_drag"], -1000.0), s)
    assert ph._tie(_outcome("preload", [], -999.0), _outcome(None, ["seal_drag"], -1000.0), s)


def test_prefer_model_parameter_on_tie_is_a_validated_setting():
    assert ph.PhysicalSettings().prefer_model_parameter_on_tie is True
    assert ph.load_physical_settings({"prefer_model_parameter_on_tie": False}) \
        .prefer_model_parameter_on_tie is False
    with pytest.raises(ConfigError, match=r"discrepancy.physical.prefer_model_parameter_on_tie"):
        ph.load_physical_settings({"prefer_model_parameter_on_tie": 1})


def test_mu_on_a_tie_with_load_dependent_is_kept_as_the_model_parameter(cache):
    """
    mu 0.097 (3 % off): its change and load_dependent's column are one column here.

    Without the tie rule the empirical twin, 0.25 better in penalised BIC (a noise draw: the
    threshold of an effect is 10), is named, and mu only reported as ambiguous with it.  With
    it (the default) mu, the model's own parameter, is kept, within 5 %, said to be chosen
    on a tie, and the pair is still reported as one ambiguous effect.
    """
    rec, cfg, _ = short_case(cache, {"material": {"friction_coefficient": 0.097}},
                             noise_nm=0.006, seed=1)

    def run(prefer):
        return analyse(rec, DiscrepancySettings(), ph.PhysicsContext(
            cfg, RUNNER, ph.PhysicalSettings(enabled=True,
                                             prefer_model_parameter_on_tie=prefer)))

    off = run(False)
    assert ph.chosen(off.physical) is None and off.terms.names == ("load_dependent",)
    pair = [x for x in off.ambiguities if x["pair"] == ["load_dependent",
                                                        "friction_coefficient"]]
    assert pair and not pair[0]["separated"] and 0.0 < pair[0]["bic_difference"] < 10.0
    on = run(True)
    choice = ph.chosen(on.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    assert abs(choice.value / 0.097 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert on.terms.names == () and on.physical.tie
    assert ph.summary(on.physical)["chosen_on_tie"] is True
    pair = [x for x in on.ambiguities if x["pair"] == ["friction_coefficient",
                                                       "load_dependent"]]
    assert pair and not pair[0]["separated"] and "on the tie" in pair[0]["statement"]
    assert any("ties with load_dependent" in n for n in on.physical.notes)


def test_a_separable_empirical_load_dependent_is_not_read_as_mu(cache):
    """
    The config right and a load_dependent of 25 % of the model's friction (2 mN m noise):
    its column has no offset, mu's change has (the model torque is affine in the load, not
    proportional), and the data tell them apart by far more than bic_threshold; the tie rule
    does not apply and no physical parameter is named.
    """
    terms = TermSet([sy.make_term("load_dependent", {"k_nm_per_n": 4e-5})])
    rec, cfg, _ = short_case(cache, {}, terms, noise_nm=0.002, seed=3)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    assert ph.chosen(a.physical) is None and a.terms.names == ("load_dependent",)


def test_unseen_on_hold_compares_the_held_out_evidence_with_a_parameters_price():
    """A change the held-out part holds less evidence of than a parameter's price is unseen."""
    s = DiscrepancySettings()
    noise = type("Noise", (), {"std_nm": 0.004, "tau": 1.0})()
    n_fit, n_hold = 700, 300
    price = math.log(n_fit) + s.bic_threshold

    def search():
        out = ph.PhysicalSearch()
        out.chosen = ph.PhysicalChoice(ph.PHYSICAL["contact_angle_deviation"], 2.0, 0.0,
                                       (1.9, 2.1), None, None)
        return out

    # |d|^2 / sigma^2 just above, then just below the price
    for ratio, unseen in ((1.05, False), (0.95, True)):
        d = np.full(n_hold, 0.004 * math.sqrt(ratio * price / n_hold))
        got = search()
        assert ph.unseen_on_hold(got, d, noise, n_fit, s) is unseen
        assert got.heldout_judged is not unseen
        assert bool(got.notes) is unseen
    assert not ph.unseen_on_hold(ph.PhysicalSearch(), np.zeros(n_hold), noise, n_fit, s)


def test_theta_the_held_out_part_cannot_see_is_not_rejected_there(cache):
    """
    theta 2.154 deg on the 20 s physical-search drive: its B2B contacts close on the fit
    part, hardly on the held-out part (|d|^2/sigma^2 = 1.8 there, against a price of 16.6).  The
    held-out RMSE after is not below before (by the last bits: this noise draw), so the
    held-out check rejected a value found within 0.01 deg (bench seeds 6 and 8 lost two
    thetas so).  The held-out part does not judge it now, and says so.
    """
    rng = np.random.default_rng(1)
    rec, cfg, _ = sy.physical_case(sy.physical_trajectory(),
                                   {"errors": {"theta_amplitude_deg": 2.154}}, TermSet(),
                                   0.004, rng, cache, MODEL_RATE_HZ)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "contact_angle_deviation"
    assert abs(choice.value - 2.154) <= THETA_TOLERANCE_DEG
    assert not a.physical.heldout_judged and ph.summary(a.physical)["heldout_judged"] is False
    assert any("does not judge contact_angle_deviation" in n for n in a.physical.notes)
    # the check as it was: after < before fails on the held-out part
    hold = ~a.fit_mask
    after, before = a.residual_nm - a.added_nm, a.residual_nm
    rms = [np.sqrt(np.mean(v[hold] ** 2)) for v in (after, before)]
    assert not rms[0] < rms[1]


def test_another_model_parameter_within_the_threshold_is_named_ambiguous():
    """_other_parameters: a parameter whose best reading is within bic_threshold is named."""
    s = DiscrepancySettings()
    best = _outcome("preload", [], -100.0)
    bounds = {"friction_coefficient": -100.0 + 0.5 * s.bic_threshold,
              "contact_angle_deviation": -100.0 + 2.0 * s.bic_threshold, "preload": -100.0}
    points = {name: [None] for name in ph.PHYSICAL}
    out = ph._other_parameters(ph.PHYSICAL["preload"], best, bounds, [], points, s)
    assert [x["pair"] for x in out] == [["preload", "friction_coefficient"]]
    assert not out[0]["separated"] and "one ambiguous effect" in out[0]["statement"]
    # a refined reading counts when it is better than the bound
    finals = [_outcome("contact_angle_deviation", [], -99.0)]
    out = ph._other_parameters(ph.PHYSICAL["preload"], best, bounds, finals, points, s)
    assert [x["pair"][1] for x in out] == ["contact_angle_deviation", "friction_coefficient"]
    # a parameter never run is not named
    points["friction_coefficient"] = []
    out = ph._other_parameters(ph.PHYSICAL["preload"], best, bounds, [], points, s)
    assert out == []


def test_cross_validation_vetoes_only_a_larger_physical_reading():
    """
    _cv_judges: the empirical selection's rule, cross-validation vetoes only the larger model.

    Bench seed 14: mu 0.07842 alone (the truth to 0.01 %) beat seal_drag + load_dependent +
    offset by 28 in penalised BIC and was vetoed by the blocked cross-validation, where the
    three free terms fit the folds a little better.  The parameter counts as one term.
    """
    mu = "friction_coefficient"
    none = _outcome(None, ["seal_drag", "load_dependent", "offset"], -1000.0)
    # a smaller reading that beats "none": not vetoed by the larger model's folds
    assert not ph._cv_judges(_outcome(mu, [], -1028.0), none, False)
    assert not ph._cv_judges(_outcome(mu, ["seal_drag"], -1001.0), none, False)
    # the same size (2 terms + the parameter) or larger: judged as before
    assert ph._cv_judges(_outcome(mu, ["seal_drag", "offset"], -1028.0), none, False)
    assert ph._cv_judges(_outcome(mu, ["stribeck", "seal_drag", "offset"], -1028.0), none,
                         False)
    # a reading that does not beat "none", or is kept on a tie: judged as before
    assert ph._cv_judges(_outcome(mu, [], -999.0), none, False)
    assert ph._cv_judges(_outcome(mu, [], -995.0), none, True)
    # "none" with one term against the parameter alone: the same size, judged
    assert ph._cv_judges(_outcome(mu, [], -1028.0), _outcome(None, ["load_dependent"], -1000.0),
                         False)


def test_mu_alone_is_not_vetoed_by_a_larger_empirical_models_folds(cache):
    """
    mu 0.0784 alone (bench seed 14's case, 3.5 mN m noise, the 20 s drive, seed 7).

    mu at about the hidden value beats "none" (seal_drag + load_dependent) in penalised BIC,
    and the blocked cross-validation vetoed it: the two free terms fit the folds a little
    better.  The selection's own rule vetoes only the larger model (``_cv_judges``), so mu
    is named now, within 5 %, and a note says cross-validation was not applied.
    """
    rec, cfg, _ = case(cache, {"material": {"friction_coefficient": 0.0784}},
                       noise_nm=0.0035, seed=7)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    assert abs(choice.value / 0.0784 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert a.terms.names == () and not a.physical.tie
    assert any("cross-validation, which vetoes only a larger model" in n
               for n in a.physical.notes)


def test_heldout_gap_is_the_held_out_likelihood_ratio_of_the_two_readings():
    """
    _heldout_gap: n'_h ln(RSS_h(parameter) / RSS_h("none")), both readings as fitted.

    A load column k |W| sign w is the truth; "none" holds it as fitted, the parameter's
    reading is the same column plus the offset a change of mu carries (the model torque is
    affine in the load).  Only the held-out samples count, the usable ones only, and
    correlated noise (tau) counts n / tau samples.
    """
    from types import SimpleNamespace
    rng = np.random.default_rng(5)
    n_in = 1000
    t = np.arange(n_in) / 50.0
    w = np.where(np.sin(2 * np.pi * t / 2.0) >= 0.0, 6.0, -6.0)
    load = 1200.0 + 500.0 * np.sin(2 * np.pi * t / 3.7)
    rec = SimpleNamespace(t_run_s=t, nut_angle_rad=np.cumsum(w) / 50.0, nut_velocity_rad_s=w,
                          axial_load_n=load, nut_accel_rad_s2=None)
    ok = np.ones(n_in, dtype=bool)
    ok[::97] = False                      # dropped samples: r and the masks are over the rest
    n = int(ok.sum())
    fit_mask = np.arange(n) < int(0.7 * n)
    k, offset, sigma = 2e-5, 0.004, 0.005
    column = k * load * np.sign(w)
    truth = column + rng.normal(0.0, sigma, n_in)
    r = truth[ok]
    none = _outcome(None, ["load_dependent"], 0.0)
    none.terms = TermSet([sy.make_term("load_dependent", {"k_nm_per_n": k})])
    d = column + offset * np.sign(w)      # the parameter's change, with its offset
    mu = _outcome("friction_coefficient", [], 5.0)
    mu.terms = TermSet()
    mu.run = ph.TrialRun(0.09, d, np.zeros(n_in), ok, 0.0, d)
    hold = ~fit_mask
    e_mu = r[hold] - d[ok][hold]
    e_none = r[hold] - column[ok][hold]
    want = hold.sum() * math.log((e_mu @ e_mu) / (e_none @ e_none))
    got = ph._heldout_gap(mu, none, rec, ok, fit_mask, r, 1.0)
    assert got == pytest.approx(want, rel=1e-12)
    # the offset is 0.8 noise std over 292 held-out samples: "none" predicts far better
    assert got > 100.0
    assert ph._heldout_gap(mu, none, rec, ok, fit_mask, r, 2.0) == pytest.approx(got / 2.0)
    # the parameter's reading is the truth: negative
    r2 = (d + rng.normal(0.0, sigma, n_in))[ok]
    assert ph._heldout_gap(mu, none, rec, ok, fit_mask, r2, 1.0) < -100.0
    # no held-out part: no evidence
    assert ph._heldout_gap(mu, none, rec, ok, np.ones(n, dtype=bool), r, 1.0) == 0.0


def test_a_tie_the_held_out_part_breaks_keeps_the_empirical_twin(cache):
    """
    The config right and only an empirical load_dependent (k = 1.6e-5 N m/N, 5.7 mN m noise,
    the 20 s drive, seed 1): on the fit part mu ties with it (load_dependent better by 8.7 <
    bic_threshold), and the tie rule named mu, a false alarm (bench seed 101 had three such
    recordings of twelve).  The held-out part, which the choice between the two readings has
    not seen, adds 10.1 for load_dependent: 18.8 over the whole recording, no tie.  The twin
    is kept, and the evidence is said.
    """
    terms = TermSet([sy.make_term("load_dependent", {"k_nm_per_n": 1.6e-5})])
    rec, cfg, _ = case(cache, {}, terms, noise_nm=0.0057, seed=1)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    assert ph.chosen(a.physical) is None and a.terms.names == ("load_dependent",)
    assert not a.physical.tie
    note = [n for n in a.physical.notes if "tied with load_dependent on the fit part" in n]
    assert note and "load_dependent is kept" in note[0]
    pair = [x for x in a.ambiguities if x["pair"] == ["load_dependent",
                                                      "friction_coefficient"]]
    assert pair and pair[0]["separated"] and pair[0]["bic_difference"] >= 10.0


def test_mu_beside_its_twin_is_refined_when_only_the_twin_held_bound_sees_it(cache):
    """
    mu 0.112 with a hidden load_dependent of k = 3.98e-5 N m/N (bench seed 13's case, 5.4 mN
    m noise, the 20 s drive, seed 1).  "none" holds load_dependent; mu's bound with the twin
    left out cannot reach it (one scale of mu's change cannot be both the hidden mu's and
    the twin's), so mu was never refined and load_dependent alone was named.  With the twin
    held as well, mu's change at its free scale beats "none"; mu is refined on that profile
    and named beside load_dependent, within 5 %.
    """
    terms = TermSet([sy.make_term("load_dependent", {"k_nm_per_n": 3.98e-5})])
    rec, cfg, _ = case(cache, {"material": {"friction_coefficient": 0.112}}, terms,
                       noise_nm=0.0054, seed=1)
    a = analyse(rec, DiscrepancySettings(),
                ph.PhysicsContext(cfg, RUNNER, ph.PhysicalSettings(enabled=True)))
    choice = ph.chosen(a.physical)
    assert choice is not None and choice.kind.name == "friction_coefficient"
    assert abs(choice.value / 0.112 - 1.0) <= MU_RELATIVE_TOLERANCE
    assert a.terms.names == ("load_dependent",)
    lo, hi = choice.interval_95
    assert lo <= choice.value <= hi


def test_reported_figures_of_a_physical_choice_are_what_replay_gives(cache, tmp_path):
    """
    The held-out and validation figures of a chosen mu are the replay path's.

    The trials step before they answer; replay answers a dense input first.  The validation
    RMSE used to be reported from the trials' schedule (1.37x what replay then gave).
    """
    hidden = {"material": {"friction_coefficient": 0.125}}
    rec, cfg, _ = short_case(cache, hidden, seed=3)
    val, _, _ = short_case(cache, hidden, seed=4)
    settings = dataclasses.replace(DiscrepancySettings(),
                                   physical=ph.PhysicalSettings(enabled=True))
    replay = NodeParameters(model_rate_hz=MODEL_RATE_HZ)
    status, summary = run_discrepancy(write_csv(tmp_path / "fit.csv", rec), tmp_path / "out",
                                      config=cfg, settings=settings, replay_settings=replay,
                                      validate_path=write_csv(tmp_path / "val.csv", val))
    assert status == 0 and summary["effects"][0]["name"] == "friction_coefficient"
    # replay's inertia term filters causally, the analysis zero-phase: not comparable here
    assert "inertia" not in [e["name"] for e in summary["effects"]]
    assert summary["physical"]["replay_path_runs"] == 2
    assert summary["physical"]["validation_model_runs"] == 2
    cols = {"t_s": val.t_s, "nut_angle_rad": val.nut_angle_rad,
            "nut_velocity_rad_s": val.nut_velocity_rad_s, "axial_load_n": val.axial_load_n}
    preds, _ = predict_events(csv_events(cols, replay.nut_joint),
                              tmp_path / "out" / "augmented.yaml", replay)
    v = summary["validation"]
    assert v["n"] == len(val)
    replayed = np.sqrt(np.mean((val.torque_meas_nm - preds.column("torque_total_nm")) ** 2))
    assert v["rmse_after_nm"] == pytest.approx(replayed, rel=1e-9)
