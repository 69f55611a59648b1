"""
The measured inputs of the discrepancy workflow: the measured torque and the sample times.

- a CSV whose t_s never advances exits 2 naming t_s (it crashed in the thermal grid);
- the motor current (CSV column motor_current_a, bag topic motor_current) times
  --torque-constant-nm-per-a is the measured torque; without the constant, exit 2 naming it.
"""

import dataclasses
import json

import numpy as np
import pytest

from bb_friction_ros.empirical_terms import make_term, TermSet

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv


@pytest.mark.parametrize("stamp", [0.0, 1234.5])
def test_csv_whose_time_never_advances_exits_2_naming_t_s(pair, tmp_path, capsys, stamp):
    """It crashed in the thermal grid before ('Geometric sequence cannot include zero')."""
    fit, _, _ = pair
    rec = dataclasses.replace(fit, t_s=np.full(len(fit), stamp))
    a = write_csv(tmp_path / "stuck.csv", rec)
    for extra in ([], ["--baseline", "zero"]):
        assert run_cli(["--no-physical", a, "--out", tmp_path / "o", "--no-progress", *extra]) == 2
        err = capsys.readouterr().err
        assert "column t_s never advances" in err and str(a) in err


K_NM_PER_A = 0.0625


def _current_csv(path, rec, with_torque=False):
    extra = {"motor_current_a": rec.torque_meas_nm / K_NM_PER_A}
    cols = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "motor_current_a",
            "torque_pred_nm") + (("torque_meas_nm",) if with_torque else ())
    return write_csv(path, rec, columns=cols, extra=extra)


def test_motor_current_with_a_torque_constant_is_the_measured_torque(pair, tmp_path):
    fit, _, _ = pair
    a = write_csv(tmp_path / "torque.csv", fit)
    b = _current_csv(tmp_path / "current.csv", fit)
    assert run_cli(["--no-physical",
                    a, "--out", tmp_path / "t", "--no-progress", "--no-plots"]) == 0
    assert run_cli(["--no-physical", b, "--out", tmp_path / "c", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 0
    st = json.loads((tmp_path / "t" / "summary.json").read_text())
    sc = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert [e["name"] for e in sc["effects"]] == [e["name"] for e in st["effects"]]
    assert sc["rmse_after_nm"] == pytest.approx(st["rmse_after_nm"], rel=1e-9)
    said = "motor_current_a x 0.0625 N m/A (--torque-constant-nm-per-a)"
    assert said in sc["input"]["measured_torque_source"]
    assert said in (tmp_path / "c" / "report.md").read_text()


@pytest.mark.parametrize("case,argv,needle", [
    ("current without a constant", [], "needs the motor's torque constant, "
     "--torque-constant-nm-per-a K"),
    ("constant without a current column", ["--torque-constant-nm-per-a", "0.1"],
     "--torque-constant-nm-per-a was given but the CSV has no motor_current_a"),
    ("zero constant", ["--torque-constant-nm-per-a", "0"],
     "--torque-constant-nm-per-a: must be a finite torque constant > 0"),
    ("NaN constant", ["--torque-constant-nm-per-a", "nan"],
     "--torque-constant-nm-per-a: must be a finite torque constant > 0"),
])
def test_current_input_errors_name_the_flag(pair, tmp_path, capsys, case, argv, needle):
    fit, _, _ = pair
    if "column" in case:
        f = write_csv(tmp_path / "torque.csv", fit)
    else:
        f = _current_csv(tmp_path / "current.csv", fit)
    assert run_cli(["--no-physical",
                    f, "--out", tmp_path / "o", "--no-progress", "--no-plots", *argv]) == 2
    assert needle in capsys.readouterr().err


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bag_motor_current_topic(base, tmp_path, capsys, storage):
    """A bag with nut_state, axial_load and a std_msgs/Float64 motor_current topic."""
    # the project's own writer and message builders, plus one foreign topic
    from bb_friction_ros.bags import _header, _wrench, BagWriter, KIND_TYPES, Topics
    rng = np.random.default_rng(3)
    r = base.recording
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.03})])
    meas = r.torque_pred_nm + hidden.torque_nm(r.t_run_s, r.nut_angle_rad,
                                               r.nut_velocity_rad_s, r.axial_load_n)
    meas = meas + rng.normal(0.0, 0.003, len(r))
    bag = tmp_path / "bag"
    topics = Topics()
    with BagWriter(bag, storage=storage) as out:
        st = out.store
        conns = {k: out.connection(topics.absolute(k), t) for k, t in KIND_TYPES.items()
                 if k != "measured_torque"}
        cur = out.connection("/motor_current", "std_msgs/msg/Float64")
        k = 0
        for ev in base.events:
            if ev.kind == "nut_state":
                msg = st.types["sensor_msgs/msg/JointState"](
                    header=_header(st, ev.stamp_s), name=list(ev.names),
                    position=np.asarray(ev.positions, float),
                    velocity=np.asarray(ev.velocities, float), effort=np.zeros(0))
                out.write(conns["nut_state"], int(round(ev.stamp_s * 1e9)), msg)
                out.write(cur, int(round(ev.stamp_s * 1e9)),
                          st.types["std_msgs/msg/Float64"](data=float(meas[k] / K_NM_PER_A)))
                k += 1
            elif ev.kind == "axial_load":
                out.write(conns["axial_load"], int(round(ev.stamp_s * 1e9)),
                          _wrench(st, ev.stamp_s, force_z=ev.value))
    assert run_cli(["--no-physical", bag, "--out", tmp_path / "o", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert [e["name"] for e in s["effects"]] == ["seal_drag"]
    assert s["effects"][0]["params"]["torque_nm"] == pytest.approx(0.03, rel=0.05)
    assert "topic motor_current (motor current) x 0.0625 N m/A" in \
        s["input"]["measured_torque_source"]
    assert run_cli(["--no-physical", bag, "--out", tmp_path / "p", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A, "--current-topic", "amps"]) == 2
    err = capsys.readouterr().err
    assert "no motor current: topic /amps is missing" in err and "--current-topic" in err
