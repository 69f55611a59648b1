"""
The plant: exact motion under held torques, stick at standstill without chatter, breakaway
at the model's torque, pre-sliding, and the integrator's error against a finer run.
"""

import dataclasses
import math

import numpy as np
import pytest

from bb_friction_ros.servo.plant import Plant, RigidBodyFriction
from bb_friction_ros.servo.settings import PlantSettings

J = 2e-4
TC = 0.2


def plant(law=None, **changes):
    law = law or RigidBodyFriction(0.0, TC, 0.0)
    return Plant(law, J, dataclasses.replace(PlantSettings(), **changes), 1.0)


def test_torque_below_breakaway_holds_the_axis_still_and_friction_equals_it():
    p = plant()
    for k in range(200):
        f = p.advance(k * 1e-3, 1e-3, 0.9 * TC, 0.0)
        assert f == pytest.approx(0.9 * TC)
    assert p.angle == 1.0 and p.velocity == 0.0
    assert p.breakaways == 0


def test_torque_above_breakaway_accelerates_exactly_as_a_rigid_body():
    """From rest, u = 3 T_c: phi - phi_0 = (u - T_c) t^2 / (2 J), to rounding."""
    p = plant()
    u = 3 * TC
    for k in range(50):
        p.advance(k * 1e-3, 1e-3, u, 0.0)
    t = 0.05
    assert p.angle - 1.0 == pytest.approx((u - TC) / J * t * t / 2, rel=1e-12)
    assert p.velocity == pytest.approx((u - TC) / J * t, rel=1e-12)


@pytest.mark.parametrize("substeps", [1, 8])
def test_coasting_axis_stops_where_friction_says_and_stays_without_chatter(substeps):
    """w0 with u = 0: stops after w0^2 J / (2 T_c) of travel, then exactly still."""
    p = plant(substeps=substeps)
    p.velocity = 5.0
    angles = []
    for k in range(100):
        p.advance(k * 1e-3, 1e-3, 0.0, 0.0)
        angles.append(p.angle)
    assert p.velocity == 0.0
    assert p.angle - 1.0 == pytest.approx(25.0 * J / (2 * TC), rel=1e-12)
    assert len(set(angles[-80:])) == 1          # no creep, no sign flipping at rest


def test_reversal_against_friction_slides_back_only_above_the_other_breakaway():
    law = RigidBodyFriction(0.0, TC, 0.05)        # offset: breakaways -0.15 and +0.25
    p = plant(law)
    p.advance(0.0, 1e-3, -0.14, 0.0)
    assert p.velocity == 0.0
    p.advance(1e-3, 1e-3, -0.16, 0.0)
    assert p.velocity < 0.0
    assert p.breakaways == 1


def test_presliding_builds_the_friction_over_its_travel_after_a_reversal():
    """Dahl element: s = 1 - 2 exp(-travel / phi_d) after a reversal from s = -1."""
    phi_d = 1e-3
    p = plant(presliding_rad=phi_d, substeps=50)
    p.f, p.level = -TC, TC
    p.velocity = 1.0
    p.advance(0.0, 1e-3, TC, 0.0)       # about 1 mrad of travel
    travel = p.angle - 1.0
    assert p.s == pytest.approx(1.0 - 2.0 * math.exp(-travel / phi_d), abs=1e-9)


class StribeckLaw:
    """A friction law whose level rises toward standstill: T_c + T_s exp(-(w / w_s)^2)."""

    errors = 0

    def torque(self, t_s, angle_rad, velocity_rad_s, load_n):
        return math.copysign(TC + 0.1 * math.exp(-(velocity_rad_s / 1.0) ** 2),
                             velocity_rad_s)

    def breakaway(self, t_s, angle_rad, load_n, direction):
        return direction * (TC + 0.1)


def ringing(p, periods=400):
    """Release a plant deflected on its pre-sliding spring, u = 0; return |angle - end| peaks."""
    angles = []
    for k in range(periods):
        p.advance(k * 1e-3, 1e-3, 0.0, 0.0)
        angles.append(p.angle)
    a = np.array(angles) - angles[-1]
    return np.abs(a[:50]).max(), np.abs(a[-50:]).max()


def test_a_level_that_changes_with_velocity_moves_a_deflected_element_only_over_travel():
    """A Stribeck rise does not lift the friction of a deflected element at once."""
    phi_d = 1e-3
    p = plant(StribeckLaw(), presliding_rad=phi_d, substeps=8)
    p.f, p.level, p.velocity = 0.1, TC, 1e-6     # half-deflected, creeping
    p.advance(0.0, 1e-3, 0.1, 0.0)
    # level 0.3 N m at 1e-6 rad/s: f moves by (0.3 - 0.1) * travel / phi_d, ~1e-6 N m,
    # where s * M(w) (the state times the level) would jump to 0.15 N m
    assert p.f == pytest.approx(0.1, abs=1e-5)
    assert p.level == pytest.approx(TC + 0.1, rel=1e-9)


def test_presliding_damping_ratio_damps_the_ringing_at_rest():
    """sigma_1 at damping ratio 0.5: the ringing dies within a few periods of its mode."""
    undamped = plant(presliding_rad=1e-3, substeps=16)
    damped = plant(presliding_rad=1e-3, substeps=16, presliding_damping_ratio=0.5)
    for p in (undamped, damped):
        p.f, p.level = 0.15, TC
    f_undamped = ringing(undamped, 60)
    f_damped = ringing(damped, 60)
    # the mode: sqrt(M / (phi_d J)) = 1000 rad/s, 60 ms are ~10 periods; zeta 0.5 leaves
    # exp(-0.5 * 1000 * 0.01) < 1 % after 10 ms
    assert f_damped[1] < 0.01 * f_damped[0]
    assert f_undamped[1] > 10.0 * f_damped[1]


def test_presliding_damping_ratio_is_zero_by_default_and_validated():
    """The default leaves the Dahl element as it is; a negative ratio is refused by name."""
    from bb_friction_ros.config import ConfigError
    from bb_friction_ros.servo.settings import settings_from_mapping
    assert PlantSettings().presliding_damping_ratio == 0.0
    loop = {"rate_hz": 1000.0, "position_gain_per_s": 40.0, "velocity_gain_nm_s_per_rad": 0.1,
            "torque_limit_nm": 1.0}
    with pytest.raises(ConfigError, match="presliding_damping_ratio"):
        settings_from_mapping({"loop": loop, "plant": {"presliding_damping_ratio": -0.1}})


def test_holding_the_model_per_servo_sample_converges_to_the_substep_run(axis_model,
                                                                         loop_file,
                                                                         short_spec):
    """
    The integrator's error: friction held per servo sample against re-answered at every
    sub-step, both against a 64-sub-step run; the error falls with the sub-steps.
    """
    from bb_friction_ros.servo.modes import Mode
    from bb_friction_ros.servo.reference import load_reference
    from bb_friction_ros.servo.run import Setup
    from bb_friction_ros.servo.settings import load_settings
    s = load_settings(loop_file)
    ref = load_reference(short_spec, 1000.0, [0.02])

    def angle(sub, update):
        st = dataclasses.replace(s, plant=dataclasses.replace(s.plant, substeps=sub,
                                                              friction_update=update))
        return Setup(st, axis_model).simulate_axis(ref, ref.axes[0], Mode("none")).angle_rad

    fine = angle(64, "substep")
    um = 0.02 / (2 * math.pi) * 1e6
    err = {key: float(np.max(np.abs(angle(*key) - fine))) * um
           for key in ((8, "sample"), (2, "substep"), (8, "substep"))}
    assert err[(8, "substep")] < 0.25           # the default's stated bound [um]
    assert err[(8, "substep")] < err[(2, "substep")] < err[(8, "sample")] < 1.0


def test_a_model_files_pre_rolling_term_becomes_the_plants_dahl_element(
        axis_model, tmp_path, loop_file):
    """
    A calibrated model's pre-sliding is simulated as the plant's Dahl element of the term's
    travel, without the term itself (counted once); ``plant.presliding_rad`` takes
    precedence; a law given to the run (the rigid-body reference) gets no Dahl element.
    """
    import yaml
    from bb_friction_ros.servo.modes import Mode
    from bb_friction_ros.servo.plant import model_presliding_rad, plant_presliding_rad
    from bb_friction_ros.servo.reference import load_reference
    from bb_friction_ros.servo.run import Setup
    from bb_friction_ros.servo.settings import load_settings
    data = yaml.safe_load(open(axis_model))
    data["empirical_terms"].append({"name": "pre_rolling",
                                    "params": {"torque_nm": 0.05, "travel_rad": 0.004}})
    model = tmp_path / "with_pre_rolling.yaml"
    model.write_text(yaml.safe_dump(data))
    assert model_presliding_rad(axis_model) == 0.0
    assert model_presliding_rad(model) == 0.004
    assert plant_presliding_rad(0.0, model) == 0.004
    assert plant_presliding_rad(0.002, model) == 0.002
    s = load_settings(loop_file)
    setup = Setup(s, model)
    assert setup.presliding_rad[0] == 0.004
    law = setup.plant_law()
    assert "pre_rolling" not in [t.name for t in law.terms.terms]
    assert [t.name for t in law.terms.terms] == \
        [t.name for t in Setup(s, axis_model).plant_law().terms.terms]
    spec = tmp_path / "spec.yaml"
    spec.write_text("reference:\n  kind: reversal\n  speeds_rev_s: [1.0]\n  stroke_rev: 0.25\n"
                    "  accel_rev_s2: 20.0\n  axial_load_n: 1500.0\n")
    ref = load_reference(spec, 1000.0, [0.02])
    run = setup.simulate_axis(ref, ref.axes[0], Mode("none"))
    # a Dahl plant has no stick switch: the axis never rests on a stuck friction
    assert run.counters["stick_substeps"] == 0
    rigid = setup.simulate_axis(ref, ref.axes[0], Mode("none"),
                                law=RigidBodyFriction(0.0, TC, 0.0), inertia=J)
    assert rigid.counters["stick_substeps"] > 0
