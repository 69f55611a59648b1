"""
What a servo engineer reads off a run.

Following error, reversal glitches, cruise ripple, and for the circle test the ballbar's
radial deviation and quadrant spikes.

All lengths are the nut's axial travel, e = phi * lead / (2 pi), in micrometres at the
edge (``*_um``).

* **Following error**: reference - actual, RMS and largest magnitude over the run.
* **Reversal glitch**: at each reversal of the reference (its velocity changing sign, a
  rest in between allowed), the largest |e(t) - e(t_r)| within ``REVERSAL_WINDOW_S`` after it:
  the bump the stick phase and the friction's flip leave on the error.
* **Cruise**: the samples where the reference moves at constant speed (|alpha_ref| below
  ``CRUISE_ACCEL_FRACTION`` of its largest, |omega_ref| above ``CRUISE_SPEED_FRACTION`` of
  its largest), from ``CRUISE_SETTLE_S`` after each such stretch begins: RMS and peak to peak
  of e there (the ripple the ball-to-ball contact leaves).
* **Circle** (ISO 230-4): the radial deviation dr = sqrt(x^2 + y^2) - r of the actual path
  over the constant-feed revolutions; its range (max - min), and the quadrant spikes: at each
  axis reversal (X at 0 and 180 deg, Y at 90 and 270 deg) the largest |dr - median(dr)|
  within ``REVERSAL_WINDOW_S`` after it.
"""

import math

import numpy as np

REVERSAL_WINDOW_S = 0.05
CRUISE_ACCEL_FRACTION = 1e-3
CRUISE_SPEED_FRACTION = 0.05
CRUISE_SETTLE_S = 0.05
# A reference standing still: |omega_ref| at most this fraction of its largest.  The central
# differences of a constant angle are rounding (1e-13 rad/s after a few revolutions), not 0.
STANDING_SPEED_FRACTION = 1e-6


def standing_mask(w_ref):
    """Return the mask of the samples where the reference stands still."""
    w_abs = np.abs(w_ref)
    return w_abs <= STANDING_SPEED_FRACTION * float(w_abs.max()) if w_abs.size else w_abs > 0


def to_um(angle_rad, lead_m):
    """Return the nut travel [um] of a nut angle [rad]."""
    return np.asarray(angle_rad) * lead_m / (2.0 * math.pi) * 1e6


def reversal_indices(velocity):
    """
    Return the sample indices where the velocity's sign changes (standstill skipped).

    A standing sample (``standing_mask``: rounding, not motion) has no sign: a stop whose
    rounding comes out with the other sign is not a reversal.
    """
    v = np.asarray(velocity, dtype=float)
    sign = np.where(standing_mask(v), 0.0, np.sign(v))
    idx = np.flatnonzero(sign != 0.0)
    if idx.size < 2:
        return np.array([], dtype=int)
    s = sign[idx]
    change = np.flatnonzero(s[1:] != s[:-1]) + 1
    return idx[change]


def cruise_mask(t_s, w_ref, a_ref):
    """Return the mask of the settled constant-speed samples (module docstring)."""
    w_abs, a_abs = np.abs(w_ref), np.abs(a_ref)
    steady = (a_abs <= CRUISE_ACCEL_FRACTION * max(float(a_abs.max()), 1e-12)) \
        & (w_abs >= CRUISE_SPEED_FRACTION * max(float(w_abs.max()), 1e-12))
    out = np.zeros_like(steady)
    start = None
    for k in range(steady.size + 1):
        if k < steady.size and steady[k]:
            if start is None:
                start = k
            continue
        if start is not None:
            keep = t_s[start:k] >= t_s[start] + CRUISE_SETTLE_S
            out[start:k] = keep
            start = None
    return out


def axis_metrics(t_s, ref_rad, angle_rad, lead_m):
    """Return the following-error, reversal and cruise figures of one axis [um]."""
    e = to_um(ref_rad - angle_rad, lead_m)
    w_ref = np.gradient(ref_rad, t_s)
    a_ref = np.gradient(w_ref, t_s)
    glitches = []
    for i in reversal_indices(w_ref):
        window = (t_s >= t_s[i]) & (t_s <= t_s[i] + REVERSAL_WINDOW_S)
        glitches.append(float(np.max(np.abs(e[window] - e[i]))))
    cruise = cruise_mask(t_s, w_ref, a_ref)
    ec = e[cruise]
    return {"following_error_rms_um": float(np.sqrt(np.mean(e ** 2))),
            "following_error_max_um": float(np.max(np.abs(e))),
            "reversal_glitch_um": glitches,
            "reversal_glitch_max_um": max(glitches) if glitches else None,
            "reversal_glitch_mean_um": float(np.mean(glitches)) if glitches else None,
            "cruise_rms_um": float(np.sqrt(np.mean(ec ** 2))) if ec.size else None,
            "cruise_p2p_um": float(ec.max() - ec.min()) if ec.size else None,
            "cruise_samples": int(ec.size)}


def circle_path(t_s, runs, leads_m):
    """Return (x, y, x_ref, y_ref) [m] of a circle's two AxisRuns."""
    x = runs[0].angle_rad * leads_m[0] / (2.0 * math.pi)
    y = runs[1].angle_rad * leads_m[1] / (2.0 * math.pi)
    xr = runs[0].ref_rad * leads_m[0] / (2.0 * math.pi)
    yr = runs[1].ref_rad * leads_m[1] / (2.0 * math.pi)
    return x, y, xr, yr


def feed_mask(t_s, xr, yr):
    """Return the mask of the constant-feed samples of the circle's reference."""
    v = np.hypot(np.gradient(xr, t_s), np.gradient(yr, t_s))
    vmax = float(v.max())
    return v >= (1.0 - 1e-6) * vmax


def circle_metrics(t_s, runs, radius_m, leads_m):
    """Return the ballbar figures of a circle: radial deviation range and quadrant spikes."""
    x, y, xr, yr = circle_path(t_s, runs, leads_m)
    dr = (np.hypot(x, y) - radius_m) * 1e6
    feed = feed_mask(t_s, xr, yr)
    med = float(np.median(dr[feed]))
    spikes = []
    for axis, ref in (("x", xr), ("y", yr)):
        for i in reversal_indices(np.gradient(ref, t_s)):
            if not feed[i]:
                continue
            window = feed & (t_s >= t_s[i]) & (t_s <= t_s[i] + REVERSAL_WINDOW_S)
            k = np.flatnonzero(window)
            j = k[np.argmax(np.abs(dr[k] - med))]
            spikes.append({"axis": axis, "t_s": float(t_s[i]),
                           "angle_deg": float(np.degrees(np.arctan2(yr[i], xr[i])) % 360.0),
                           "spike_um": float(dr[j] - med)})
    return {"radial_deviation_range_um": float(dr[feed].max() - dr[feed].min()),
            "radial_deviation_median_um": med,
            "quadrant_spikes": spikes,
            "quadrant_spike_max_um": max((abs(s["spike_um"]) for s in spikes), default=None)}


def mode_metrics(reference, runs, lead_m):
    """Return the summary figures of one mode's runs."""
    t = reference.t_s
    if reference.kind == "circle":
        out = {"axes": {}}
        for run, axis, lead in zip(runs, reference.axes, reference.leads_m):
            out["axes"][axis.name] = axis_metrics(t, run.ref_rad, run.angle_rad, lead)
        for key in ("following_error_rms_um", "following_error_max_um"):
            out[key] = max(v[key] for v in out["axes"].values())
        glitches = [g for v in out["axes"].values() for g in v["reversal_glitch_um"]]
        out["reversal_glitch_max_um"] = max(glitches) if glitches else None
        cruise = [v["cruise_rms_um"] for v in out["axes"].values()
                  if v["cruise_rms_um"] is not None]
        out["cruise_rms_um"] = max(cruise) if cruise else None
        out["circle"] = circle_metrics(t, runs, reference.radius_m, reference.leads_m)
        return out
    return axis_metrics(t, runs[0].ref_rad, runs[0].angle_rad, lead_m)
