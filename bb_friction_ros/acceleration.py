"""
The nut acceleration: one filter, zero-phase for the analysis, causal in the runner.

The inertia term needs alpha, the derivative of the measured nut velocity, low-passed at a
cut-off ``accel_cutoff_hz``: ``AccelerationFilter`` runs causally in the node (one sample at
a time), ``zero_phase_acceleration`` forward and backward over a recording's segments.
"""

import functools
import math

import numpy as np

# Time resolution of the filter's step [s]: stamps closer than this are one instant, and the
# discretisation is cached per step at this resolution (jittery 1 kHz stamps: a few hundred
# distinct steps, not one per sample).
FILTER_STEP_RESOLUTION_S = 1e-6


@functools.lru_cache(maxsize=4096)
def _filter_step(cutoff_hz, step_us):
    """
    Return (Phi, G0, G1) of one step of the velocity filter, exact for a linear input.

    The filter is the 2nd-order Butterworth low-pass y'' + sqrt(2) wc y' + wc^2 y = wc^2 v
    (state [y, y'], y' = alpha).  Over a step of dt the input is taken linear between the
    two samples (first-order hold, exact for a ramp of velocity, i.e. constant acceleration):
    s(dt) = Phi s(0) + G0 v0 + G1 (v1 - v0), from the matrix exponential of the augmented
    system (van Loan).
    """
    from scipy.linalg import expm
    dt = step_us * FILTER_STEP_RESOLUTION_S
    wc = 2.0 * math.pi * cutoff_hz
    m = np.zeros((4, 4))
    m[0, 1] = 1.0
    m[1, 0], m[1, 1], m[1, 2] = -wc * wc, -math.sqrt(2.0) * wc, wc * wc
    m[2, 3] = 1.0 / dt
    e = expm(m * dt)
    return (float(e[0, 0]), float(e[0, 1]), float(e[1, 0]), float(e[1, 1]),
            float(e[0, 2]), float(e[1, 2]), float(e[0, 3]), float(e[1, 3]))


def filter_lag_s(cutoff_hz):
    """Return the low-frequency group delay [s] of the causal filter: sqrt(2) / (2 pi fc)."""
    return math.sqrt(2.0) / (2.0 * math.pi * cutoff_hz)


class AccelerationFilter:
    """
    Causal nut acceleration from the nut velocity, one sample at a time (node and replay).

    alpha is the derivative of the velocity low-passed by a 2nd-order Butterworth at
    ``cutoff_hz`` (``_filter_step``).  It lags the true acceleration by about
    sqrt(2) / (2 pi fc) (22 ms at 10 Hz: ``filter_lag_s``).  A new segment starts, with the
    filter at rest on the new velocity (alpha = 0), at the first sample, after ``reset``, after
    a backward stamp and after a step longer than ``max_gap_s``: the filter never runs across
    a gap.  ``zero_phase_acceleration`` runs this same filter forward and backward.
    """

    def __init__(self, cutoff_hz, max_gap_s):
        """Filter at ``cutoff_hz`` [Hz]; restart after gaps longer than ``max_gap_s`` [s]."""
        if not (cutoff_hz > 0 and max_gap_s > 0):
            raise ValueError(f"cutoff_hz and max_gap_s must be > 0, got {cutoff_hz}, "
                             f"{max_gap_s}")
        self.cutoff_hz = float(cutoff_hz)
        self.max_gap_s = float(max_gap_s)
        self.reset()

    def reset(self):
        """Forget the state: the next sample starts a new segment."""
        self._stamp = None
        self._v = self._y = self._a = 0.0

    def update(self, stamp_s, velocity_rad_s):
        """Take one sample; return the filtered acceleration [rad/s^2] at it."""
        v = float(velocity_rad_s)
        if self._stamp is not None:
            dt = stamp_s - self._stamp
            if 0.0 <= dt <= self.max_gap_s:
                steps = int(round(dt / FILTER_STEP_RESOLUTION_S))
                if steps > 0:
                    p00, p01, p10, p11, g0y, g0a, g1y, g1a = _filter_step(self.cutoff_hz, steps)
                    y, a = self._y, self._a
                    self._y = p00 * y + p01 * a + g0y * self._v + g1y * (v - self._v)
                    self._a = p10 * y + p11 * a + g0a * self._v + g1a * (v - self._v)
                    self._stamp, self._v = stamp_s, v
                return self._a
        self._stamp, self._v, self._y, self._a = stamp_s, v, v, 0.0
        return 0.0


def segments(t_s, max_gap_s):
    """Return [(start, stop)] of the continuous segments: split at backward stamps and gaps."""
    t = np.asarray(t_s, dtype=float)
    if t.size == 0:
        return []
    dt = np.diff(t)
    cut = np.flatnonzero((dt < 0.0) | (dt > max_gap_s)) + 1
    edges = np.concatenate(([0], cut, [t.size]))
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def zero_phase_acceleration(t_s, velocity_rad_s, cutoff_hz, max_gap_s, min_segment_samples=5):
    """
    Return the nut acceleration [rad/s^2] for analysis, with zero phase (no lag).

    ``AccelerationFilter`` runs forward, then backward in time on its output, per continuous
    segment.

    The derivative is the backward pass's own rate state (negated: its time runs backwards),
    so no numerical differentiation adds noise.  Segments shorter than
    ``min_segment_samples`` get NaN: too short to derive an acceleration.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(velocity_rad_s, dtype=float)
    out = np.full(t.size, np.nan)
    for lo, hi in segments(t, max_gap_s):
        if hi - lo < min_segment_samples:
            continue
        steps = np.rint(np.diff(t[lo:hi]) / FILTER_STEP_RESOLUTION_S)
        if steps.size and steps[0] > 0 and np.all(steps == steps[0]):
            out[lo:hi] = _uniform_zero_phase(v[lo:hi], cutoff_hz, int(steps[0]))
            continue
        f = AccelerationFilter(cutoff_hz, math.inf)
        y = np.empty(hi - lo)
        for i in range(lo, hi):
            f.update(t[i], v[i])
            y[i - lo] = f._y
        b = AccelerationFilter(cutoff_hz, math.inf)
        for j, i in enumerate(range(hi - 1, lo - 1, -1)):
            out[i] = -b.update(-t[i], y[hi - 1 - lo - j])
    return out


@functools.lru_cache(maxsize=256)
def _uniform_transfer(cutoff_hz, step_us):
    """
    Return (b_y, b_alpha, a) of the filter's step at a uniform period, as z-transfer functions.

    The state recursion s_k+1 = Phi s_k + G0 v_k + G1 (v_k+1 - v_k) of ``_filter_step`` is
    linear and time-invariant at a fixed period, so from rest it is an IIR filter of the
    velocity (y and alpha outputs): scipy's lfilter runs it in C.  Measured need: the
    acceleration cut-off is chosen by cross-validation over a grid, a per-sample
    Python loop per grid value took ~2 s on a 25,000-sample recording; this takes ~2 ms and
    agrees with the loop to 1e-13 of the peak.
    """
    from scipy.signal import ss2tf
    p00, p01, p10, p11, g0y, g0a, g1y, g1a = _filter_step(cutoff_hz, step_us)
    phi = np.array([[p00, p01], [p10, p11]])
    b0 = np.array([[g0y - g1y], [g0a - g1a]])      # the input at step k
    b1 = np.array([[g1y], [g1a]])                  # the input at step k + 1 (enters as z b1)
    out = []
    for c in ([[1.0, 0.0]], [[0.0, 1.0]]):
        n0, den = ss2tf(phi, b0, np.array(c), np.zeros((1, 1)))
        n1, _ = ss2tf(phi, b1, np.array(c), np.zeros((1, 1)))
        out.append(np.array([n1[0][1], n1[0][2] + n0[0][1], n0[0][2]]))
    return out[0], out[1], den


def _uniform_zero_phase(v, cutoff_hz, step_us):
    """Zero-phase acceleration of one segment at a uniform period (see ``_uniform_transfer``)."""
    from scipy.signal import lfilter
    by, ba, den = _uniform_transfer(cutoff_hz, step_us)
    # at rest on the first value: a linear filter of (v - v0) from zero state, y offset by v0
    y = lfilter(by, den, v - v[0]) + v[0]
    back = y[::-1]
    return -lfilter(ba, den, back - back[0])[::-1]
