"""Fig. 21 features of a whole-screw run: the smoothed peak angle beside the raw one."""

import math

import numpy as np
import pytest

from bb_friction_ros.ball_screw import simulation as sim

STEP = math.radians(3.6)          # the paper's step (200 steps over 720 deg)


def _hump_with_jitter(centre_deg=120.0):
    """
    A B2B share hump over 720 deg, a 0.05 step-to-step jitter and one outlier step.

    The outlier (a contact that closes a step early) sits 10 steps past the hump's top and
    beats it: the raw peak lands on it, 36 deg off.
    """
    angle = STEP * np.arange(1, 201)
    share = 0.4 * np.exp(-0.5 * ((np.degrees(angle) - centre_deg) / 40.0) ** 2)
    share += 0.05 * (np.arange(angle.size) % 2)
    share[np.argmin(np.abs(np.degrees(angle) - centre_deg)) + 10] += 0.2
    return angle, share


def test_smoothed_peak_finds_the_hump_the_raw_peak_misses():
    angle, share = _hump_with_jitter()
    f = sim.fig21_features(angle, np.ones_like(share), share, np.ones(share.size, int))
    assert math.degrees(f["peak_b2b_nut_angle_rad"]) == pytest.approx(156.0, abs=3.6)
    assert math.degrees(f["peak_b2b_nut_angle_smoothed_rad"]) == pytest.approx(120.0, abs=3.6)


def test_window_zero_is_the_raw_peak_and_bad_windows_are_refused():
    angle, share = _hump_with_jitter()
    args = (angle, np.ones_like(share), share, np.ones(share.size, int))
    f = sim.fig21_features(*args, smoothing_window_rad=0.0)
    assert f["peak_b2b_nut_angle_smoothed_rad"] == f["peak_b2b_nut_angle_rad"]
    for bad in (-STEP, math.nan, math.inf):
        with pytest.raises(ValueError, match="window_rad"):
            sim.fig21_features(*args, smoothing_window_rad=bad)


def test_moving_average_keeps_a_constant_and_spans_the_window():
    angle = STEP * np.arange(50)
    np.testing.assert_allclose(sim.moving_average(np.full(50, 2.0), angle, math.radians(18)),
                               2.0)
    spike = np.zeros(50)
    spike[25] = 1.0
    avg = sim.moving_average(spike, angle, sim.PEAK_SMOOTHING_WINDOW_RAD)
    # 18 deg at 3.6 deg steps: 5 samples of 1/5
    assert np.count_nonzero(avg) == 5 and avg.max() == pytest.approx(0.2)


def test_default_window_is_between_the_jitter_and_a_group_s_life():
    """Wider than a 3.6 deg step's jitter (2 steps), far narrower than 100-200 deg groups."""
    assert 2 * STEP < sim.PEAK_SMOOTHING_WINDOW_RAD <= math.radians(30.0)
