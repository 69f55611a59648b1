"""
Summary of a finished sweep: counts, per-output quantiles and the sensitivity ranking.

Statistics use the samples that have numbers (status ``ok`` or ``invalid``; ``invalid`` ones
are solved but flagged, e.g. two-point contact, and counted in ``n_invalid``).

Sensitivity (which input drives an output), over the inputs that vary in the sweep:

- First-order index S_i = Var(E[Y | X_i]) / Var(Y) (the correlation ratio, Sobol's
  first-order index), estimated by binning X_i into equal-count bins (its distinct values if
  there are few) and corrected for the bias of binning like an adjusted R^2.  It is
  variance-based and model-free, so it also sees an input whose effect is not monotone: B2B
  contact needs eps_1 > eps_2, which flips with the sign of theta times rho, so F_B2B grows
  with |theta| and a rank correlation with theta is near zero.  **The ranking is by S_i.**
  ``interactions`` = 1 - sum S_i is the share of the variance no input explains alone (on
  the Figs. 8-9 grid nearly all of it: contact needs theta and rho of opposite signs).
- Spearman rank correlation rho_S: the direction of a monotone effect.
- Standardised regression coefficients (SRC: least squares on inputs and output scaled to
  unit standard deviation) with the R^2 of that linear fit: SRC_i^2 is input i's share of
  the variance when R^2 is near 1; with a low R^2 the SRC are not to be trusted.
"""

from collections import Counter
import json
import math
import os

import numpy as np

from bb_friction_ros.sweep.files import write_text_atomic
from bb_friction_ros.sweep.models import FAILED, INVALID, MODELS, NONCONVERGED, OK

QUANTILES = (0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99)
# Fewer samples with numbers than this (or than inputs + this) give no sensitivity ranking:
# rank correlations of a handful of points are noise.
MIN_SENSITIVITY_SAMPLES = 10
# Bins of the first-order index: about sqrt(n) samples per bin and sqrt(n) bins, at most this
# many (more bins only add estimator noise).
MAX_BINS = 50
# Failure reasons listed in the summary (most frequent first); the table has all of them.
MAX_REASONS = 10


def column(table, name):
    """Return a column as a float numpy array (nulls as NaN)."""
    return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=float)


def with_numbers(table):
    """Return a boolean mask of the rows that have outputs (status ok or invalid)."""
    status = np.asarray(table.column("status").to_pylist())
    return (status == OK) | (status == INVALID)


def output_statistics(values):
    """Return mean, std, min, quantiles and max of the finite values (None if there are none)."""
    v = values[np.isfinite(values)]
    stats = {"n": int(v.size)}
    if not v.size:
        return stats
    stats.update(mean=float(v.mean()), std=float(v.std(ddof=1)) if v.size > 1 else 0.0,
                 min=float(v.min()))
    for q, x in zip(QUANTILES, np.quantile(v, QUANTILES)):
        stats[f"q{round(q * 100):02d}"] = float(x)
    stats["max"] = float(v.max())
    return stats


def rank(x):
    """Return average ranks (ties share their mean rank), as Spearman's rho uses."""
    from scipy.stats import rankdata
    return rankdata(x)


def first_order_index(x, y):
    """
    Return the binned estimate of S = Var(E[y | x]) / Var(y), bias-corrected, in [0, 1].

    Bins: the distinct values of x if there are at most sqrt(n) of them (a grid axis), else
    about sqrt(n) equal-count bins (at most MAX_BINS).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n = y.size
    n_bins = int(min(MAX_BINS, max(2, math.isqrt(n))))
    values, groups = np.unique(x, return_inverse=True)
    if values.size > n_bins:
        edges = np.quantile(x, np.linspace(0.0, 1.0, n_bins + 1)[1:-1])
        groups = np.searchsorted(edges, x, side="right")
    counts = np.bincount(groups)
    used = counts > 0
    means = np.bincount(groups, weights=y)[used] / counts[used]
    k = int(used.sum())
    total = float(np.sum((y - y.mean()) ** 2))
    if total == 0.0 or n <= k:
        return math.nan
    between = float(np.sum(counts[used] * (means - y.mean()) ** 2))
    adjusted = 1.0 - (1.0 - between / total) * (n - 1) / (n - k)
    return float(min(1.0, max(0.0, adjusted)))


def sensitivity(inputs, output):
    """
    Return first-order index, Spearman rho_S and SRC per input, and R^2 of the linear fit.

    ``inputs``: {name: array}, ``output``: array, same length, all finite.
    """
    names = list(inputs)
    y = np.asarray(output, dtype=float)
    x = np.column_stack([np.asarray(inputs[n], dtype=float) for n in names])
    out = {"first_order": {}, "spearman": {}, "src": {}, "r2_linear": None}
    if np.ptp(y) == 0.0:
        return out
    ry = rank(y)
    for j, n in enumerate(names):
        out["first_order"][n] = first_order_index(x[:, j], y)
        out["spearman"][n] = float(np.corrcoef(rank(x[:, j]), ry)[0, 1])
    xs = (x - x.mean(axis=0)) / x.std(axis=0)
    ys = (y - y.mean()) / y.std()
    coef, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    resid = ys - xs @ coef
    out["src"] = {n: float(c) for n, c in zip(names, coef)}
    out["r2_linear"] = float(1.0 - resid @ resid / (ys @ ys))
    return out


def sensitivity_ranking(spec, table):
    """Return the sensitivity of every float output to the inputs that vary (or None)."""
    model = MODELS[spec.model]
    mask = with_numbers(table)
    varying = [n for n in spec.input_names if _spread(column(table, n)[mask]) > 0]
    result = {"method": "ranking by the first-order index S = Var(E[Y|X])/Var(Y) (binned, "
                        "bias-corrected); also Spearman rank correlation and standardised "
                        "regression coefficients (SRC) with the R^2 of the linear fit",
              "inputs": varying, "by_output": {}}
    if not varying:
        return result
    for name in spec.outputs:
        if model.output(name).dtype == "bool":
            continue
        y = column(table, name)
        ok = mask & np.isfinite(y)
        if ok.sum() < max(MIN_SENSITIVITY_SAMPLES, len(varying) + MIN_SENSITIVITY_SAMPLES):
            continue
        here = [n for n in varying if _spread(column(table, n)[ok]) > 0]
        s = sensitivity({n: column(table, n)[ok] for n in here}, y[ok])
        if not s["spearman"]:
            continue        # a constant output has no sensitivity
        order = sorted(here, key=lambda n: -np.nan_to_num(s["first_order"][n], nan=-1.0))
        result["by_output"][name] = {
            "ranking": [{"input": n, "first_order": s["first_order"][n],
                         "spearman": s["spearman"][n], "src": s["src"][n]} for n in order],
            "interactions": _interactions(s["first_order"]),
            "r2_linear": s["r2_linear"], "n": int(ok.sum())}
    return result


def _interactions(first_order):
    """Return 1 - sum of the first-order indices: the variance share of interactions."""
    total = sum(v for v in first_order.values() if v is not None and math.isfinite(v))
    return float(max(0.0, 1.0 - total))


def _spread(x):
    return float(np.ptp(x)) if x.size else 0.0


def timing(history):
    """
    Return the computing figures of a sweep, summed over the invocations that computed.

    ``wall_s``: wall time of those invocations (cluster start to last result);
    ``samples_per_s``: samples computed per second of compute time (first task submitted to
    last result saved); ``workers``, ``threads``, ``scheduler``: of the last invocation.
    """
    computed = sum(r["n_computed"] for r in history)
    compute_s = sum(r["compute_wall_s"] for r in history)
    last = history[-1] if history else {}
    return {"wall_s": sum(r["wall_s"] for r in history), "compute_wall_s": compute_s,
            "samples_per_s": computed / compute_s if computed and compute_s else None,
            "n_computed": computed, "invocations": len(history),
            "workers": last.get("workers"), "threads": last.get("threads"),
            "scheduler": last.get("scheduler")}


def summarize(spec, table, history):
    """Return the summary mapping of a finished sweep (see docs/sweeps.md)."""
    model = MODELS[spec.model]
    status = Counter(table.column("status").to_pylist())
    mask = with_numbers(table)
    reasons = Counter(r for s, r in zip(table.column("status").to_pylist(),
                                        table.column("reason").to_pylist())
                      if s in (FAILED, NONCONVERGED))
    outputs = {}
    for name in spec.outputs:
        stats = output_statistics(column(table, name)[mask])
        outputs[name] = {"unit": model.output(name).unit, **stats}
    return {
        "name": spec.name, "model": spec.model, "spec_digest": spec.digest(),
        "source": spec.source, "n_samples": table.num_rows,
        "n_ok": status[OK], "n_invalid": status[INVALID],
        "n_nonconverged": status[NONCONVERGED], "n_failed": status[FAILED],
        "failure_reasons": dict(reasons.most_common(MAX_REASONS)),
        "outputs": outputs,
        "sensitivity": sensitivity_ranking(spec, table),
        **timing(history), "cpu_count": os.cpu_count(),
    }


def _json_safe(x):
    """Replace non-finite floats by None (JSON has no NaN)."""
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_summary(spec, table, history, out_dir):
    """Write DIR/summary.json; return the summary."""
    summary = _json_safe(summarize(spec, table, history))
    path = out_dir / "summary.json"
    write_text_atomic(path, json.dumps(summary, indent=2))
    return summary
