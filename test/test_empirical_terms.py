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
NEW_TERMS = [
    {"name": "inertia", "params": {"j_kg_m2": 2e-4, "accel_cutoff_hz": 10.0, "max_gap_s": 0.05}},
    {"name": "offset", "params": {"torque_nm": -0.01}},
    {"name": "coulomb_asymmetry", "params": {"delta_torque_nm": 0.004}},
    {"name": "viscous_asymmetry", "params": {"delta_c_nm_s_per_rad": -1e-4}},
    {"name": "pre_rolling", "params": {"torque_nm": 0.02, "travel_rad": 0.003}},
    {"name": "stroke_position", "params": {"center_rad": 50.0, "half_range_rad": 40.0,
                                           "p1_nm": 0.01, "p2_nm": -0.004}},
    {"name": "angle_ripple", "params": {"sin1_nm": 0.003, "cos2_nm": 0.001}},
]


def test_yaml_round_trip_gives_the_same_torque():
    terms = load_terms(ALL_TERMS + NEW_TERMS)
    again = load_terms(terms.to_list())
    assert again.names == tuple(e["name"] for e in ALL_TERMS + NEW_TERMS)
    t, phi, w, load = np.linspace(0, 10, 50), np.linspace(0, 20, 50), \
        np.linspace(-8, 8, 50), np.linspace(800, 2000, 50)
    accel = np.linspace(-100, 100, 50)
    assert np.array_equal(terms.torque_nm(t, phi, w, load, accel),
                          again.torque_nm(t, phi, w, load, accel))
    assert set(LIBRARY) == set(terms.names)
    assert terms.to_list()[-2]["params"] == NEW_TERMS[-2]["params"]


def test_new_terms_have_their_physical_shape():
    """inertia J alpha; offset unsigned; asymmetries zero-mean; stroke, ripple as documented."""
    w = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    accel = np.array([5.0, -3.0, 0.0, 1.0, 0.0])
    one = {e["name"]: load_terms([e]) for e in NEW_TERMS}
    assert np.allclose(one["inertia"].torque_nm(0.0, 0.0, w, 1.0, accel), 2e-4 * accel)
    with pytest.raises(ValueError, match="acceleration"):
        one["inertia"].torque_nm(0.0, 0.0, w, 1.0)
    assert np.allclose(one["offset"].torque_nm(0.0, 0.0, w, 1.0), -0.01)
    # positive direction's drag is +Delta/2 above the mean, the negative one's Delta/2 below:
    # in torque (sign of omega) both are +Delta/2; nothing at standstill
    ca = one["coulomb_asymmetry"].torque_nm(0.0, 0.0, w, 1.0)
    assert np.allclose(ca, [0.002, 0.002, 0.0, 0.002, 0.002])
    seal = load_terms([{"name": "seal_drag", "params": {"torque_nm": 0.03}}])
    total = seal.torque_nm(0.0, 0.0, w, 1.0) + ca
    assert total[4] == pytest.approx(0.032) and total[0] == pytest.approx(-0.028)
    assert (total[4] - total[0]) / 2 == pytest.approx(0.03)     # seal keeps the mean
    va = one["viscous_asymmetry"].torque_nm(0.0, 0.0, w, 1.0)
    assert np.allclose(va, -0.5e-4 * np.abs(w))
    # stroke: Legendre P1, P2 of the travel, signed by the motion, held beyond the stroke
    phi = np.array([10.0, 50.0, 90.0, 500.0])
    xi = np.clip((phi - 50.0) / 40.0, -1, 1)
    expect = 0.01 * xi - 0.004 * 0.5 * (3 * xi ** 2 - 1)
    assert np.allclose(one["stroke_position"].torque_nm(0.0, phi, 1.0, 1.0), expect)
    assert np.allclose(one["stroke_position"].torque_nm(0.0, phi, -1.0, 1.0), -expect)
    # ripple: independent of the load (lead_error is the load-scaled one)
    phi = np.linspace(0, 2 * math.pi, 7)
    r1 = one["angle_ripple"].torque_nm(0.0, phi, 1.0, 100.0)
    r2 = one["angle_ripple"].torque_nm(0.0, phi, 1.0, 5000.0)
    assert np.array_equal(r1, r2)
    assert np.allclose(r1, 0.003 * np.sin(phi) + 0.001 * np.cos(2 * phi))


def test_inertia_terms_must_share_one_filter():
    other = dict(NEW_TERMS[0], params=dict(NEW_TERMS[0]["params"], accel_cutoff_hz=20.0))
    with pytest.raises(ConfigError, match=r"empirical_terms\[1\].params.accel_cutoff_hz"):
        load_terms([NEW_TERMS[0], other])


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


@pytest.mark.parametrize("entry", [e for e in ALL_TERMS if e["name"] != "lead_error"]
                         + [e for e in NEW_TERMS if e["name"] == "stroke_position"])
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


FULL_TERMS = [
    {"name": "lead_error", "params": {f"{k}{h}_m": 1e-6 * (h + 0.3 * (k == "cos"))
                                      for h in range(1, 5) for k in ("sin", "cos")}},
    {"name": "angle_ripple", "params": {f"{k}{h}_nm": 1e-3 / h * (-1) ** h
                                        for h in range(1, 5) for k in ("sin", "cos")}},
    {"name": "stroke_position", "params": {"center_rad": 10.0, "half_range_rad": 25.0,
                                           "p1_nm": 0.01, "p2_nm": -0.004, "p3_nm": 0.002}},
]


# The stateless terms: a single sample's torque is a function of that sample alone (the
# pre-rolling state is compared over whole sequences in test_pre_rolling.py).
STATELESS = [e for e in ALL_TERMS + NEW_TERMS + FULL_TERMS if e["name"] != "pre_rolling"]


@pytest.mark.parametrize("entries", [[e] for e in STATELESS] + [STATELESS],
                         ids=lambda es: es[0]["name"] if len(es) == 1 else "all")
def test_live_terms_equal_the_vectorised_terms_bit_for_bit(entries):
    """
    LiveTerms' per-sample path (node and replay) gives exactly TermSet.torque_nm's number at
    each sample: replay's output must not move when the evaluation is made cheaper.
    """
    terms = load_terms(entries)
    live = terms.live()
    rng = np.random.default_rng(11)
    n = 600
    t = np.cumsum(rng.uniform(0.0, 2e-3, n))
    phi = rng.uniform(-80.0, 80.0, n)
    w = rng.normal(0.0, 10.0, n)
    w[::7] = 0.0                                   # standstill: sign 0, drag terms 0
    w[3::11] *= 1e-9                               # tiny speeds near the Stribeck peak
    load = rng.uniform(-3000.0, 3000.0, n)
    for k in range(n):
        got = live.torque_nm(t[k], t[k] - t[0], phi[k], w[k], load[k])
        want = float(terms.torque_nm(t[k] - t[0], phi[k], w[k], load[k],
                                     live.last_accel_rad_s2))
        assert got.hex() == want.hex(), (k, got, want)
