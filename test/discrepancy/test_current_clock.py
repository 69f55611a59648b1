"""
A motor current without a header is put on the motion's clock before it is aligned.

The current has only its bag log time; the motion is placed at its header stamps.  Both went
through one recorder, so the nut states' own log times tell the offset between the clocks.
Without it a recorder latency of 10 ms moved the current 10 ms against the motion.
"""

import json

import numpy as np
import pytest

from bb_friction_ros.bags import _header, _wrench, BagWriter, KIND_TYPES, Topics
from bb_friction_ros.discrepancy.data import current_on_header_clock, InputProblem
from bb_friction_ros.empirical_terms import make_term, TermSet

from .test_discrepancy_inputs import run_cli

K_NM_PER_A = 0.0625


def _bag(base, path, latency_s, clock_offset_s=0.0, current_shift_s=0.0):
    """nut_state, axial_load and a headerless motor current, logged ``latency_s`` late."""
    rng = np.random.default_rng(3)
    r = base.recording
    hidden = TermSet([make_term("seal_drag", {"torque_nm": 0.03}),
                      make_term("viscous_drag", {"c_nm_s_per_rad": 0.003})])
    meas = r.torque_pred_nm + hidden.torque_nm(r.t_run_s, r.nut_angle_rad,
                                               r.nut_velocity_rad_s, r.axial_load_n)
    meas = meas + rng.normal(0.0, 0.002, len(r))
    topics = Topics()
    with BagWriter(path) as out:
        st = out.store
        conns = {k: out.connection(topics.absolute(k), t) for k, t in KIND_TYPES.items()
                 if k != "measured_torque"}
        cur = out.connection("/motor_current", "std_msgs/msg/Float64")
        k = 0
        for ev in base.events:
            log_ns = int(round((ev.stamp_s + clock_offset_s + latency_s) * 1e9))
            if ev.kind == "nut_state":
                msg = st.types["sensor_msgs/msg/JointState"](
                    header=_header(st, ev.stamp_s), name=list(ev.names),
                    position=np.asarray(ev.positions, float),
                    velocity=np.asarray(ev.velocities, float), effort=np.zeros(0))
                out.write(conns["nut_state"], log_ns, msg)
                out.write(cur, log_ns + int(round(current_shift_s * 1e9)),
                          st.types["std_msgs/msg/Float64"](data=float(meas[k] / K_NM_PER_A)))
                k += 1
            elif ev.kind == "axial_load":
                out.write(conns["axial_load"], log_ns, _wrench(st, ev.stamp_s, force_z=ev.value))
    return path


def _run(bag, out):
    assert run_cli(["--no-physical", bag, "--out", out, "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 0
    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("latency_s, clock_offset_s", [(0.010, 0.0), (0.005, 1.7e9)],
                         ids=["recorder_latency", "device_clock"])
def test_recorder_latency_does_not_move_the_current(base, tmp_path, latency_s, clock_offset_s):
    ref = _run(_bag(base, tmp_path / "a", 0.0), tmp_path / "ra")
    late = _run(_bag(base, tmp_path / "b", latency_s, clock_offset_s), tmp_path / "rb")
    assert [e["name"] for e in late["effects"]] == [e["name"] for e in ref["effects"]]
    assert late["rmse_after_nm"] == pytest.approx(ref["rmse_after_nm"], rel=0.02)
    said = late["input"]["current_time_base"]
    assert said["offset_median_s"] == pytest.approx(-(latency_s + clock_offset_s), abs=1e-6)


def test_current_recorded_at_another_time_is_refused_with_both_spans(base, tmp_path, capsys):
    bag = _bag(base, tmp_path / "c", 0.0, current_shift_s=1e4)
    assert run_cli(["--no-physical", bag, "--out", tmp_path / "o", "--no-progress", "--no-plots",
                    "--torque-constant-nm-per-a", K_NM_PER_A]) == 2
    err = capsys.readouterr().err
    assert "do not overlap in log time" in err and "nut_state" in err


def test_clock_offset_is_smoothed_and_held_at_the_ends():
    log = np.arange(200) * 0.01
    jitter = np.random.default_rng(1).uniform(0.0, 0.002, log.size)
    stamp = log - 0.010 - jitter            # the recorder logs 10-12 ms after the stamp
    mapped, said = current_on_header_clock(np.array([-1.0, 0.5, 5.0]), log, stamp, "x")
    assert said["offset_median_s"] == pytest.approx(-0.011, abs=5e-4)
    assert mapped == pytest.approx([-1.011, 0.489, 4.989], abs=1e-3)
    with pytest.raises(InputProblem, match="do not overlap"):
        current_on_header_clock(np.array([10.0, 11.0]), log, stamp, "x")
