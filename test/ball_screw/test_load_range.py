"""The model's load range (config.validity): derived from the Hertz contact, refused beyond."""

import math

import pytest

from bb_friction_ros.ball_screw.reproduce import load_range_rows
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import ConfigError
from bb_friction_ros.model_file import load_ball_screw


def test_limit_is_where_the_ellipse_or_the_pressure_reaches_its_bound(model, config):
    q = model.max_contact_load_n()
    v = config.validity
    ratios = [h.semi_axes(q)[0] / model.ball.r_b for h in model.ball.hertz]
    pressures = [h.peak_pressure(q) for h in model.ball.hertz]
    assert max(ratios) <= v.max_contact_semi_axis_ratio * (1 + 1e-12)
    assert max(pressures) <= v.max_hertz_pressure_pa * (1 + 1e-12)
    # one of the two bounds is reached exactly (Table 4: a / R_B = 0.2 binds at ~398 N,
    # where p0 is ~2.8 GPa)
    assert max(ratios) == pytest.approx(v.max_contact_semi_axis_ratio, rel=1e-9) or \
        max(pressures) == pytest.approx(v.max_hertz_pressure_pa, rel=1e-9)
    assert 350.0 < q < 450.0
    w = model.max_axial_load_n(37)
    assert w == pytest.approx(q * 37 * model.ball.cos_a * math.sin(model.ball.beta0))
    assert 9e3 < w < 11e3


def test_pressure_bound_binds_when_it_is_lower(model):
    cfg = load_ball_screw(overrides={"validity": {"max_hertz_pressure_pa": 2.0e9}})
    low = ScrewModel(cfg)
    q = low.max_contact_load_n()
    assert q < model.max_contact_load_n()
    assert max(h.peak_pressure(q) for h in low.ball.hertz) == pytest.approx(2.0e9, rel=1e-9)


@pytest.mark.parametrize("load_n", [20e3, 50e3, -20e3])
def test_load_beyond_the_range_is_refused_not_solved(config, model, load_n):
    # At 20 kN the solve used to swing from -58 to +8 N m, unflagged
    # in the feedforward.  Now: not solved, flagged, zero torque, state kept.
    screw = WholeScrew(config, model)
    ok = screw.step(0.06, 6.0, 1500.0, 0.01)
    assert ok.converged and ok.in_load_range
    out = screw.step(0.12, 6.0, load_n, 0.01)
    assert not out.converged and not out.in_load_range
    assert out.torque_total_nm == 0.0 and out.iterations == 0
    back = screw.step(0.18, 6.0, 1500.0, 0.01)
    assert back.converged and back.in_load_range
    assert back.torque_total_nm == pytest.approx(ok.torque_total_nm, rel=0.05)


def test_inside_the_range_solutions_are_flagged_in_range(config, model):
    screw = WholeScrew(config, model)
    for k in range(1, 4):
        r = screw.step(0.06 * k, 6.0, 5000.0, 0.01)
        assert r.converged and r.in_load_range
        assert r.loads_n.max() <= screw.max_contact_load_n


def test_unconverged_step_inside_the_range_is_not_called_out_of_range(config, model):
    # 9 kN is inside the 10.2 kN range; steps there may fail to converge (the third contact
    # unloads, docs/assumptions_ball_screw.md).  in_load_range then speaks of the load, not
    # of the meaningless contact loads of the last iterate; a solution is judged per contact.
    # (Elastic: its failed iterates carry contacts above the limit.)
    elastic = load_ball_screw(overrides={"load_distribution": "elastic"})
    screw = WholeScrew(elastic, model)
    for k in range(1, 4):
        r = screw.step(0.06 * k, 6.0, 9000.0, 0.01)
        if r.converged:
            assert r.in_load_range == (r.loads_n.max() <= screw.max_contact_load_n)
        else:
            assert r.in_load_range


@pytest.mark.parametrize("key, value", [("max_contact_semi_axis_ratio", 0.0),
                                        ("max_hertz_pressure_pa", -1.0),
                                        ("max_contact_semi_axis_ratio", 1.5)])
def test_bad_range_config_is_refused_by_name(key, value):
    with pytest.raises(ConfigError, match=key):
        load_ball_screw(overrides={"validity": {key: value}})


def test_reproduce_report_states_the_range(model, config):
    # The report's rows are the model's own limits, with the bound that binds.
    rows = {r["quantity"]: r for r in load_range_rows(model, config.track.n_balls)}
    contact = rows["Load range: largest contact load"]
    assert contact["ours"] == model.max_contact_load_n()
    assert "a/R_B = 0.200" in contact["note"]
    axial = rows["Load range: largest axial load"]
    assert axial["ours"] == model.max_axial_load_n(config.track.n_balls)
