"""
The unstated amplitude of theta(phi) (paper Fig. 19): the bundled sweep and its calibration.

The paper's whole-screw study (Sec. 3.4) gives theta(phi) only as a picture without scale.
``config/sweeps/theta_amplitude_fig21.yaml`` runs the whole screw over the amplitude (2-5 deg)
with rigid and elastic load distribution and records the features of Figs. 20-21 that the
paper states.  ``bb-friction sweep`` runs that spec on the Dask engine; ``bb-friction
reproduce`` runs the same samples through the same ``models.evaluate`` in this process
(``run_theta_sweep``), so that reproducing the paper needs neither Dask nor Arrow.

The amplitude is calibrated against ONE of the features, the peak B2B share (paper 49.6 %):
a straight line fitted to the sweep's points around the crossing gives the value and its
uncertainty.  The other features are validation, never
fitted.  The result is the config value ``errors.theta_amplitude_deg``
(docs/assumptions_ball_screw.md).
"""

import math

import numpy as np

from bb_friction_ros import paper
from bb_friction_ros.config import bundled_config
from bb_friction_ros.sweep.models import MODELS, OK, evaluate
from bb_friction_ros.sweep.spec import load_spec

SPEC_NAME = "sweeps/theta_amplitude_fig21.yaml"
AMPLITUDE = "errors.theta_amplitude_rad"
ELASTIC = "elastic_load_distribution"
# Fig. 21 as the paper states it (Sec. 3.4 text; paper.py): peak share, its angle, the zero.
PAPER_PEAK_SHARE = paper.B2B_PEAK_SHARE.value / 100.0
PAPER_PEAK_ANGLE_DEG = paper.B2B_PEAK_NUT_ANGLE.value
PAPER_ZERO_ANGLE_DEG = paper.B2B_ZERO_NUT_ANGLE.value
PAPER_GROUPS = paper.B2B_GROUPS.value
# Half-width of the amplitude window of the calibration's straight-line fit (see
# ``calibrate_amplitude``): 2 grid steps of the full sweep either side, 1 of the coarse one.
FIT_WINDOW_RAD = math.radians(0.5)


def run_theta_sweep(coarse=False):
    """
    Run the bundled sweep in this process; return its rows as {column: numpy array}.

    ``coarse``: 0.5 deg instead of 0.25 deg steps (7 instead of 13 amplitudes).  The
    samples and each sample's evaluation are the sweep engine's (``spec.sample_inputs``,
    ``models.evaluate``); only the Dask scheduling and the Parquet file are left out: 26
    runs of 200 steps take seconds, less than starting a Dask cluster, and reproducing the
    paper should not need the design-study stack.  Raises RuntimeError naming the first
    sample that did not finish OK.
    """
    overrides = {"grid": {"errors.theta_amplitude_deg": {"start": 2.0, "stop": 5.0, "num": 7},
                          ELASTIC: [0, 1]}} if coarse else None
    spec = load_spec(bundled_config(SPEC_NAME), overrides)
    model = MODELS[spec.model]
    cols = spec.sample_inputs(0, spec.n_samples)
    outs = {name: [] for name in spec.outputs}
    for j in range(spec.n_samples):
        params = {name: cols[name][j].item() for name in spec.input_names}
        out, status, reason = evaluate(model, spec.base, params, spec.option_map,
                                       spec.config_names)
        if status != OK:
            raise RuntimeError(f"theta-amplitude sweep: sample {j} ({params}) {status}: "
                               f"{reason}")
        for name in spec.outputs:
            outs[name].append(out[name])
    cols.update(outs)
    return {name: np.asarray(values, dtype=float) for name, values in cols.items()}


def _feature(rows, elastic, name):
    """(amplitudes [rad], values) of one output for one load distribution, by amplitude."""
    sel = rows[ELASTIC] == (1.0 if elastic else 0.0)
    amp = rows[AMPLITUDE][sel]
    k = np.argsort(amp)
    return amp[k], rows[name][sel][k]


def calibrate_amplitude(rows, elastic, target=PAPER_PEAK_SHARE, window_rad=FIT_WINDOW_RAD):
    """
    Amplitude [rad] at which the peak B2B share reaches ``target``, from the sweep rows.

    The peak share is not smooth at fine resolution: with 3.6 deg time steps the peak
    switches between neighbouring local maxima and a contact may close a step earlier, so
    it scatters by about +-1 pt between amplitudes 0.01 deg apart.  A root find on it would
    fit that scatter.  Instead a straight line is fitted to the grid points within
    ``window_rad`` of the first grid crossing and solved for ``target``.  Returns
    (amplitude, uncertainty): the uncertainty is the fit's residual scatter over its slope.
    None if the sweep never crosses ``target``.
    """
    amp, share = _feature(rows, elastic, "fig21_peak_b2b_share")
    above = np.flatnonzero(share >= target)
    if not above.size or above[0] == 0:
        return None
    k = above[0]
    cross = amp[k - 1] + (target - share[k - 1]) * (amp[k] - amp[k - 1]) \
        / (share[k] - share[k - 1])
    near = np.abs(amp - cross) <= window_rad + 1e-12
    slope, icpt = np.polyfit(amp[near], share[near], 1)
    resid = share[near] - (slope * amp[near] + icpt)
    scatter = float(np.sqrt(np.mean(resid ** 2))) if near.sum() > 2 else 0.0
    return float((target - icpt) / slope), scatter / abs(float(slope))


# Features that also have a smoothed value, drawn beside the raw one (the raw peak angle jumps
# between neighbouring local maxima from one amplitude to the next).
SMOOTHED = {"fig21_peak_nut_angle_rad": "fig21_peak_nut_angle_smoothed_rad"}


def plot_theta_sweep(rows, path, calibrated_deg=None, config_deg=None):
    """Plot the whole sweep: each Fig. 21 feature over the amplitude, rigid and elastic, paper."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(12, 6.5))
    axes = fig.subplots(2, 3)
    panels = [("fig21_peak_b2b_share", 100.0, "peak B2B / ball-groove torque [%]",
               100 * PAPER_PEAK_SHARE),
              ("fig21_peak_nut_angle_rad", 180 / math.pi, "nut angle of the peak [deg]",
               PAPER_PEAK_ANGLE_DEG),
              ("fig21_zero_nut_angle_rad", 180 / math.pi, "B2B back to zero at [deg]",
               PAPER_ZERO_ANGLE_DEG),
              ("max_groups", 1.0, "B2B contact groups (max)", PAPER_GROUPS),
              ("fig21_b2g_torque_variation", 100.0, "ball-groove torque (max-min)/mean [%]",
               None)]
    for ax, (name, factor, label, stated) in zip(axes.flat, panels):
        for flag, style, text in ((0.0, "o-", "rigid"), (1.0, "s--", "elastic")):
            sel = rows[ELASTIC] == flag
            amp = np.degrees(rows[AMPLITUDE][sel])
            k = np.argsort(amp)
            ax.plot(amp[k], factor * rows[name][sel][k], style, ms=4, label=text)
            smoothed = SMOOTHED.get(name)
            if smoothed in rows:
                ax.plot(amp[k], factor * rows[smoothed][sel][k], style[0] + ":", ms=3,
                        mfc="none", label=text + ", smoothed")
        if stated is not None:
            ax.axhline(stated, color="r", lw=0.8, label="paper")
        else:
            ax.text(0.02, 0.92, "paper: 'barely has variation'", transform=ax.transAxes,
                    fontsize=8, color="r")
        if calibrated_deg is not None:
            ax.axvline(calibrated_deg, color="k", lw=0.6, ls=":", label="calibrated")
        ax.set_xlabel("theta amplitude [deg]")
        ax.set_ylabel(label, fontsize=9)
        ax.grid(True, lw=0.3)
    axes.flat[0].legend(fontsize=8)
    ax = axes.flat[5]
    ax.axis("off")
    lines = ["Calibrated against the peak share only;", "the other panels are validation."]
    if calibrated_deg is not None:
        lines.append(f"calibrated amplitude: {calibrated_deg:.3f} deg")
    if config_deg is not None:
        lines.append(f"config errors.theta_amplitude_deg: {config_deg:g}")
    ax.text(0.0, 0.8, "\n".join(lines), fontsize=9, va="top")
    fig.suptitle("Fig. 19's unstated theta amplitude: Fig. 20-21 features over the sweep")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
