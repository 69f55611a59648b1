"""
Point-to-point moves of a servo axis, sampled at any rate: sharp acceleration edges.

A servo axis driven with trapezoidal velocity profiles has a piecewise-constant acceleration
that jumps at the start and the end of every ramp.  That is what a fixed 10 Hz acceleration
filter cannot follow, and what makes the cut-off depend on the recording.  The motion is
computed exactly (alpha piecewise constant, omega and the angle integrated in closed form)
and sampled at ``rate_hz``, as a recorder would, so one drive can be "recorded" at 10 Hz and
at 2 kHz.  The measured torque is the rigid-body drive J alpha + c omega + T_c sign(omega)
plus white noise; there is no model of a screw (``torque_pred_nm`` = 0, baseline zero).
Used by test/discrepancy/test_bandwidth.py and bench/bench_discrepancy.py.
"""

import dataclasses

import numpy as np

from bb_friction_ros.discrepancy.data import Recording, run_times
from bb_friction_ros.empirical_terms import dahl_state


@dataclasses.dataclass(frozen=True)
class Drive:
    """The hidden drive: inertia [kg m^2], viscous [N m s/rad], Coulomb [N m], noise [N m]."""

    j_kg_m2: float = 2e-4
    c_nm_s_per_rad: float = 4e-4
    coulomb_nm: float = 0.02
    noise_nm: float = 0.002
    # > 0: the Coulomb friction pre-rolls over this nut rotation after a reversal (a Dahl
    # element, T_c z instead of T_c sign(omega): empirical_terms.dahl_state) [rad]
    pre_rolling_rad: float = 0.0


def move_profile(rng, duration_s):
    """
    Return the breakpoints (t [s], alpha [rad/s^2] from t on) of random trapezoidal moves.

    Each move: ramp to a cruise speed of 2-30 rad/s (either sign) at 100-1000 rad/s^2, cruise
    0.15-0.5 s, ramp back to rest, dwell 0.05-0.2 s.
    """
    t, times, alphas = 0.0, [], []
    while t < duration_s:
        speed = rng.uniform(2.0, 30.0) * rng.choice([-1.0, 1.0])
        accel = rng.uniform(100.0, 1000.0)
        ramp = abs(speed) / accel
        for a, dur in ((np.sign(speed) * accel, ramp), (0.0, rng.uniform(0.15, 0.5)),
                       (-np.sign(speed) * accel, ramp), (0.0, rng.uniform(0.05, 0.2))):
            times.append(t)
            alphas.append(a)
            t += dur
    return np.array(times), np.array(alphas)


def sample_moves(times, alphas, t_s):
    """Return (angle [rad], omega [rad/s], alpha [rad/s^2]) of the profile at ``t_s``."""
    dt = np.diff(times)
    w0 = np.concatenate(([0.0], np.cumsum(alphas[:-1] * dt)))
    p0 = np.concatenate(([0.0], np.cumsum(w0[:-1] * dt + 0.5 * alphas[:-1] * dt ** 2)))
    k = np.clip(np.searchsorted(times, t_s, side="right") - 1, 0, times.size - 1)
    tau = t_s - times[k]
    w = w0[k] + alphas[k] * tau
    w[np.abs(w) < 1e-9] = 0.0            # at rest exactly, not a rounding residue
    return p0[k] + w0[k] * tau + 0.5 * alphas[k] * tau ** 2, w, alphas[k]


def servo_recording(rate_hz, duration_s=10.0, drive=Drive(), seed=0):
    """
    Return (Recording, hidden torque [N m]) of the moves sampled at ``rate_hz``.

    The same ``seed`` gives the same physical motion at every rate.
    """
    rng = np.random.default_rng(seed)
    times, alphas = move_profile(rng, duration_s)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    phi, w, a = sample_moves(times, alphas, t)
    coulomb = np.sign(w) if not drive.pre_rolling_rad > 0.0 else \
        dahl_state(phi, t, drive.pre_rolling_rad, w)
    hidden = (drive.j_kg_m2 * a + drive.c_nm_s_per_rad * w + drive.coulomb_nm * coulomb)
    noise = np.random.default_rng(seed + 1).normal(0.0, drive.noise_nm, t.size)
    n = t.size
    rec = Recording(t, run_times(t), phi, w, np.full(n, 1000.0), hidden + noise, np.zeros(n),
                    np.ones(n, dtype=bool),
                    {"input": f"servo moves at {rate_hz:g} Hz", "baseline": "zero",
                     "prediction_source": "none (synthetic servo moves)"})
    return rec, hidden
