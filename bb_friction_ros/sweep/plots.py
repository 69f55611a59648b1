"""
Plots of a finished sweep (PNG), in display units (deg, mm or um, %).

- ``grid_heatmaps.png``: with two or more grid axes, one heatmap per output over the first two
  axes (Figs. 8-9 style); where a grid point has several values (random draws, further axes)
  the median is shown, as the title says.  With one axis: median against the axis, with the
  5-95 % band of the draws if there are draws.
- ``mc_histograms.png``: with random draws, a histogram per output with its 5, 50 and 95 %
  quantiles.
- ``sensitivity.png``: the first-order index of each varying input per output (report.py),
  Spearman's rho_S printed by each bar.
"""

import math
import warnings

from matplotlib.figure import Figure
import numpy as np

from bb_friction_ros.sweep.models import MODELS
from bb_friction_ros.sweep.report import column, with_numbers

# Dimensionless outputs shown in percent.
PERCENT = {"eps1", "eps2", "eps_diff", "friction_ratio", "friction_increase",
           "torque_band_rel", "torque_dev_max_rel", "b2b_share_max"}
# Lengths below this are shown in um rather than mm  [m].
MICRO_BELOW_M = 1e-4
PANEL_COLUMNS = 2
HIST_COLUMNS = 3
HIST_BINS = 40
DPI = 110


def display_input(name, values):
    """Return (label, values) of an input in display units."""
    values = np.asarray(values, dtype=float)
    short = name.rsplit(".", 1)[-1]
    if short.endswith("_rad"):
        return f"{name[:-4]} [deg]", np.degrees(values)
    if short.endswith("_m"):
        if np.nanmax(np.abs(values), initial=0.0) < MICRO_BELOW_M:
            return f"{name[:-2]} [um]", values * 1e6
        return f"{name[:-2]} [mm]", values * 1e3
    return name, values


def display_output(spec, name, values):
    """Return (label, values) of an output in display units."""
    unit = MODELS[spec.model].output(name).unit
    if name in PERCENT:
        return f"{name} [%]", np.asarray(values, dtype=float) * 100.0
    return (name if unit == "1" else f"{name} [{unit}]"), np.asarray(values, dtype=float)


def _float_outputs(spec):
    model = MODELS[spec.model]
    return [n for n in spec.outputs if model.output(n).dtype != "bool"]


def grid_medians(spec, table, name):
    """Return the median of output ``name`` per grid point, shaped like the grid (NaN: none)."""
    y = np.where(with_numbers(table), column(table, name), np.nan)
    return _nanmedian(y.reshape(spec.n_grid, spec.samples), 1).reshape(spec.grid_shape)


def _nanmedian(a, axis):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # an all-NaN point stays NaN
        return np.nanmedian(a, axis=axis)


def plot_grid(spec, table, path):
    """Write the heatmaps (or 1-D curves) of every output over the grid; return the path."""
    axes_used = [i for i, a in enumerate(spec.grid) if len(a.values) > 1]
    names = _float_outputs(spec)
    rows = math.ceil(len(names) / PANEL_COLUMNS)
    fig = Figure(figsize=(5.2 * PANEL_COLUMNS, 4.0 * rows))
    axs = fig.subplots(rows, PANEL_COLUMNS, squeeze=False)
    extra = spec.samples > 1 or len(axes_used) > 2
    for ax, name in zip(axs.flat, names):
        med = grid_medians(spec, table, name)
        label, _ = display_output(spec, name, [])
        if len(axes_used) >= 2:
            ix, iy = axes_used[:2]
            # Median over every other axis, then y rows x columns for pcolormesh.
            other = tuple(i for i in range(med.ndim) if i not in (ix, iy))
            z = _nanmedian(med, other) if other else med
            z = z if ix > iy else z.T
            xl, xv = display_input(spec.grid[ix].name, spec.grid[ix].values)
            yl, yv = display_input(spec.grid[iy].name, spec.grid[iy].values)
            _, zv = display_output(spec, name, z)
            mesh = ax.pcolormesh(xv, yv, zv, shading="nearest", cmap="viridis")
            if np.isfinite(zv).sum() > 3 and np.nanmax(zv) > np.nanmin(zv):
                ax.contour(xv, yv, zv, colors="w", linewidths=0.5)
            fig.colorbar(mesh, ax=ax, label=label)
            ax.set_xlabel(xl)
            ax.set_ylabel(yl)
        else:
            i = axes_used[0] if axes_used else 0
            xl, xv = display_input(spec.grid[i].name, spec.grid[i].values)
            _, yv = display_output(spec, name, med.reshape(-1))
            ax.plot(xv, yv, "o-", ms=3, label="median")
            if spec.samples > 1:
                y = np.where(with_numbers(table), column(table, name), np.nan)
                lo, hi = np.nanquantile(y.reshape(spec.n_grid, spec.samples), [0.05, 0.95],
                                        axis=1)
                _, lo = display_output(spec, name, lo)
                _, hi = display_output(spec, name, hi)
                ax.fill_between(xv, lo, hi, alpha=0.3, label="5-95 %")
                ax.legend(fontsize=8)
            ax.set_xlabel(xl)
            ax.set_ylabel(label)
            ax.grid(True)
        ax.set_title(name + (" (median over draws/other axes)" if extra else ""), fontsize=10)
    for ax in list(axs.flat)[len(names):]:
        ax.set_visible(False)
    fig.suptitle(f"{spec.name}: {spec.model} over the grid")
    return _save(fig, path)


def plot_histograms(spec, table, summary, path):
    """Write a histogram per output with its 5/50/95 % quantiles; return the path."""
    names = _float_outputs(spec)
    rows = math.ceil(len(names) / HIST_COLUMNS)
    fig = Figure(figsize=(4.4 * HIST_COLUMNS, 3.3 * rows))
    axs = fig.subplots(rows, HIST_COLUMNS, squeeze=False)
    mask = with_numbers(table)
    for ax, name in zip(axs.flat, names):
        label, y = display_output(spec, name, column(table, name)[mask])
        y = y[np.isfinite(y)]
        if y.size:
            ax.hist(y, bins=HIST_BINS, color="tab:blue", alpha=0.8)
            stats = summary["outputs"][name]
            for q, style in (("q05", ":"), ("q50", "-"), ("q95", "--")):
                _, v = display_output(spec, name, [stats[q]])
                ax.axvline(v[0], color="k", ls=style, lw=1, label=f"{q}: {v[0]:.4g}")
            ax.legend(fontsize=7)
        ax.set_xlabel(label)
        ax.set_ylabel("samples")
    for ax in list(axs.flat)[len(names):]:
        ax.set_visible(False)
    fig.suptitle(f"{spec.name}: {int(mask.sum())} samples with results of {table.num_rows}")
    return _save(fig, path)


def plot_sensitivity(spec, summary, path):
    """Write the first-order index bars per output (None if there is no ranking)."""
    by_output = summary["sensitivity"]["by_output"]
    if not by_output:
        return None
    names = list(by_output)
    rows = math.ceil(len(names) / PANEL_COLUMNS)
    fig = Figure(figsize=(5.5 * PANEL_COLUMNS, 0.5 + 0.5 * max(
        len(v["ranking"]) for v in by_output.values()) * rows + 1.0 * rows))
    axs = fig.subplots(rows, PANEL_COLUMNS, squeeze=False)
    for ax, name in zip(axs.flat, names):
        ranking = by_output[name]["ranking"][::-1]
        s = [np.nan_to_num(r["first_order"] if r["first_order"] is not None else np.nan)
             for r in ranking]
        ax.barh([r["input"] for r in ranking], s, color="tab:orange")
        for k, r in enumerate(ranking):
            rho = r["spearman"]
            ax.text(s[k], k, f"  rho_S {rho:+.2f}" if rho is not None else "", va="center",
                    fontsize=7)
        ax.set_xlim(0.0, 1.15)
        ax.set_xlabel("first-order index S = Var(E[Y|X]) / Var(Y)")
        ax.set_title(f"{name} (interactions: {by_output[name]['interactions']:.2f})",
                     fontsize=10)
    for ax in list(axs.flat)[len(names):]:
        ax.set_visible(False)
    fig.suptitle(f"{spec.name}: which input drives each output")
    return _save(fig, path)


def plot_all(spec, table, summary, out_dir):
    """Write every plot that applies to this sweep into ``out_dir``; return their paths."""
    paths = []
    if spec.grid and spec.n_grid > 1:
        paths.append(plot_grid(spec, table, out_dir / "grid_heatmaps.png"))
    if spec.samples > 1:
        paths.append(plot_histograms(spec, table, summary, out_dir / "mc_histograms.png"))
    sens = plot_sensitivity(spec, summary, out_dir / "sensitivity.png")
    if sens is not None:
        paths.append(sens)
    return paths


# Fraction of the figure height left above the panels for the suptitle.
TITLE_ROOM = 0.04


def _save(fig, path):
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - TITLE_ROOM))
    fig.savefig(path, dpi=DPI)
    return path
