"""
The feedforward's B2B torque averaged over the balls' arrangements.

The machine never sees where its balls are; a model reset at start-up assumes them evenly
spaced, and the B2B ripple of that arrangement, fed forward, is a ripple of the wrong phase.
The default feedforward carries the mean over arrangements instead; the prediction keeps the
model state's own B2B torque.
"""

import math

import numpy as np
import pytest
import yaml

from bb_friction_ros.ball_screw.arrangement import ArrangementAverage, mean_b2b
from bb_friction_ros.config import bundled_config
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.runner import (ARRANGEMENT_AVERAGED, ARRANGEMENT_MODEL, build_runner,
                                    InputSample)

THETA_DEG = 3.0


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    doc = yaml.safe_load(open(bundled_config("ball_screw.yaml")))
    doc["ball_screw"]["errors"]["theta_amplitude_deg"] = THETA_DEG
    path = tmp_path_factory.mktemp("arrangement") / "theta3.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _rotate(runner, revolutions=3.0, rate_hz=1000.0, load=1500.0):
    w = 2 * math.pi
    n = int(revolutions * rate_hz)
    return [runner.process(InputSample(k / rate_hz, w * k / rate_hz, w, load))
            for k in range(n)]


def test_without_a_contact_angle_deviation_nothing_depends_on_the_arrangement():
    cfg = load_ball_screw(bundled_config("ball_screw.yaml"),
                          {"errors": {"theta_amplitude_deg": 0.0}})
    assert mean_b2b(cfg) is None


def test_mean_has_the_velocitys_sign_and_is_below_a_fresh_screws(model):
    cfg = load_ball_screw(model)
    m = mean_b2b(cfg)
    assert np.all(m.torque_nm >= 0.0) and m.at(0.0, 1.0) == 0.0
    assert m.at(1500.0, -1.0) == -m.at(1500.0, 1.0) and m.at(1500.0, 0.0) == 0.0
    # the balls settle: below the first revolutions' B2B torque of an evenly spaced start
    fresh = [p.torque_b2b_nm for p in _rotate(build_runner(model, 100.0), revolutions=1.0)]
    assert m.at(1500.0, 1.0) < np.mean(fresh)
    assert ArrangementAverage().load_factors[0] == 0.0


def test_feedforward_carries_the_mean_and_the_prediction_the_states_own(model):
    cfg = load_ball_screw(model)
    m = mean_b2b(cfg)
    averaged = _rotate(build_runner(model, 100.0, b2b_feedforward="averaged"))
    own = _rotate(build_runner(model, 100.0, b2b_feedforward="model"))
    for a, o in zip(averaged, own):
        assert a.torque_total_nm == o.torque_total_nm and a.torque_b2b_nm == o.torque_b2b_nm
        assert o.feedforward_nm == o.torque_total_nm and o.arrangement == ARRANGEMENT_MODEL
        assert a.arrangement == ARRANGEMENT_AVERAGED
        assert a.feedforward_nm == m.total_at(1500.0, 2 * math.pi)
    # the ripple of the assumed arrangement (in both parts) is gone from the feedforward
    assert np.std([p.torque_b2b_nm for p in own]) > 1e-3
    assert np.std([p.torque_b2g_nm for p in own]) > 1e-4
    assert len({p.feedforward_nm for p in averaged}) == 1      # one load, one speed
    # and the mean is the physics' own mean over a settled run, within its spread
    own_mean = np.mean([p.torque_total_nm for p in own[-1000:]])
    assert m.total_at(1500.0, 1.0) == pytest.approx(own_mean, abs=0.02)


def test_message_constants_are_the_runners():
    from bb_friction_msgs.msg import FrictionPrediction
    assert FrictionPrediction.ARRANGEMENT_MODEL == ARRANGEMENT_MODEL
    assert FrictionPrediction.ARRANGEMENT_AVERAGED == ARRANGEMENT_AVERAGED
