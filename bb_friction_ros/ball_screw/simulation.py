"""
Whole-screw simulation of Sec. 3.4: run, write timeseries/summary, plot Figs. 20 and 21.

Outputs of ``write_outputs``: ``timeseries.csv`` (one row per step: t_s, nut_angle_rad,
torque_total_nm, torque_b2g_nm, torque_b2b_nm, n_groups, drive_power_w, loss_w, plus
converged), ``summary.json`` (peak_b2b_share, peak_b2b_nut_angle_deg and its smoothed
value, max_groups, step_time_median_s, max_power_balance_error, ...),
``fig20_ball_distance.png`` and ``fig21_torque_split.png``.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Sec. 3.4, Figs. 20-21.

"""

import csv
import json
import math
from pathlib import Path

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew

TIMESERIES_COLUMNS = ("t_s", "nut_angle_rad", "torque_total_nm", "torque_b2g_nm",
                      "torque_b2b_nm", "n_groups", "drive_power_w", "loss_w", "converged")


def run_whole_screw(config, n_steps=None, screw=None):
    """
    Sec. 3.4: constant omega_N and W for ``duration_s`` in ``n_steps`` steps.

    Parameters
    ----------
    config : BallScrewConfig
        Screw and operating point (``operation.nut_velocity_rad_s`` [rad/s],
        ``axial_load_n`` [N], ``duration_s`` [s], ``n_steps``).
    n_steps : int, optional
        Run only the first ``n_steps`` steps (same step length).
    screw : WholeScrew, optional
        A screw to reuse (its friction maps are built once); it is reset.

    Returns
    -------
    (list of StepResult, WholeScrew)
        One result per step (torques [N m], powers [W], ball states) and the screw.

    """
    op = config.operation
    steps = op.n_steps if n_steps is None else int(n_steps)
    dt = op.duration_s / op.n_steps
    screw = WholeScrew(config) if screw is None else screw
    screw.reset(0.0)
    return [screw.step(op.nut_velocity_rad_s * k * dt, op.nut_velocity_rad_s, op.axial_load_n, dt)
            for k in range(1, steps + 1)], screw


# Width of the moving average over the nut angle behind the smoothed Fig. 21 peak angle  [rad].
# At the paper's 3.6 deg steps the raw peak of T_B2B / T_B2G jumps between neighbouring local
# maxima (a contact closes a step earlier or later), by about +-5 share points and 10 deg from
# one step size or amplitude to the next (docs/assumptions_ball_screw.md); 18 deg = 5 steps of
# 3.6 deg spans that jitter and stays well below the 100-200 deg over which a B2B group builds
# and dissolves (Fig. 20), so it moves the peak of the underlying hump very little.
PEAK_SMOOTHING_WINDOW_RAD = math.radians(18.0)


def moving_average(values, angle_rad, window_rad):
    """
    Centred moving average of ``values`` over a nut-angle window of ``window_rad`` [rad].

    The samples are taken as evenly spaced in angle (the Sec. 3.4 run); the window holds
    the odd number of samples closest to ``window_rad`` / step.  Near the ends the average
    is over the samples that exist.  ``window_rad`` = 0 returns the values unchanged.
    """
    values = np.asarray(values, dtype=float)
    if not (math.isfinite(window_rad) and window_rad >= 0.0):
        raise ValueError(f"window_rad: a finite angle >= 0 [rad] is needed, got {window_rad}")
    angle = np.asarray(angle_rad, dtype=float)
    step = float(np.median(np.abs(np.diff(angle)))) if angle.size > 1 else 0.0
    half = int(round(window_rad / step / 2.0)) if step > 0.0 else 0
    if half == 0:
        return values.copy()
    kernel = np.ones(2 * half + 1)
    total = np.convolve(values, kernel, mode="same")
    count = np.convolve(np.ones_like(values), kernel, mode="same")
    return total / count


def fig21_features(nut_angle_rad, torque_b2g_nm, torque_b2b_nm, n_groups,
                   smoothing_window_rad=PEAK_SMOOTHING_WINDOW_RAD):
    """
    Compute the features of Figs. 20-21 that the paper states from a run's series (SI).

    Returns peak_b2b_share (largest T_B2B / T_B2G; paper 49.6 %), peak_b2b_nut_angle_rad
    (where; paper 126 deg), peak_b2b_nut_angle_smoothed_rad (where the share averaged over
    ``smoothing_window_rad`` of nut angle peaks: the raw peak jitters between neighbouring
    local maxima, see ``PEAK_SMOOTHING_WINDOW_RAD``), b2b_zero_nut_angle_rad (first nut angle
    after the raw peak with no B2B torque; paper 306 deg; NaN if B2B never vanishes),
    max_groups (paper 4) and b2g_torque_variation ((max - min) / mean |T_B2G|; paper:
    "barely has variation").
    """
    angle = np.asarray(nut_angle_rad, dtype=float)
    b2g = np.asarray(torque_b2g_nm, dtype=float)
    b2b = np.asarray(torque_b2b_nm, dtype=float)
    share = np.divide(b2b, b2g, out=np.zeros_like(b2b), where=b2g != 0.0)
    k = int(np.argmax(share))
    smooth = int(np.argmax(moving_average(share, angle, smoothing_window_rad)))
    after = np.flatnonzero((np.arange(share.size) > k) & (share <= 0.0))
    return {
        "peak_b2b_share": float(share[k]),
        "peak_b2b_nut_angle_rad": float(angle[k]),
        "peak_b2b_nut_angle_smoothed_rad": float(angle[smooth]),
        "b2b_zero_nut_angle_rad": float(angle[after[0]]) if after.size else math.nan,
        "max_groups": int(np.max(n_groups)),
        "b2g_torque_variation": float((b2g.max() - b2g.min()) / np.mean(np.abs(b2g))),
    }


def summarize(results, separation_rad):
    """
    Figures of merit of a run (Fig. 21's peak B2B share and where B2B vanishes).

    Parameters
    ----------
    results : list of StepResult
        The steps of a run.
    separation_rad : float
        Azimuth separation of two touching balls  [rad].

    Returns
    -------
    dict
        ``peak_b2b_share`` (T_b2b / T_b2g, fraction), ``peak_b2b_nut_angle_deg``,
        ``peak_b2b_nut_angle_smoothed_deg`` (``fig21_features``),
        ``b2b_zero_nut_angle_deg`` [deg], ``max_groups``, ``step_time_median_s`` [s],
        ``max_power_balance_error`` [1], ``all_converged``, ``b2g_torque_variation``
        (fraction) and more (``fig21_features``).

    """
    f21 = fig21_features([r.nut_angle_rad for r in results],
                         [r.torque_b2g_nm for r in results],
                         [r.torque_b2b_nm for r in results], [r.n_groups for r in results])
    zero = f21["b2b_zero_nut_angle_rad"]
    times = np.array([r.solve_time_s for r in results])
    return {
        "peak_b2b_share": f21["peak_b2b_share"],
        "peak_b2b_nut_angle_deg": math.degrees(f21["peak_b2b_nut_angle_rad"]),
        "peak_b2b_nut_angle_smoothed_deg":
            math.degrees(f21["peak_b2b_nut_angle_smoothed_rad"]),
        "peak_smoothing_window_deg": math.degrees(PEAK_SMOOTHING_WINDOW_RAD),
        "b2b_zero_nut_angle_deg": None if math.isnan(zero) else math.degrees(zero),
        "max_groups": f21["max_groups"],
        "step_time_median_s": float(np.median(times)),
        "step_time_median_warm_s": float(np.median(times[1:])) if times.size > 1
        else float(times[0]),
        "max_power_balance_error": float(max(r.power_balance_error for r in results)),
        "all_converged": bool(all(r.converged for r in results)),
        "b2g_torque_variation": f21["b2g_torque_variation"],
        "n_steps": len(results),
        "b2b_contact_separation_deg": math.degrees(separation_rad),
    }


def plot_fig20(results, separation_rad, loop_rad, path):
    """Fig. 20: angular distance between neighbouring balls; B2B contact as black dots."""
    from matplotlib.figure import Figure
    angle = np.degrees([r.nut_angle_rad for r in results])
    fig = Figure(figsize=(8, 4.5))
    ax = fig.subplots()
    dist = []
    touch = []
    for r in results:
        # Ring pair j = (ball j, ball j+1), the order along the loop; b2b_forces_n[j] is its
        # force.  Per pair, not per sorted position, so recirculation leaves no jumps.
        phi = r.azimuth_rad
        dist.append(np.degrees(np.mod(np.roll(phi, -1) - phi, loop_rad)))
        touch.append(r.b2b_forces_n > 0.0)
    dist, touch = np.array(dist), np.array(touch)
    ax.plot(angle, dist, lw=0.6, color="0.6")
    xx = np.repeat(angle[:, None], dist.shape[1], axis=1)
    ax.plot(xx[touch], dist[touch], "k.", ms=2, label="B2B contact")
    ax.axhline(math.degrees(separation_rad), color="r", lw=0.5, ls="--",
               label="contact separation")
    ax.set_xlabel("nut rotation angle [deg]")
    ax.set_ylabel("angular distance between balls [deg]")
    ax.set_title("Fig. 20 (ours): ball spacing and B2B contact")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def plot_fig21(results, path):
    """Fig. 21: total friction torque and its ball-groove and B2B parts."""
    from matplotlib.figure import Figure
    angle = np.degrees([r.nut_angle_rad for r in results])
    fig = Figure(figsize=(8, 4.5))
    ax = fig.subplots()
    ax.plot(angle, [1e3 * r.torque_total_nm for r in results], "k", label="total")
    ax.plot(angle, [1e3 * r.torque_b2g_nm for r in results], "b", label="ball-groove")
    ax.plot(angle, [1e3 * r.torque_b2b_nm for r in results], "r", label="ball-to-ball")
    ax.set_xlabel("nut rotation angle [deg]")
    ax.set_ylabel("friction torque T_f [N mm]")
    ax.set_title("Fig. 21 (ours): friction torque split")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def write_outputs(results, summary, separation_rad, loop_rad, out_dir):
    """Write timeseries.csv, summary.json and both figures into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "timeseries.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(TIMESERIES_COLUMNS)
        for r in results:
            w.writerow([f"{r.t_s:.9g}", f"{r.nut_angle_rad:.9g}", f"{r.torque_total_nm:.9g}",
                        f"{r.torque_b2g_nm:.9g}", f"{r.torque_b2b_nm:.9g}", r.n_groups,
                        f"{r.drive_power_w:.9g}", f"{r.loss_w:.9g}", int(r.converged)])
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_fig20(results, separation_rad, loop_rad, out / "fig20_ball_distance.png")
    plot_fig21(results, out / "fig21_torque_split.png")
    return out
