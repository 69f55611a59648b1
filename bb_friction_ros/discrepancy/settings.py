"""
Settings of the discrepancy workflow: every threshold is a named, validated field with a reason.

Read from the ``discrepancy:`` mapping of a YAML file (``--settings``); an unknown key or an
out-of-range value is refused with the dotted key, like every other config of the project.
"""

import dataclasses

from bb_friction_ros.config import field, from_mapping, load_section
from bb_friction_ros.discrepancy.physical import PhysicalSettings
from bb_friction_ros.empirical_terms import (MAX_LEAD_HARMONICS, MAX_RIPPLE_HARMONICS,
                                             MAX_STROKE_ORDER)


@dataclasses.dataclass(frozen=True)
class DiscrepancySettings:
    """Thresholds and grids of the discrepancy workflow (docs/discrepancy.md)."""

    # --- the time split -------------------------------------------------------------------
    holdout_fraction: float = field(
        0.3, "1", "last part of the recording (in samples) held out from fitting; the RMSE "
        "before/after is reported on it", lo=0.05, hi=0.5)
    # --- is the recording informative enough? ---------------------------------------------
    min_samples: int = field(
        200, "1", "usable samples needed: the fit part must carry ~10 parameters through "
        "cross-validation folds and the held-out part must give a meaningful RMSE", lo=20,
        hi=10 ** 9)
    standstill_speed_rad_s: float = field(
        0.01, "rad/s", "|nut speed| below which a sample counts as standing still (the "
        "model's friction is zero there; static friction is indeterminate)", lo=0.0)
    min_direction_fraction: float = field(
        0.1, "1", "share of the moving fit samples needed in EACH direction: with one "
        "direction a drag cannot be told from a torque offset", lo=0.0, hi=0.5)
    min_speed_ratio: float = field(
        1.5, "1", "needed ratio of the 90th to the 10th percentile of |nut speed| (moving "
        "fit samples): with one speed, viscous and constant drag are indistinguishable; "
        "speeds 1.5x apart already give the two a different ratio", lo=1.0)
    min_load_variation_fraction: float = field(
        0.1, "1", "needed (P90 - P10) / median of |axial load|; below it load_dependent is "
        "not tested (it would be a copy of seal_drag)", lo=0.0)
    min_samples_per_angle_bin: int = field(
        5, "1", "fit samples needed in every angle bin for lead_error to be tested (the "
        "nut angle must cover a whole revolution)", lo=1)
    # --- selection --------------------------------------------------------------------------
    bic_threshold: float = field(
        10.0, "1", "BIC decrease a term must bring to enter (and keep) the model: > 10 is "
        "'very strong' evidence (Kass & Raftery 1995)", lo=0.0)
    rigid_body_bic_threshold: float = field(
        0.0, "1", "BIC decrease each rigid-body term (inertia, viscous_drag, seal_drag, "
        "offset) must bring when the recording has no model of the drive (--baseline zero): "
        "there they are the textbook floor of every motor torque, not discoveries, so plain "
        "BIC (0) decides; with a model they need bic_threshold like every term", lo=0.0)
    cv_folds: int = field(
        5, "1", "contiguous time blocks of the fit part for cross-validation: a term must "
        "also lower the cross-validated RMSE", lo=2, hi=50)
    max_terms: int = field(
        5, "1", "most terms selected: a recording without a model of its screw needs drag, "
        "its viscous part, a direction asymmetry, the inertia and Stribeck at once", lo=1,
        hi=8)
    lead_error_harmonics: int = field(
        2, "1", "harmonics per revolution fitted by lead_error", lo=1, hi=MAX_LEAD_HARMONICS)
    angle_ripple_harmonics: int = field(
        2, "1", "harmonics per revolution fitted by angle_ripple", lo=1,
        hi=MAX_RIPPLE_HARMONICS)
    stroke_order: int = field(
        2, "1", "order of the Legendre polynomial of stroke_position (1: a linear change "
        "along the stroke)", lo=1, hi=MAX_STROKE_ORDER)
    min_stroke_revolutions: float = field(
        2.0, "rev", "nut travel (P95 - P5 of the cumulative angle) needed in the fit part to "
        "test stroke_position: over less, a change along the stroke is a change in time",
        lo=0.0)
    # --- acceleration ---------------------------------------------------------------------
    accel_cutoff_hz: float = field(
        0.0, "Hz", "cut-off of the 2nd-order Butterworth low-pass of the nut velocity whose "
        "derivative is the acceleration (the inertia term); 0 chooses it from the data "
        "(blocked cross-validation, discrepancy/bandwidth.py), a positive value overrides "
        "the choice; the causal version lags by sqrt(2)/(2 pi fc), 22 ms at 10 Hz", lo=0.0)
    accel_min_cutoff_hz: float = field(
        0.1, "Hz", "lowest cut-off accel_cutoff_hz may set: below it the causal filter lags "
        "by more than 2 s, longer than any acceleration phase of an axis (5e-324 Hz wrote "
        "Infinity into summary.json)", lo=0.0, lo_open=True)
    accel_max_cutoff_fraction: float = field(
        0.2, "1", "the cut-off is at most this fraction of the sample rate (a slow recorder: "
        "the filter must stay well below Nyquist); the highest candidate of the choice",
        lo=0.01, hi=0.45)
    accel_grid_min_share: float = field(
        0.1, "1", "a file of runs at several rates: the grid tops at the safe cut-off of the "
        "fastest rate that holds this share of the samples (a run of 40 rows among 3000 "
        "does not set the cut-off of the whole file)", lo=0.0, hi=1.0)
    accel_cutoff_grid_points: int = field(
        8, "1", "candidate cut-offs of the cross-validated choice, log-spaced", lo=2, hi=50)
    accel_cutoff_grid_span: float = field(
        32.0, "1", "ratio of the highest to the lowest candidate cut-off (at 1 kHz: 200 Hz "
        "down to 6.25 Hz; at 50 Hz: 10 Hz down to 0.31 Hz)", lo=1.5, hi=1e4)
    segment_gap_factor: float = field(
        5.0, "1", "a step longer than this many median sample periods starts a new "
        "continuous segment: the acceleration filter never runs across it", lo=1.5)
    accel_min_segment_samples: int = field(
        5, "1", "samples a continuous segment needs for an acceleration to be derived on it",
        lo=3)
    # --- noise ------------------------------------------------------------------------------
    noise_max_lag: int = field(
        64, "samples", "longest lag of the differences that estimate the noise: the noise "
        "of a filtered (smooth) signal decorrelates within it", lo=1, hi=10 ** 6)
    noise_plateau_ratio: float = field(
        1.1, "1", "the noise std is read at the first lag where doubling the lag raises the "
        "difference-based estimate by less than this ratio (the noise has decorrelated)",
        lo=1.0)
    nonlinear_grid_points: int = field(
        12, "1", "grid points when profiling a nonlinear parameter (Stribeck velocity, "
        "thermal time constant) before a bounded 1-D refinement", lo=3, hi=200)
    stribeck_max_speed_fraction: float = field(
        0.5, "1", "largest Stribeck velocity tried, as a fraction of the 90th percentile of "
        "|nut speed|: a larger one makes stribeck a copy of seal_drag", lo=0.01, hi=1.0)
    pre_rolling_min_travel_rad: float = field(
        1e-4, "rad", "shortest pre-rolling travel tried (nut rotation; 0.3 um of axial travel "
        "at a 20 mm lead)", lo=0.0, lo_open=True)
    pre_rolling_max_travel_rad: float = field(
        0.05, "rad", "longest pre-rolling travel tried (160 um at a 20 mm lead, several times "
        "the tens of um measured on ball screws): beyond it a build-up is a speed effect "
        "(Stribeck, viscous), not pre-rolling", lo=0.0, lo_open=True)
    pre_rolling_min_samples: float = field(
        3.0, "samples", "a pre-rolling travel is tried only if it spans at least this many "
        "samples after a reversal (the median first-sample rotation of the recording's "
        "reversals): a recorder too slow to see it leaves the term untested", lo=1.0)
    thermal_min_tau_fraction: float = field(
        0.05, "1", "shortest thermal time constant tried, as a fraction of the fit span",
        lo=1e-3, hi=1.0)
    thermal_max_tau_fraction: float = field(
        10.0, "1", "longest thermal time constant tried, as a fraction of the fit span "
        "(beyond it the drift is linear in time)", lo=1.0, hi=1e3)
    # --- where: regime table ----------------------------------------------------------------
    speed_bins: int = field(4, "1", "quantile bins of |nut speed| per direction", lo=1, hi=20)
    angle_bins: int = field(8, "1", "bins of the nut angle within a revolution", lo=2, hi=72)
    load_bins: int = field(4, "1", "quantile bins of the axial load", lo=1, hi=20)
    time_bins: int = field(5, "1", "equal bins of time", lo=1, hi=50)
    accel_bins: int = field(2, "1", "quantile bins of |acceleration| per sign (accelerating, "
                            "decelerating) among the samples above accel_regime_fraction",
                            lo=1, hi=20)
    accel_regime_fraction: float = field(
        0.1, "1", "samples whose |acceleration| exceeds this fraction of its 99th percentile "
        "form the acceleration regimes", lo=0.0, hi=1.0)
    stroke_bins: int = field(5, "1", "equal bins of the nut's travel (cumulative angle)",
                             lo=1, hi=50)
    min_bin_samples: int = field(10, "1", "samples needed for a bin to be judged", lo=2)
    flag_z: float = field(
        4.0, "1", "a bin's mean residual is significant when it exceeds flag_z noise "
        "standard errors (4: ~6e-5 false flags per bin under white noise)", lo=1.0)
    flag_min_bias_fraction: float = field(
        0.25, "1", "and when it exceeds this fraction of the noise std (relevance, not only "
        "significance)", lo=0.0)
    # --- is the measurement plausible at all? (plausibility.py) -----------------------------
    sign_error_z: float = field(
        5.0, "1", "the measured torque's Coulomb part (least squares on 1 and sign(omega) over "
        "the moving samples of both directions) below -sign_error_z standard errors is a sign "
        "error: friction has the sign of the nut velocity (5: ~3e-7 false refusals under "
        "white noise)", lo=1.0)
    sign_error_fraction: float = field(
        0.9, "1", "a recording moving in one direction only: this share of moving samples "
        "with a measured torque against the velocity's sign is a sign error", lo=0.5, hi=1.0)
    min_torque_constant_nm_per_a: float = field(
        1e-4, "N m/A", "smallest torque constant accepted (--torque-constant-nm-per-a): a "
        "6 mm micro motor has ~1.5e-3 N m/A", lo=0.0, lo_open=True)
    max_torque_constant_nm_per_a: float = field(
        1e4, "N m/A", "largest torque constant accepted: direct-drive torque motors reach a "
        "few hundred N m/A", lo=0.0, lo_open=True)
    max_measured_scale_ratio: float = field(
        100.0, "1", "a measured torque whose RMS on moving samples is more than this factor "
        "above or below the model's prediction is refused as a unit or torque-constant error "
        "(the model's friction is off by tens of percent, not by orders of magnitude)",
        lo=1.0)
    # --- the model's own parameters as candidates (physical/) --------------------------------
    physical: PhysicalSettings = dataclasses.field(default_factory=PhysicalSettings)


def load_settings(path=None):
    """Read ``discrepancy:`` settings from YAML (defaults when ``path`` is None)."""
    data = {} if path is None else load_section(path, "discrepancy")
    return from_mapping(DiscrepancySettings, data, "discrepancy")
