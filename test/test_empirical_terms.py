"""The library of empirical terms: validation with dotted keys, YAML round trip, signs."""

import math

import numpy as np
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.empirical_terms import LIBRARY, load_terms, make_term, TermSet

ALL_TERMS = [
    {"name": "viscous_drag", "params": {"c_nm_s_per_rad": 0.004}},
    {"name": "seal_drag", "params": {"torque_nm": 0.03}},
    {"name": "stribeck", "params": {"torque_nm": 0.05, "velocity_rad_s": 1.0}},
    {"name": "load_dependent", "params": {"k_nm_per_n": -2e-5}},
    {"name": "lead_error", "params": {"sin1_m": 5e-6, "cos2_m": -1e-6}},
    {"name": "thermal_drift", "params": {"delta_torque_nm": -0.02, "time_constant_s": 30.0}},
]


def test_yaml_round_trip_gives_the_same_torque():
    terms = load_terms(ALL_TERMS)
    again = load_terms(terms.to_list())
    assert again.names == tuple(e["name"] for e in ALL_TERMS)
    t, phi, w, load = np.linspace(0, 10, 50), np.linspace(0, 20, 50), \
        np.linspace(-8, 8, 50), np.linspace(800, 2000, 50)
    assert np.array_equal(terms.torque_nm(t, phi, w, load), again.torque_nm(t, phi, w, load))
    assert set(LIBRARY) == set(terms.names)


@pytest.mark.parametrize("raw, key", [
    ([{"name": "viscous"}], "empirical_terms[0].name"),
    ([ALL_TERMS[0], {"name": "viscous_drag", "params": {"c": 1.0}}],
     "empirical_terms[1].params.c"),
    ([ALL_TERMS[0], {"name": "viscous_drag", "params": {"c_nm_s_per_rad": -1.0}}],
     "empirical_terms[1].params.c_nm_s_per_rad"),
    ([{"name": "stribeck", "params": {"torque_nm": 0.1}}],
     "empirical_terms[0].params.velocity_rad_s"),
    ([{"name": "seal_drag", "params": {"torque_nm": 0.1}, "extra": 1}],
     "empirical_terms[0].extra"),
    ({"name": "seal_drag"}, "empirical_terms"),
])
def test_bad_terms_are_refused_naming_the_dotted_key(raw, key):
    with pytest.raises(ConfigError) as err:
        load_terms(raw)
    assert str(err.value).startswith(key + ":")


def test_edge_units_and_no_terms():
    assert load_terms([{"name": "lead_error", "params": {"sin1_um": 4.0}}]).to_list() == \
        [{"name": "lead_error", "params": {"sin1_m": 4e-6}}]
    assert len(load_terms(None)) == 0 and TermSet().torque_nm(0.0, 0.0, 1.0, 1000.0) == 0.0


@pytest.mark.parametrize("entry", [e for e in ALL_TERMS if e["name"] != "lead_error"])
def test_dissipative_terms_oppose_motion_and_vanish_at_standstill(entry):
    term = load_terms([entry])
    w = np.array([-5.0, -0.5, 0.0, 0.5, 5.0])
    torque = term.torque_nm(10.0, 0.3, w, 1500.0)
    assert torque[2] == 0.0
    # same sign as the nut velocity (a negative-amplitude term: consistently the opposite)
    signs = np.sign(torque[[0, 1, 3, 4]]) * np.sign(w[[0, 1, 3, 4]])
    assert np.all(signs == signs[0]) and signs[0] != 0


def test_lead_error_is_the_load_torque_of_the_axial_error():
    """T = W de/dphi: checked against a finite difference of e(phi)."""
    amp = 6e-6
    term = make_term("lead_error", {"sin1_m": amp})
    phi = np.linspace(0.0, 2 * math.pi, 9)
    h = 1e-6
    de = (amp * np.sin(phi + h) - amp * np.sin(phi - h)) / (2 * h)
    torque = TermSet([term]).torque_nm(0.0, phi, 0.0, 1500.0)      # not zero at standstill
    assert np.allclose(torque, 1500.0 * de, rtol=1e-6, atol=1e-12)


def test_thermal_time_starts_at_zero_and_saturates():
    term = load_terms([ALL_TERMS[-1]])
    t = np.array([0.0, 30.0, 1e6])
    torque = term.torque_nm(t, 0.0, 1.0, 1000.0)
    assert torque[0] == 0.0
    assert torque[1] == pytest.approx(-0.02 * (1 - math.exp(-1)))
    assert torque[2] == pytest.approx(-0.02)


def test_effects_report_units():
    effects = load_terms(ALL_TERMS[:1]).effects()
    assert effects == [{"name": "viscous_drag", "params": {"c_nm_s_per_rad": 0.004},
                        "units": {"c_nm_s_per_rad": "N m s/rad"}}]
