"""
A hidden pre-rolling travel is named by the workflow and its travel fitted within 25 %.

Servo moves at 1 kHz from rest in either direction; the hidden drive's Coulomb friction
builds up over the travel after each reversal (a Dahl element), on top of inertia, viscous
and Coulomb drag.  No model of a screw: the workflow sees the measured torque alone.
"""

import numpy as np
import pytest

from bb_friction_ros.discrepancy.selection import pre_rolling_grid
from bb_friction_ros.discrepancy.servo_moves import Drive, servo_recording
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.workflow import analyse, inputs_of

TRAVEL_TOLERANCE = 0.25
DURATION_S = 12.0


def _fitted(rec):
    a = analyse(rec, DiscrepancySettings())
    return {t.name: t.params for t in a.terms.terms}, a


@pytest.mark.parametrize("travel_rad, seed", [(0.003, 3), (0.01, 4)])
def test_hidden_pre_rolling_travel_is_named_and_fitted(travel_rad, seed):
    """0.003 and 0.01 rad: 10 and 32 um of axial travel at a 20 mm lead."""
    drive = Drive(coulomb_nm=0.03, pre_rolling_rad=travel_rad)
    rec, _ = servo_recording(1000.0, DURATION_S, drive, seed=seed)
    terms, _ = _fitted(rec)
    assert "pre_rolling" in terms, terms
    p = terms["pre_rolling"]
    assert abs(p.travel_rad / travel_rad - 1.0) <= TRAVEL_TOLERANCE
    assert p.torque_nm == pytest.approx(drive.coulomb_nm, rel=0.25)


def test_no_pre_rolling_is_named_where_there_is_none():
    rec, _ = servo_recording(1000.0, DURATION_S, Drive(coulomb_nm=0.03), seed=3)
    terms, _ = _fitted(rec)
    assert "pre_rolling" not in terms and "seal_drag" in terms


def test_a_recorder_too_slow_to_see_it_leaves_pre_rolling_untested():
    rec, _ = servo_recording(20.0, DURATION_S, Drive(coulomb_nm=0.03, pre_rolling_rad=0.003),
                             seed=3)
    why = pre_rolling_grid(inputs_of(rec), DiscrepancySettings())
    assert isinstance(why, str) and "too far apart" in why
    _, a = _fitted(rec)
    assert "pre_rolling" in a.untested and "pre_rolling" not in a.terms.names


def test_travel_grid_starts_where_the_recording_resolves_it():
    rec, _ = servo_recording(1000.0, DURATION_S, Drive(), seed=3)
    s = DiscrepancySettings()
    grid = pre_rolling_grid(inputs_of(rec), s)
    assert grid[-1] == pytest.approx(s.pre_rolling_max_travel_rad)
    assert grid[0] >= s.pre_rolling_min_travel_rad and np.all(np.diff(grid) > 0)
