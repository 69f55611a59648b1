"""
The analysis cuts a recording into runs exactly where the runner resets.

A stamp a little behind the one before (jitter, a delayed driver thread) is a late sample
for the runner: answered, no reset.  The analysis used to start a new run there, restarting
the clock of time-dependent terms (a warm-up drift was then missed).
"""

import dataclasses
import json

import numpy as np
import pytest

from bb_friction_ros.bags import LATE_STAMP_TOLERANCE_S
from bb_friction_ros.discrepancy.data import check_time_order, run_times
from bb_friction_ros.discrepancy.synthetic import synthesize
from bb_friction_ros.empirical_terms import make_term, TermSet
from bb_friction_ros.runner import run_starts

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv


@pytest.fixture(scope="module")
def drifting(base):
    """Viscous and seal drag and a 40 mN m warm-up drift on top of the model."""
    rng = np.random.default_rng(2)
    hidden = TermSet([make_term("viscous_drag", {"c_nm_s_per_rad": 0.002}),
                      make_term("seal_drag", {"torque_nm": 0.03}),
                      make_term("thermal_drift", {"delta_torque_nm": 0.04,
                                                  "time_constant_s": 3.0})])
    rec, _ = synthesize(base, hidden, 0.003, rng)
    return rec


def test_run_starts_follow_the_runner_rule():
    t = np.array([0.0, 0.01, 0.02, 0.0095, 0.03, 0.04, 0.035, 0.034, 0.033, 0.032, 0.5,
                  0.0, 0.01])
    starts, late = run_starts(t)
    assert np.flatnonzero(starts).tolist() == [0, 9, 11]   # 4th late in a row; a loop
    assert np.flatnonzero(late).tolist() == [3, 6, 7, 8]
    assert run_times(t)[4] == pytest.approx(0.03)          # the clock went on
    back = np.array([0.0, 0.01, 0.01 - LATE_STAMP_TOLERANCE_S - 1e-3, 0.03])
    assert np.flatnonzero(run_starts(back)[0]).tolist() == [0, 2]


def test_a_file_with_late_rows_is_one_run_not_rows_out_of_order(tmp_path):
    t = np.arange(100) * 0.001
    t[50] = t[49] - 0.0105
    assert check_time_order(tmp_path / "x.csv", t) == 1


def _summary(path, out):
    assert run_cli(["--no-physical", path, "--out", out, "--no-progress", "--no-plots"]) == 0
    return json.loads((out / "summary.json").read_text())


def _late(rec, t):
    return dataclasses.replace(rec, t_s=t)


@pytest.mark.parametrize("how", ["one_late_stamp", "jitter"])
def test_late_stamps_leave_the_analysis_as_it_was(drifting, tmp_path, how):
    clean = _summary(write_csv(tmp_path / "clean.csv", drifting), tmp_path / "c")
    t = drifting.t_s.copy()
    if how == "one_late_stamp":
        i = t.size // 3
        t[i] = t[i - 1] - 0.0105            # 10.5 ms behind the sample before it
    else:
        step = float(np.median(np.diff(t)))
        t = t + np.random.default_rng(4).uniform(-0.7, 0.7, t.size) * step
    assert run_starts(t)[1].any()           # the runner does see late samples
    late = _summary(write_csv(tmp_path / "late.csv", _late(drifting, t)), tmp_path / "l")
    names = [e["name"] for e in clean["effects"]]
    assert "thermal_drift" in names
    assert [e["name"] for e in late["effects"]] == names
    assert late["rmse_after_nm"] == pytest.approx(clean["rmse_after_nm"], rel=0.15)
