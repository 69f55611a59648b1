"""
Per-model runners of a sweep: one sample in, a flat mapping of scalar outputs out.

Three models (``MODELS``):

- ``linear_pair``: the two-ball case of the paper's Sec. 2.4 (``LinearPairCase``), numerical
  or analytical;
- ``screw_pair``: the two-ball module of the ball screw, Sec. 3.3 (``solve_two_ball_module``);
- ``whole_screw``: the whole ball screw of Sec. 3.4 stepped over the configured stroke
  (``WholeScrew`` via ``run_whole_screw``), reduced to stroke statistics.

A sample sets *parameters*: the model's case parameters (``linear_pair`` only: theta, rho and
the contact-angle deviations) and any numeric field of the model's config (flat names for the
linear bearing, dotted ``section.field`` names for the ball screw).  Everything is SI.

Status of a sample (column ``status``): ``ok``; ``invalid`` (solved, but outside the model's
validity, e.g. a two-point contact: numbers kept, ``reason`` says why); ``nonconverged`` (the
solver did not converge: numbers null); ``failed`` (an exception, e.g. an out-of-range config
value drawn from a distribution: numbers null, ``reason`` holds the error).
"""

import dataclasses
import functools
import math
import threading

import numpy as np

from bb_friction_ros.config import ConfigError, validate

OK, INVALID, NONCONVERGED, FAILED = "ok", "invalid", "nonconverged", "failed"

# Distinct configs whose models (friction maps, Hertz constants) a worker thread keeps; a sweep
# over a config field rebuilds a model only when that field's value is new.
MODEL_CACHE_SIZE = 16
# A reason longer than this is cut: a traceback-sized message would bloat the table.
MAX_REASON_CHARS = 400


@dataclasses.dataclass(frozen=True)
class Output:
    """One scalar output of a model: column name, unit, meaning and Arrow type."""

    name: str
    unit: str
    doc: str
    dtype: str = "float64"          # float64 | int64 | bool


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One settable input of a model (SI unit), a case parameter or a config field."""

    name: str
    unit: str
    doc: str
    integer: bool = False
    config_field: bool = True


# Stroke statistics of the whole screw; also used by the verdict.
WHOLE_SCREW_OUTPUTS = (
    Output("torque_mean_nm", "N m", "mean friction torque on the nut over the stroke"),
    Output("torque_max_nm", "N m", "largest friction torque over the stroke"),
    Output("torque_min_nm", "N m", "smallest friction torque over the stroke"),
    Output("torque_band_rel", "1", "fluctuation band (max - min) / |mean| of the friction "
           "torque"),
    Output("torque_dev_max_rel", "1", "largest |T - mean| / |mean| over the stroke"),
    Output("torque_b2g_mean_nm", "N m", "mean ball-to-groove part of the friction torque"),
    Output("torque_b2b_mean_nm", "N m", "mean ball-to-ball part of the friction torque"),
    Output("torque_b2b_max_nm", "N m", "largest ball-to-ball part of the friction torque"),
    Output("b2b_share_max", "1", "largest T_B2B / T_B2G over the stroke (Fig. 21)"),
    Output("f_b2b_max_n", "N", "largest B2B contact force over the stroke"),
    Output("max_group_size", "1", "most balls in one B2B contact group", "int64"),
    Output("max_groups", "1", "most B2B contact groups at one step", "int64"),
    Output("power_balance_error_max", "1", "largest |drive power - loss| / loss (solver "
           "precision)"),
    # Fig. 21 features over the whole run (``simulation.fig21_features``; settle_steps is
    # not applied: the paper's features start at 0 deg).
    Output("fig21_peak_b2b_share", "1", "largest T_B2B / T_B2G (paper 49.6 %)"),
    Output("fig21_peak_nut_angle_rad", "rad", "nut angle of that peak (paper 126 deg)"),
    Output("fig21_peak_nut_angle_smoothed_rad", "rad", "nut angle of the peak of the share "
           "averaged over simulation.PEAK_SMOOTHING_WINDOW_RAD (the raw peak jitters)"),
    Output("fig21_zero_nut_angle_rad", "rad", "first nut angle after the peak without B2B "
           "torque (paper 306 deg; NaN: never)"),
    Output("fig21_b2g_torque_variation", "1", "(max - min) / mean of the ball-groove torque "
           "(paper: 'barely has variation')"),
)

WHOLE_SCREW_PARAMETERS = (
    Parameter("elastic_load_distribution", "1", "1: load_distribution elastic (shaft and nut "
              "deform axially, ref. [19]); 0: rigid; default: the config's", integer=True,
              config_field=False),
)

LINEAR_PAIR_OUTPUTS = (
    Output("eps1", "1", "velocity deviation of ball 1 alone (fraction of v/2)"),
    Output("eps2", "1", "velocity deviation of ball 2 alone (fraction of v/2)"),
    Output("eps_diff", "1", "velocity difference eps1 - eps2 (Fig. 8); B2B contact iff > 0"),
    Output("f_b2b_n", "N", "B2B contact force (Fig. 9 a, b)"),
    Output("p_f_w", "W", "ball-groove loss of both balls without B2B (baseline)"),
    Output("p_b2b_w", "W", "B2B friction loss"),
    Output("friction_ratio", "1", "(P_f + P_fB2B) / P_f (Fig. 9 c, d)"),
    Output("friction_increase", "1", "P_fB2B / P_f (as bb-friction linear --json)"),
)

SCREW_PAIR_OUTPUTS = (
    Output("f_b2b_n", "N", "B2B contact force of the two-ball module (Table 5)"),
    Output("friction_increase", "1", "loss with B2B / loss without - 1 (Table 5)"),
    Output("torque_nm", "N m", "friction torque on the nut with B2B"),
    Output("torque_no_b2b_nm", "N m", "friction torque on the nut without B2B"),
    Output("loss_w", "W", "total friction loss with B2B"),
    Output("b2b_loss_w", "W", "B2B friction loss"),
    Output("omega_ratio", "1", "orbit ratio omega_B / omega_N of the pair in contact"),
    Output("power_balance_error", "1", "|drive power - loss| / loss (solver precision)"),
)

LINEAR_CASE_PARAMETERS = (
    Parameter("theta_rad", "rad", "bottom deviation theta: dbeta_BL = -theta, dbeta_BR = "
              "+theta (Sec. 2.4.1)", config_field=False),
    Parameter("rho", "1", "side force ratio N_x / N_y on ball 1 (default: the config's "
              "side_force_ratio)", config_field=False),
    Parameter("dbeta_tr_rad", "rad", "top-right contact-angle deviation", config_field=False),
    Parameter("dbeta_tl_rad", "rad", "top-left contact-angle deviation", config_field=False),
    Parameter("dbeta_bl_rad", "rad", "bottom-left deviation, independent of dbeta_BR "
              "(instead of theta)", config_field=False),
    Parameter("dbeta_br_rad", "rad", "bottom-right deviation, independent of dbeta_BL "
              "(instead of theta)", config_field=False),
)


def config_parameters(config):
    """
    Return {name: Parameter} of every numeric field of a config dataclass (dotted if nested).

    A renamed field (``RENAMED`` of its class) is also listed under its old name.
    """
    out = {}

    def walk(obj, prefix):
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if dataclasses.is_dataclass(value):
                walk(value, f"{prefix}{f.name}.")
            elif isinstance(value, (int, float)) and not isinstance(value, bool) \
                    and "unit" in f.metadata:
                out[prefix + f.name] = Parameter(prefix + f.name, f.metadata["unit"],
                                                 f.metadata["doc"], isinstance(value, int))
        for old, new in getattr(type(obj), "RENAMED", {}).items():
            if prefix + new in out:     # an old name: the same parameter, named anew
                out[prefix + old] = out[prefix + new]
    walk(config, "")
    return out


def with_changes(config, changes, root):
    """
    Return ``config`` with dotted-name ``changes`` applied, range-checked like a loaded file.

    An out-of-range value raises ConfigError naming ``root.name``.
    """
    if not changes:
        return config
    nested = {}
    flat = {}
    for name, value in changes.items():
        head, _, rest = name.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            flat[name] = value
    for head, sub in nested.items():
        flat[head] = with_changes(getattr(config, head), sub, f"{root}.{head}")
    new = dataclasses.replace(config, **flat)
    validate(new, root)
    return new


class _ThreadCache:
    """LRU cache per thread: model objects keep scratch state, so threads never share one."""

    def __init__(self, build):
        self._build = build
        self._local = threading.local()

    def __call__(self, key):
        cached = getattr(self._local, "fn", None)
        if cached is None:
            cached = self._local.fn = functools.lru_cache(MODEL_CACHE_SIZE)(self._build)
        return cached(key)


def _build_linear_case(cfg):
    from bb_friction_ros.linear_bearing.case_study import LinearPairCase
    return LinearPairCase(cfg)


def _build_screw_model(key):
    from bb_friction_ros.ball_screw.parameters import BallScrewConfig
    from bb_friction_ros.ball_screw.screw_model import ScrewModel
    geometry, material, solver = key
    return ScrewModel(BallScrewConfig(geometry=geometry, material=material, solver=solver))


_linear_cases = _ThreadCache(_build_linear_case)
_screw_models = _ThreadCache(_build_screw_model)


def screw_model(cfg):
    """Return a cached ScrewModel: it depends on geometry, material and solver settings only."""
    return _screw_models((cfg.geometry, cfg.material, cfg.solver))


def linear_pair_result(cfg, params, method="numerical"):
    """Solve the Sec. 2.4 two-ball case for ``params`` (case parameters, SI); a PairResult."""
    case = _linear_cases(cfg)
    rho = params.get("rho", cfg.side_force_ratio)
    tr, tl = params.get("dbeta_tr_rad", 0.0), params.get("dbeta_tl_rad", 0.0)
    bottom = "dbeta_bl_rad" in params or "dbeta_br_rad" in params
    if not bottom:
        run = case.numerical if method == "numerical" else case.analytical
        return run(params.get("theta_rad", 0.0), rho, tr, tl)
    if method != "numerical":
        raise ConfigError("dbeta_bl_rad, dbeta_br_rad: the analytical model takes the "
                          "symmetric theta only; use method: numerical")
    return case.numerical(0.0, rho, tr, tl, params.get("dbeta_bl_rad", 0.0),
                          params.get("dbeta_br_rad", 0.0))


def run_linear_pair(cfg, params, options):
    """One ``linear_pair`` sample: (outputs, status, reason)."""
    res = linear_pair_result(cfg, params, options["method"])
    if not res.converged:
        return {}, NONCONVERGED, "; ".join(res.notes)
    ratio = (res.p_f_w + res.p_b2b_w) / res.p_f_w if res.p_f_w else math.nan
    out = {"eps1": res.eps[0], "eps2": res.eps[1], "eps_diff": res.eps[0] - res.eps[1],
           "f_b2b_n": res.f_b2b_n, "p_f_w": res.p_f_w, "p_b2b_w": res.p_b2b_w,
           "friction_ratio": ratio, "friction_increase": ratio - 1.0}
    return out, (OK if res.valid else INVALID), "; ".join(res.notes)


def run_screw_pair(cfg, params, options):
    """One ``screw_pair`` sample: the two-ball module at the config's operation.module_*."""
    from bb_friction_ros.ball_screw.module import solve_two_ball_module
    op = cfg.operation
    res = solve_two_ball_module(screw_model(cfg), op.module_theta1_rad, op.module_theta2_rad,
                                op.module_axial_load_n, op.nut_velocity_rad_s)
    if not res.converged:
        return {}, NONCONVERGED, "two-ball module solve did not converge"
    out = {o.name: getattr(res, o.name) for o in SCREW_PAIR_OUTPUTS}
    return out, OK, ""


def stroke_statistics(torque_nm, torque_b2g_nm, torque_b2b_nm, f_b2b_max_n, group_sizes,
                      n_groups, power_balance_error, settle_steps=0):
    """
    Reduce a whole-screw time series (one value per step) to the stroke statistics.

    The first ``settle_steps`` steps are left out, as ISO 3408-3 leaves out the ends of the
    travel.  Relative quantities divide by |mean torque|.
    """
    sl = slice(settle_steps, None)
    t = np.asarray(torque_nm, dtype=float)[sl]
    b2g = np.asarray(torque_b2g_nm, dtype=float)[sl]
    b2b = np.asarray(torque_b2b_nm, dtype=float)[sl]
    mean = float(np.mean(t))
    scale = abs(mean)
    share = np.divide(b2b, b2g, out=np.zeros_like(b2b), where=b2g != 0.0)
    return {
        "torque_mean_nm": mean,
        "torque_max_nm": float(t.max()),
        "torque_min_nm": float(t.min()),
        "torque_band_rel": float((t.max() - t.min()) / scale) if scale else math.nan,
        "torque_dev_max_rel": float(np.max(np.abs(t - mean)) / scale) if scale else math.nan,
        "torque_b2g_mean_nm": float(np.mean(b2g)),
        "torque_b2b_mean_nm": float(np.mean(b2b)),
        "torque_b2b_max_nm": float(b2b.max()),
        "b2b_share_max": float(share.max()),
        "f_b2b_max_n": float(np.max(np.asarray(f_b2b_max_n, dtype=float)[sl])),
        "max_group_size": int(np.max(np.asarray(group_sizes)[sl])),
        "max_groups": int(np.max(np.asarray(n_groups)[sl])),
        "power_balance_error_max": float(np.max(np.asarray(power_balance_error)[sl])),
    }


def run_whole_screw(cfg, params, options):
    """One ``whole_screw`` sample: the configured stroke (operation.*), reduced to statistics."""
    from bb_friction_ros.ball_screw import simulation
    from bb_friction_ros.ball_screw.whole_screw import WholeScrew
    settle = options["settle_steps"]
    if "elastic_load_distribution" in params:
        flag = int(params["elastic_load_distribution"])
        if flag not in (0, 1):
            raise ConfigError(f"elastic_load_distribution: 0 (rigid) or 1 (elastic), got "
                              f"{flag}")
        cfg = dataclasses.replace(cfg, load_distribution="elastic" if flag else "rigid")
    if settle >= cfg.operation.n_steps:
        raise ConfigError(f"sweep.options.settle_steps: {settle} leaves no step of the "
                          f"{cfg.operation.n_steps} of ball_screw.operation.n_steps")
    steps, _ = simulation.run_whole_screw(cfg, screw=WholeScrew(cfg, model=screw_model(cfg)))
    converged = np.array([s.converged for s in steps])
    if not converged.all():
        bad = np.flatnonzero(~converged)
        return {}, NONCONVERGED, (f"{bad.size} of {converged.size} steps did not converge "
                                  f"(first: step {bad[0] + 1})")
    out = stroke_statistics(
        [s.torque_total_nm for s in steps], [s.torque_b2g_nm for s in steps],
        [s.torque_b2b_nm for s in steps],
        [float(np.max(s.b2b_forces_n, initial=0.0)) for s in steps],
        [max((len(ids) for ids, _ in s.groups), default=0) for s in steps],
        [s.n_groups for s in steps], [s.power_balance_error for s in steps], settle)
    f21 = simulation.fig21_features([s.nut_angle_rad for s in steps],
                                    [s.torque_b2g_nm for s in steps],
                                    [s.torque_b2b_nm for s in steps], [s.n_groups for s in steps])
    out.update(fig21_peak_b2b_share=f21["peak_b2b_share"],
               fig21_peak_nut_angle_rad=f21["peak_b2b_nut_angle_rad"],
               fig21_peak_nut_angle_smoothed_rad=f21["peak_b2b_nut_angle_smoothed_rad"],
               fig21_zero_nut_angle_rad=f21["b2b_zero_nut_angle_rad"],
               fig21_b2g_torque_variation=f21["b2g_torque_variation"])
    return out, OK, ""


@dataclasses.dataclass(frozen=True)
class Model:
    """A model a sweep can run: its config root, case parameters, outputs and options."""

    name: str
    config_root: str
    outputs: tuple
    case_parameters: tuple
    options: dict                   # option -> (default, allowed values or type)
    run: object
    batch_size: dict                # samples per Dask task, by method (or "default")

    def load_base(self, path, overrides):
        """Load the base config of this model from a YAML path and/or overrides."""
        if self.config_root == "linear_bearing":
            from bb_friction_ros.config import load_linear_bearing
            return load_linear_bearing(path, overrides)
        from bb_friction_ros.model_file import load_ball_screw
        return load_ball_screw(path, overrides)

    def parameters(self, base):
        """Return {name: Parameter} a sample may set (case parameters, then config fields)."""
        out = {p.name: p for p in self.case_parameters}
        for name, p in config_parameters(base).items():
            out.setdefault(name, p)
        if self.name == "linear_pair":
            # rho is the per-sample side force ratio; the config field would be a second name.
            out.pop("side_force_ratio", None)
        return out

    def output(self, name):
        """Return the Output called ``name``."""
        return {o.name: o for o in self.outputs}[name]


# Samples per Dask task: about 0.2-1 s of work, so that the per-task cost of the scheduler
# (about a millisecond) stays well below 1 % of the work.
MODELS = {
    "linear_pair": Model("linear_pair", "linear_bearing", LINEAR_PAIR_OUTPUTS,
                         LINEAR_CASE_PARAMETERS,
                         {"method": ("numerical", ("numerical", "analytical"))},
                         run_linear_pair, {"numerical": 250, "analytical": 2000}),
    "screw_pair": Model("screw_pair", "ball_screw", SCREW_PAIR_OUTPUTS, (), {}, run_screw_pair,
                        {"default": 20}),
    "whole_screw": Model("whole_screw", "ball_screw", WHOLE_SCREW_OUTPUTS,
                         WHOLE_SCREW_PARAMETERS,
                         {"settle_steps": (0, int)}, run_whole_screw, {"default": 1}),
}


def evaluate(model, base, params, options, config_names):
    """
    Run one sample: (outputs, status, reason); never raises for a bad sample.

    ``params``: {parameter name: SI value}; the names in ``config_names`` go into a copy of
    ``base`` (range-checked), the rest are case parameters.
    """
    changes = {n: v for n, v in params.items() if n in config_names}
    case = {n: v for n, v in params.items() if n not in config_names}
    try:
        cfg = with_changes(base, changes, model.config_root)
        out, status, reason = model.run(cfg, case, options)
    except Exception as exc:       # a sample's failure is data: recorded, never dropped
        return {}, FAILED, f"{type(exc).__name__}: {exc}"[:MAX_REASON_CHARS]
    bad = [o.name for o in model.outputs if o.name in out and not _finite(out[o.name])]
    if bad:
        reason = "; ".join(filter(None, [reason, "non-finite: " + ", ".join(bad)]))
    return out, status, reason[:MAX_REASON_CHARS]


def _finite(x):
    return isinstance(x, (bool, np.bool_)) or math.isfinite(float(x))
