"""
Where the model disagrees: the noise level and the residual per operating regime.

The noise level is estimated from the data, not assumed: the residual's differences remove
everything that changes slowly from sample to sample (every candidate effect does), and a
median absolute deviation ignores the few steps at reversals.  For white noise of std sigma
the differences have std sigma sqrt(2).  Measured torque is often smooth at the sample rate,
so the lag grows until the noise has decorrelated (``noise_model``).

A regime is a bin of one variable: direction, |nut speed| per direction, nut angle within a
revolution, axial load, time, acceleration (accelerating / decelerating) and the nut's travel
along the stroke.  Per bin we report the mean residual and the mean "drag excess"
(residual times sign(omega), over moving samples: a dissipative effect cancels in the plain
mean over both directions but not in this one), each with its z-value against the noise
standard error.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.runner import run_starts

# Median absolute deviation -> standard deviation for a normal distribution.
MAD_TO_STD = 1.4826


# Two samples are in the same operating state when their speeds differ by less than this
# fraction: then every candidate effect (a function of speed, direction, slow time) is nearly
# equal at both, and their difference is noise.
SAME_STATE_SPEED_FRACTION = 0.05
# Pairs a lag needs for its estimate to count (fewer: the lag is too long for the recording).
MIN_NOISE_PAIRS = 100


def _diff_std(r, lag, same=None):
    d = r[lag:] - r[:-lag]
    if same is not None:
        d = d[same(lag)]
    if d.size < MIN_NOISE_PAIRS:
        return float("nan")
    return float(MAD_TO_STD * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


def _same_state(velocity, stamps):
    """
    Return lag -> mask of the pairs (i, i + lag) in one operating state and one run.

    The speed tolerance is SAME_STATE_SPEED_FRACTION of the speed, and at least 3 times the
    velocity signal's own sample-to-sample scatter (a quantised encoder speed jitters by a
    count: that is still one operating state).
    """
    w = np.asarray(velocity, dtype=float)
    run = np.cumsum(run_starts(stamps)[0]) if stamps is not None else np.zeros(w.size)
    dw = np.diff(w)
    jitter = 3.0 * MAD_TO_STD * float(np.median(np.abs(dw - np.median(dw)))) \
        if dw.size else 0.0

    def same(lag):
        a, b = w[:-lag], w[lag:]
        tol = np.maximum(SAME_STATE_SPEED_FRACTION * np.maximum(np.abs(a), np.abs(b)), jitter)
        return (np.abs(a - b) <= tol) & (np.sign(a) == np.sign(b)) & \
            (run[:-lag] == run[lag:])
    return same


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """
    The noise of a residual: its std and its integrated autocorrelation time.

    ``std_nm`` is the plateau of the lag-L difference estimate (below), ``lag`` the L it was
    read at, ``std_lag1_nm`` the classic lag-1 value and ``tau`` (samples, >= 1) the
    integrated autocorrelation time 1 + 2 sum_k rho_k, with rho_k = 1 - (std_k / std)^2
    from the lag-k estimates (interpolated between the doubling lags, 0 beyond L).  A mean
    over n samples then has the standard error std sqrt(tau / n), and the evidence of n
    correlated samples is that of n / tau independent ones.
    """

    std_nm: float
    std_lag1_nm: float
    lag: int
    tau: float

    def as_dict(self):
        """Return the JSON form."""
        return {"std_nm": self.std_nm, "std_lag1_nm": self.std_lag1_nm, "lag_samples": self.lag,
                "autocorrelation_time_samples": self.tau}


def noise_model(residual_nm, max_lag=64, plateau_ratio=1.1, velocity=None, stamps=None):
    """
    Estimate the noise of a residual [N m] from its differences at growing lags.

    The MAD of lag-L differences, x 1.4826 / sqrt(2), is the noise std once the noise has
    decorrelated over L samples, while every candidate effect (slow in time) still cancels
    and the MAD ignores the few steps at reversals.  White noise decorrelates at L = 1.
    Measured torque is often smooth at the sample rate (an averaging recorder, a sensor
    filter): its noise is correlated, the lag-1 estimate is several times too small, and a
    regime table built on it calls everything significant.  So L doubles from 1 until the
    estimate grows by less than ``plateau_ratio`` (or reaches ``max_lag``).

    With the nut ``velocity`` (and ``stamps``, whose backward steps start new runs), only
    pairs of samples in the same operating state count at lags above 1: the same direction,
    speeds within SAME_STATE_SPEED_FRACTION, one run.  So a long lag does not straddle a
    reversal or a speed change, where the effects themselves step.
    """
    r = np.asarray(residual_nm, dtype=float)
    ok = np.isfinite(r)
    r = r[ok]
    if r.size < 3:
        return NoiseModel(float("nan"), float("nan"), 1, 1.0)
    same = None
    if velocity is not None:
        same = _same_state(np.asarray(velocity, float)[ok],
                           None if stamps is None else np.asarray(stamps, float)[ok])
    s1 = _diff_std(r, 1)
    lags, stds = [1], [s1]
    while 2 * lags[-1] <= max_lag and 2 * lags[-1] < r.size // 4:
        s2 = _diff_std(r, 2 * lags[-1], same)
        if not s2 < math.inf or s2 < plateau_ratio * stds[-1]:
            break
        lags.append(2 * lags[-1])
        stds.append(s2)
    lag, s = lags[-1], stds[-1]
    tau = 1.0
    if s > 0 and lag > 1:
        rho = np.clip(1.0 - (np.array(stds) / s) ** 2, 0.0, 1.0)
        k = np.arange(1, lag + 1)
        tau = 1.0 + 2.0 * float(np.sum(np.interp(k, lags, rho)))
    return NoiseModel(s, s1, lag, tau)


def noise_std_nm(residual_nm):
    """Return the robust noise std [N m] of a residual (``noise_model`` with defaults)."""
    return noise_model(residual_nm).std_nm


@dataclasses.dataclass(frozen=True)
class Bin:
    """One regime: samples where lo <= value(variable) < hi (and the direction, if any)."""

    variable: str
    label: str
    lo: float
    hi: float
    direction: int = 0        # +1 / -1: only moving samples of that direction; 0: all


def _value(variable, x):
    if variable in ("direction", "speed"):
        return np.abs(x.nut_velocity_rad_s)
    if variable == "acceleration":
        return x.nut_accel_rad_s2
    if variable == "stroke":
        return x.nut_angle_rad
    if variable == "angle":
        return np.mod(x.nut_angle_rad, 2.0 * math.pi)
    if variable == "load":
        return x.axial_load_n
    return x.t_s


def mask_of(b, x, standstill_rad_s):
    """Return the boolean mask of bin ``b`` over inputs ``x`` (an empirical_terms.Inputs)."""
    v = _value(b.variable, x)
    m = (v >= b.lo) & (v < b.hi)
    if b.direction:
        m &= (np.sign(x.nut_velocity_rad_s) == b.direction)
        m &= np.abs(x.nut_velocity_rad_s) > standstill_rad_s
    return m


def _quantile_edges(values, bins):
    edges = np.unique(np.quantile(values, np.linspace(0.0, 1.0, bins + 1)))
    if edges.size < 2:
        edges = np.array([values.min(), values.min()])
    edges[-1] = np.nextafter(edges[-1], np.inf)          # include the largest sample
    return edges


def _fmt(v):
    return f"{v:.3g}"


def make_bins(x, settings):
    """Return the regime bins for inputs ``x``; the same bins serve every table."""
    s = settings.standstill_speed_rad_s
    speed = np.abs(x.nut_velocity_rad_s)
    bins = [Bin("direction", "positive", s, math.inf, +1),
            Bin("direction", "negative", s, math.inf, -1),
            Bin("direction", "standstill", 0.0, s if s > 0 else np.nextafter(0.0, 1.0))]
    for sign, name in ((+1, "+"), (-1, "-")):
        moving = speed[(np.sign(x.nut_velocity_rad_s) == sign) & (speed > s)]
        if moving.size == 0:
            continue
        edges = _quantile_edges(moving, settings.speed_bins)
        for lo, hi in zip(edges[:-1], edges[1:]):
            bins.append(Bin("speed", f"{name}[{_fmt(lo)}, {_fmt(hi)}] rad/s", lo, hi, sign))
    step = 2.0 * math.pi / settings.angle_bins
    for k in range(settings.angle_bins):
        lo = k * step
        bins.append(Bin("angle", f"[{math.degrees(lo):.0f}, {math.degrees(lo + step):.0f}) "
                        "deg", lo, lo + step))
    for variable, values, n, unit in (("load", x.axial_load_n, settings.load_bins, "N"),):
        edges = _quantile_edges(values, n)
        for lo, hi in zip(edges[:-1], edges[1:]):
            bins.append(Bin(variable, f"[{_fmt(lo)}, {_fmt(hi)}] {unit}", lo, hi))
    if x.nut_accel_rad_s2 is not None:
        bins += _accel_bins(x, settings)
    lo, hi = float(np.min(x.nut_angle_rad)), float(np.max(x.nut_angle_rad))
    if hi > lo:
        edges = np.linspace(lo, hi, settings.stroke_bins + 1)
        edges[-1] = np.nextafter(edges[-1], np.inf)
        for a, b in zip(edges[:-1], edges[1:]):
            bins.append(Bin("stroke", f"[{a / (2 * math.pi):.3g}, {b / (2 * math.pi):.3g}] "
                            "rev", a, b))
    t0, t1 = float(np.min(x.t_s)), float(np.max(x.t_s))
    edges = np.linspace(t0, t1, settings.time_bins + 1)
    edges[-1] = np.nextafter(edges[-1], np.inf)
    for lo, hi in zip(edges[:-1], edges[1:]):
        bins.append(Bin("time", f"[{_fmt(lo)}, {_fmt(hi)}] s", lo, hi))
    return bins


def _accel_bins(x, settings):
    """Bins of accelerating (alpha > 0) and decelerating (alpha < 0) samples by |alpha|."""
    a = x.nut_accel_rad_s2
    finite = np.isfinite(a)
    if not finite.any():
        return []
    floor = settings.accel_regime_fraction * float(np.percentile(np.abs(a[finite]), 99))
    out = []
    if floor <= 0:
        return out
    for sign, name in ((+1, "+"), (-1, "-")):
        mag = np.abs(a[finite & (np.sign(a) == sign) & (np.abs(a) > floor)])
        if mag.size == 0:
            continue
        edges = _quantile_edges(mag, settings.accel_bins)
        for lo, hi in zip(edges[:-1], edges[1:]):
            out.append(Bin("acceleration", f"{name}[{_fmt(lo)}, {_fmt(hi)}] rad/s^2",
                           sign * lo if sign > 0 else -hi, sign * hi if sign > 0 else -lo))
    return out


def bin_stats(b, x, residual_nm, noise_nm, settings, tau=1.0):
    """
    Return the statistics of ``residual_nm`` in bin ``b`` (a dict, JSON-ready).

    The standard error of a mean over n samples is noise sqrt(tau / n): correlated noise
    (``tau`` > 1 samples) averages out more slowly than white noise.
    """
    m = mask_of(b, x, settings.standstill_speed_rad_s) & np.isfinite(residual_nm)
    n = int(m.sum())
    row = {"variable": b.variable, "label": b.label, "n": n, "mean_residual_nm": None,
           "rms_residual_nm": None, "mean_drag_excess_nm": None, "z_mean": None,
           "z_drag": None, "significant": False}
    if n == 0:
        return row
    r = residual_nm[m]
    row["mean_residual_nm"] = float(r.mean())
    row["rms_residual_nm"] = float(np.sqrt(np.mean(r ** 2)))
    sign = np.sign(x.nut_velocity_rad_s[m])
    moving = np.abs(x.nut_velocity_rad_s[m]) > settings.standstill_speed_rad_s
    se = noise_nm * math.sqrt(tau / n) if noise_nm > 0 else math.nan
    row["z_mean"] = float(row["mean_residual_nm"] / se) if se > 0 else None
    if moving.any():
        row["mean_drag_excess_nm"] = float(np.mean(r[moving] * sign[moving]))
        se_d = noise_nm * math.sqrt(tau / int(moving.sum())) if noise_nm > 0 else math.nan
        row["z_drag"] = float(row["mean_drag_excess_nm"] / se_d) if se_d > 0 else None
    row["significant"] = n >= settings.min_bin_samples and any(
        _is_significant(mean, z, noise_nm, settings)
        for mean, z in ((row["mean_residual_nm"], row["z_mean"]),
                        (row["mean_drag_excess_nm"], row["z_drag"])))
    return row


def _is_significant(mean, z, noise_nm, settings):
    if mean is None or z is None:
        return False
    return abs(z) >= settings.flag_z and abs(mean) >= settings.flag_min_bias_fraction \
        * noise_nm


def regime_table(bins, x, residual_nm, noise_nm, settings, tau=1.0):
    """Return one stats row per bin."""
    return [bin_stats(b, x, np.asarray(residual_nm, float), noise_nm, settings, tau)
            for b in bins]
