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
    p.s, p.magnitude = -1.0, TC
    p.velocity = 1.0
    p.advance(0.0, 1e-3, TC, 0.0)       # about 1 mrad of travel
    travel = p.angle - 1.0
    assert p.s == pytest.approx(1.0 - 2.0 * math.exp(-travel / phi_d), abs=1e-9)


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
