"""
Torque-fluctuation verdict of a ball screw, in the spirit of ISO 3408-3 (drag torque variation).

ISO 3408-3 accepts a preloaded ball screw when its drag torque stays within a band of +-x %
around the nominal torque over the useful travel.  Here, for a ``whole_screw`` sweep spec:

- the *variation* of one run is max |T - T_ref| / |T_ref| over the stroke (after
  ``settle_steps``, as the standard leaves out the ends of the travel), with T_ref the
  user's reference torque or, without one, the run's own mean friction torque;
- the *nominal build* is the spec's base config (and grid point) without the random
  tolerances; it passes if its variation is within the band;
- the *probability of failing* is the fraction of the Monte Carlo builds (the spec's random
  tolerances) whose variation exceeds the band, with a 95 % Wilson score interval.  Builds
  without a result (not converged, failed) are left out of that fraction and counted; the
  bound ``p_fail_if_missing_fail`` counts them as failures.

The nominal runs go to ``DIR/nominal``, the tolerance runs to ``DIR/tolerance`` (both
ordinary, resumable sweeps), the verdict to ``DIR/verdict.json``.
"""

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from bb_friction_ros.config import ConfigError
from bb_friction_ros.sweep.files import write_text_atomic
from bb_friction_ros.sweep.models import MODELS
from bb_friction_ros.sweep.report import column, with_numbers

NEEDED = ("torque_mean_nm", "torque_max_nm", "torque_min_nm", "torque_dev_max_rel")
# Standard normal quantile of a two-sided 95 % interval.
Z_95 = 1.959963984540054


def variation(table, reference_torque_nm=None):
    """Return max |T - T_ref| / |T_ref| of every run (NaN where a run has no result)."""
    ok = with_numbers(table)
    if reference_torque_nm is None:
        v = column(table, "torque_dev_max_rel")
    else:
        ref = float(reference_torque_nm)
        v = np.maximum(column(table, "torque_max_nm") - ref,
                       ref - column(table, "torque_min_nm")) / abs(ref)
    return np.where(ok, v, np.nan)


def wilson_interval(k, n, z=Z_95):
    """Return the Wilson score interval (lo, hi) of a proportion k / n (None if n = 0)."""
    if n == 0:
        return None
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def verdict_rows(spec, nominal, tolerance, band_rel, reference_torque_nm=None):
    """Return one verdict row per grid point from the nominal and tolerance tables."""
    v_nom = variation(nominal, reference_torque_nm)
    v_tol = variation(tolerance, reference_torque_nm).reshape(spec.n_grid, spec.samples)
    rows = []
    for g in range(spec.n_grid):
        runs = v_tol[g]
        have = np.isfinite(runs)
        n, k = int(have.sum()), int((runs[have] > band_rel).sum())
        missing = spec.samples - n
        ci = wilson_interval(k, n)
        point = {}
        if spec.grid:
            point = {a.name: a.values[i] for a, i in zip(spec.grid, np.unravel_index(
                g, spec.grid_shape))}
        nominal_v = float(v_nom[g])
        rows.append({
            "grid_point": point,
            "nominal_variation_rel": nominal_v if math.isfinite(nominal_v) else None,
            "nominal_pass": bool(nominal_v <= band_rel) if math.isfinite(nominal_v) else None,
            "n_builds": spec.samples, "n_with_result": n, "n_fail": k,
            "n_missing": missing,
            "p_fail": k / n if n else None,
            "p_fail_ci95": list(ci) if ci else None,
            "p_fail_if_missing_fail": (k + missing) / spec.samples,
            "variation_q50": float(np.quantile(runs[have], 0.5)) if n else None,
            "variation_q95": float(np.quantile(runs[have], 0.95)) if n else None,
        })
    return rows


def overall_pass(passes):
    """Return False if any nominal build fails, None if any has no result, else True."""
    if any(p is False for p in passes):
        return False
    return None if any(p is None for p in passes) else True


def verdict_specs(spec):
    """Return (nominal spec, tolerance spec) of a whole-screw spec with random tolerances."""
    if spec.model != "whole_screw":
        raise ConfigError(f"sweep.model: the torque-fluctuation verdict needs the whole "
                          f"screw (model: whole_screw), got {spec.model}")
    if not spec.variables:
        raise ConfigError("sweep.random: the verdict needs the tolerance distribution "
                          "(random variables and samples)")
    outputs = tuple(dict.fromkeys(spec.outputs + NEEDED))
    tolerance = dataclasses.replace(spec, outputs=outputs)
    nominal = dataclasses.replace(spec, name=spec.name + "-nominal", variables=(), samples=1,
                                  seed=0, outputs=outputs)
    return nominal, tolerance


def run_verdict(spec, out_dir, band_rel, reference_torque_nm=None, workers=None,
                scheduler=None, processes=True, progress=True, plots=True, log=None,
                connect_timeout_s=None):
    """Run the nominal and tolerance sweeps and write DIR/verdict.json; return the verdict."""
    from bb_friction_ros.sweep.engine import dask_client, run_sweep
    if not band_rel > 0:
        raise ConfigError(f"--band-pct: must be > 0, got {band_rel * 100}")
    if reference_torque_nm is not None and not (math.isfinite(reference_torque_nm)
                                                and reference_torque_nm != 0):
        raise ConfigError("--reference-torque-nm: must be finite and non-zero")
    nominal_spec, tolerance_spec = verdict_specs(spec)
    out_dir = Path(out_dir)
    with dask_client(workers, scheduler, processes, connect_timeout_s) as (client, _):
        runs = [run_sweep(s, out_dir / sub, progress=progress, plots=plots, log=log,
                          client=client)
                for s, sub in ((nominal_spec, "nominal"), (tolerance_spec, "tolerance"))]
    if not all(r.complete for r in runs):
        return None
    import pyarrow.parquet as pq
    tables = [pq.read_table(r.out_dir / "results.parquet") for r in runs]
    rows = verdict_rows(tolerance_spec, *tables, band_rel, reference_torque_nm)
    result = {
        "name": spec.name, "criterion": "max |T - T_ref| / |T_ref| over the stroke <= band "
        "(ISO 3408-3 spirit: drag torque variation)",
        "band_rel": band_rel,
        "reference": ("mean friction torque of each run" if reference_torque_nm is None
                      else f"{reference_torque_nm} N m"),
        "settle_steps": spec.option_map["settle_steps"],
        "tolerances": [{"name": v.name, "dist": v.kind, **{k: (list(p) if isinstance(
            p, tuple) else p) for k, p in v.params}} for v in spec.variables],
        "nominal_pass": overall_pass([r["nominal_pass"] for r in rows]),
        "rows": rows,
        "units": {n: MODELS["whole_screw"].output(n).unit for n in NEEDED},
    }
    path = out_dir / "verdict.json"
    write_text_atomic(path, json.dumps(result, indent=2))
    return result
