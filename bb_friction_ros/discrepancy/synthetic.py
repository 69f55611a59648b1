"""
Synthetic recordings with hidden effects, for the tests and the benchmark of the workflow.

A recording is: the model's own prediction for an input trajectory (the baseline) plus one or
two effects of the library with random but physical magnitudes, plus white noise.  The
baseline is exactly what the workflow subtracts (its prediction on the same inputs), so it is
computed once per trajectory and cached on disk (an ``.npz`` keyed by the trajectory, the
model config and the model's source code), and many recordings are built on it.

The reference trajectory repeats a cycle of speeds in both directions (very slow to fast, so
Stribeck, viscous and constant drag separate) under a sinusoidal load of another period, so
the held-out last 30 % sees every regime the fit saw.
"""

import dataclasses
import hashlib
import math
import os
from pathlib import Path

import numpy as np

from bb_friction_ros.config import bundled_config
from bb_friction_ros.trajectories import DemoRecording, make_demo_events
from bb_friction_ros.discrepancy.data import predict_events, Recording, run_times
from bb_friction_ros.empirical_terms import make_term, TermSet
from bb_friction_ros.node_parameters import NodeParameters

# One cycle of nut speeds [rev/s]: slow (Stribeck region), fast, medium, fastest.
CYCLE_REV_S = (0.05, -0.05, 1.0, -1.0, 0.25, -0.25, 2.0, -2.0)

# Physical ranges of the hidden effects [SI], drawn uniformly; "signed" ones get a random
# sign.  They are a few percent to ~30 % of the model's ~0.25 N m friction torque.
EFFECT_RANGES = {
    "viscous_drag": {"c_nm_s_per_rad": (1.5e-3, 6e-3)},
    "seal_drag": {"torque_nm": (0.015, 0.05)},
    "stribeck": {"torque_nm": (0.03, 0.08), "velocity_rad_s": (0.5, 2.5)},
    "load_dependent": {"k_nm_per_n": (1.5e-5, 4e-5)},              # signed: mu off 9-25 %
    "lead_error": {"sin1_m": (4e-6, 10e-6)},                         # ISO 3408 v_2pi, C5-C7
    "thermal_drift": {"delta_torque_nm": (0.02, 0.06), "time_constant_s": (3.0, 30.0)},
    # J alpha peaks at 2-8 % of the friction torque with the filtered alpha of the trajectory
    "inertia": {"j_kg_m2": (1e-4, 4e-4)},
    "offset": {"torque_nm": (0.01, 0.04)},                           # signed
    "coulomb_asymmetry": {"delta_torque_nm": (0.02, 0.08)},          # signed: +/-Delta/2
    "viscous_asymmetry": {"delta_c_nm_s_per_rad": (1.5e-3, 5e-3)},   # signed
    "angle_ripple": {"sin1_nm": (0.006, 0.02)},                      # random phase
}
# stroke_position is not drawn: the reference trajectory travels ~1 rev, too little to tell a
# change along the stroke from one in time (tested on its own trajectory instead).
SIGNED = {"k_nm_per_n", "delta_torque_nm", "delta_c_nm_s_per_rad"}
NOISE_RANGE_NM = (0.002, 0.008)
# Second harmonic of the lead error, as a fraction of the first.
LEAD_SECOND_HARMONIC_MAX = 0.5


def reference_trajectory(cycles=3, rate_hz=50.0, segment_s=0.6):
    """Return the DemoRecording of the reference trajectory (no effects, no noise)."""
    return DemoRecording(state_rate_hz=rate_hz, load_rate_hz=rate_hz, accel_rad_s2=250.0,
                         segments_rev_s=CYCLE_REV_S * cycles, segment_duration_s=segment_s,
                         load_mean_n=1500.0, load_amplitude_n=500.0, load_period_s=3.7,
                         viscous_drag_nm_s_per_rad=0.0, seal_drag_nm=0.0, noise_nm=0.0)


def _cache_key(cfg, config_path, model_rate_hz):
    h = hashlib.sha256()
    h.update(repr(dataclasses.astuple(cfg)).encode())
    h.update(Path(config_path).read_bytes())
    h.update(repr(float(model_rate_hz)).encode())
    root = Path(__file__).resolve().parent.parent
    for pattern in ("ball_screw/*.py", "contact/*.py", "runner.py", "replay.py",
                    "trajectories.py"):
        for p in sorted(root.glob(pattern)):
            h.update(p.read_bytes())
    return h.hexdigest()[:20]


@dataclasses.dataclass
class Baseline:
    """Input events of a trajectory and the model's prediction on them."""

    events: list              # axial_load and nut_state events, log order (no measurement)
    recording: Recording      # torque_meas_nm = NaN; torque_pred_nm = the model


def baseline(cfg, config_path=None, model_rate_hz=100.0, cache_dir=None):
    """Return the Baseline of trajectory ``cfg``: computed once, then read from the cache."""
    config_path = config_path or bundled_config("ball_screw.yaml")
    settings = NodeParameters(nut_joint=cfg.nut_joint, model_rate_hz=float(model_rate_hz))
    cache = None
    if cache_dir is not None:
        cache = Path(cache_dir) / f"baseline_{_cache_key(cfg, config_path, model_rate_hz)}.npz"
    stored = {}
    if cache is not None and cache.is_file():
        stored = dict(np.load(cache))

    def predict(events):
        if "pred" not in stored:
            preds, _ = predict_events(events, config_path, settings)
            stored.update(pred=preds.column("torque_total_nm").copy(),
                          converged=preds.converged.copy())
            if cache is not None:
                cache.parent.mkdir(parents=True, exist_ok=True)
                # the writer's own temporary name: test sessions run side by side share
                # the cache, and a shared name would let one's write tear another's
                tmp = cache.with_suffix(f".{os.getpid()}.tmp.npz")
                np.savez(tmp, **stored)
                tmp.replace(cache)
        return stored["pred"]

    events = [e for e in make_demo_events(cfg, predict) if e.kind != "measured_torque"]
    states = [e for e in events if e.kind == "nut_state"]
    t = np.array([e.stamp_s for e in states])
    loads = _held_loads(events)
    rec = Recording(t, run_times(t), np.array([e.positions[0] for e in states]),
                    np.array([e.velocities[0] for e in states]), loads,
                    np.full(t.size, np.nan), np.asarray(stored["pred"], float),
                    np.asarray(stored["converged"], bool),
                    {"input": "synthetic", "prediction_source": "model (replay path)"})
    return Baseline(events, rec)


def _held_loads(events):
    out, load = [], math.nan
    for e in events:
        if e.kind == "axial_load":
            load = e.value
        elif e.kind == "nut_state":
            out.append(load)
    return np.array(out)


def draw_effect(name, rng):
    """Return a Term of ``name`` with random physical parameters (EFFECT_RANGES)."""
    values = {}
    for key, (lo, hi) in EFFECT_RANGES[name].items():
        v = float(rng.uniform(lo, hi))
        signed = key in SIGNED or (name == "offset")
        values[key] = v * rng.choice((-1.0, 1.0)) if signed else v
    if name == "lead_error":                  # random phase and a second harmonic
        amp, phase = values.pop("sin1_m"), float(rng.uniform(0.0, 2.0 * math.pi))
        values.update(sin1_m=amp * math.cos(phase), cos1_m=amp * math.sin(phase))
        amp2 = amp * float(rng.uniform(0.0, LEAD_SECOND_HARMONIC_MAX))
        phase2 = float(rng.uniform(0.0, 2.0 * math.pi))
        values.update(sin2_m=amp2 * math.cos(phase2), cos2_m=amp2 * math.sin(phase2))
    if name == "angle_ripple":                # random phase
        amp, phase = values.pop("sin1_nm"), float(rng.uniform(0.0, 2.0 * math.pi))
        values.update(sin1_nm=amp * math.cos(phase), cos1_nm=amp * math.sin(phase))
    if name == "inertia":                     # the analysis filter of the reference rate
        values.update(accel_cutoff_hz=INERTIA_FILTER["accel_cutoff_hz"],
                      max_gap_s=INERTIA_FILTER["max_gap_s"])
    return make_term(name, values)


# The acceleration filter the workflow derives for the reference trajectory (default
# settings at 50 Hz): hidden inertia is J times that alpha, the library's own shape.
INERTIA_FILTER = {"accel_cutoff_hz": 10.0, "max_gap_s": 0.1}


def reference_acceleration(rec):
    """Return the zero-phase acceleration the workflow derives for ``rec`` (defaults)."""
    from bb_friction_ros.discrepancy.settings import DiscrepancySettings
    from bb_friction_ros.discrepancy.workflow import with_acceleration
    return with_acceleration(rec, DiscrepancySettings())[0].nut_accel_rad_s2


def synthesize(base, terms, noise_nm, rng):
    """Return (Recording with measured torque, noise array): baseline + terms + noise."""
    r = base.recording
    noise = rng.normal(0.0, noise_nm, len(r))
    accel = reference_acceleration(r) if "inertia" in terms.names else None
    hidden = terms.torque_nm(r.t_run_s, r.nut_angle_rad, r.nut_velocity_rad_s,
                             r.axial_load_n, accel) if len(terms) else 0.0
    rec = dataclasses.replace(r, torque_meas_nm=r.torque_pred_nm + hidden + noise,
                              info=dict(r.info, hidden=list(terms.names)))
    return rec, noise


def random_case(base, rng, n_effects):
    """Return (Recording, hidden TermSet, noise array, noise std) with n_effects random ones."""
    names = rng.choice(sorted(EFFECT_RANGES), size=n_effects, replace=False)
    terms = TermSet([draw_effect(str(n), rng) for n in names])
    noise_nm = float(rng.uniform(*NOISE_RANGE_NM))
    rec, noise = synthesize(base, terms, noise_nm, rng)
    return rec, terms, noise, noise_nm


def named_correctly(analysis, hidden_names):
    """
    Tell whether the workflow named the hidden effects.

    The selected set must equal the hidden one; a member of an ambiguous pair (offset,
    coulomb_asymmetry) counts for its partner when the analysis reports the pair as one
    ambiguous effect, as it must where the data cannot separate the two.
    """
    got, want = set(analysis.terms.names), set(hidden_names)
    if got == want:
        return True
    for amb in analysis.ambiguities:
        if not amb["separated"]:
            a, b = amb["pair"]
            swap = {a: b, b: a}
            if {swap.get(n, n) for n in got} == want:
                return True
    return False


# ------------------------------------------------------------------------------------------
# Hidden physical parameters: the recording is made by the model itself with a
# parameter the config given to the workflow does not have.

# The drive the physical search is tested on: speeds +-0.5-2 rev/s with reversals under
# 700-1700 N, 20 s.
PHYSICAL_CYCLE_REV_S = (0.5, -0.5, 1.0, -1.0, 2.0, -2.0, 0.75, -0.75, 1.5, -1.5)
# Hidden physical ranges (edge units, as the config writes them), drawn uniformly.
PHYSICAL_RANGES = {
    "contact_angle_deviation": ("errors", "theta_amplitude_deg", (1.5, 3.5)),
    "friction_coefficient": ("material", "friction_coefficient", (0.07, 0.15)),
    "preload": ("geometry", "ball_oversize_um", (1.5, 3.5)),
}
# The config the workflow is given: the bundled screw without a contact-angle deviation.
PHYSICAL_BASE_OVERRIDES = {"errors": {"theta_amplitude_deg": 0.0}}


def physical_trajectory(duration_s=20.0, rate_hz=50.0):
    """Return the DemoRecording of the physical-search drive (no effects, no noise)."""
    segment = duration_s / len(PHYSICAL_CYCLE_REV_S)
    return DemoRecording(state_rate_hz=rate_hz, load_rate_hz=rate_hz, accel_rad_s2=250.0,
                         segments_rev_s=PHYSICAL_CYCLE_REV_S, segment_duration_s=segment,
                         load_mean_n=1200.0, load_amplitude_n=500.0, load_period_s=3.7,
                         viscous_drag_nm_s_per_rad=0.0, seal_drag_nm=0.0, noise_nm=0.0)


def model_config(directory, overrides, base=None):
    """
    Write a model file: the bundled (or ``base``) config with nested ``overrides``; return it.

    The name is keyed by the content, so the baseline cache of each config is reused.
    """
    from bb_friction_ros.model_file import read_model_file, write_model_file
    import yaml
    section, terms = read_model_file(base or bundled_config("ball_screw.yaml"))
    merged = _deep_merge(section, overrides)
    key = hashlib.sha256(yaml.safe_dump(merged, sort_keys=True).encode()).hexdigest()[:16]
    path = Path(directory) / f"model_{key}.yaml"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")     # as baseline's, one per writer
        write_model_file(tmp, merged, terms, "# synthetic model config (discrepancy tests)\n")
        tmp.replace(path)
    return path


def draw_physical(name, rng):
    """Return {section: {param: value}} of a hidden physical parameter (PHYSICAL_RANGES)."""
    section, param, (lo, hi) = PHYSICAL_RANGES[name]
    return {section: {param: float(rng.uniform(lo, hi))}}


def physical_case(traj, hidden, terms, noise_nm, rng, cache_dir, model_rate_hz=50.0,
                  base_overrides=PHYSICAL_BASE_OVERRIDES):
    """
    Return (Recording, base config path, noise): a recording of the model with ``hidden``.

    The measured torque is the model's with the hidden parameters (``hidden``: nested
    overrides over the base config) plus the empirical ``terms`` plus white noise; the
    prediction is the base config's, which is what the workflow is given.
    """
    base_cfg = model_config(cache_dir, base_overrides)
    hidden_cfg = model_config(cache_dir, _deep_merge(base_overrides, hidden))
    given = baseline(traj, base_cfg, model_rate_hz, cache_dir)
    truth = baseline(traj, hidden_cfg, model_rate_hz, cache_dir)
    r = given.recording
    noise = rng.normal(0.0, noise_nm, len(r))
    accel = reference_acceleration(r) if "inertia" in terms.names else None
    extra = terms.torque_nm(r.t_run_s, r.nut_angle_rad, r.nut_velocity_rad_s,
                            r.axial_load_n, accel) if len(terms) else 0.0
    rec = dataclasses.replace(r, torque_meas_nm=truth.recording.torque_pred_nm + extra + noise,
                              info=dict(r.info, hidden=list(terms.names),
                                        hidden_physical=hidden))
    return rec, base_cfg, noise


def _deep_merge(a, b):
    """Return mapping ``a`` with the two-level mapping ``b`` merged over it (copies)."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in a.items()}
    for k, v in b.items():
        out[k] = {**out.get(k, {}), **v}
    return out
