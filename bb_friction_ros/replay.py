"""
``bb-friction replay``: a recording through exactly the live node's model path, offline.

Events are fed in log order to the same ``InputAssembler`` and ``ModelRunner`` the node uses,
so the predictions equal the node's for the same messages (tested).  Writes
``prediction.csv``, ``summary.json`` and PNG plots.
"""

import csv
import json
from pathlib import Path
import sys
import time

import numpy as np

from bb_friction_ros.bags import measured_torque_at, read_events, Topics
from bb_friction_ros.config import bundled_config
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.runner import build_runner, InputAssembler, InputError

CSV_COLUMNS = ["t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_pred_nm",
               "torque_b2b_nm"]


def run_events(events, runner, assembler, progress=False):
    """
    Feed events in order; return the predictions.

    Rejected inputs are counted in ``runner.stats`` (``rejected`` by reason), as the node
    counts them.
    """
    preds = []
    iterator = events
    if progress:
        from tqdm import tqdm
        iterator = tqdm(events, desc="replay", unit="msg", file=sys.stderr, mininterval=0.5)
    for ev in iterator:
        try:
            if ev.kind == "axial_load":
                assembler.on_axial_load(ev.value)
            elif ev.kind == "nut_state":
                sample = assembler.on_nut_state(ev.stamp_s, ev.names, ev.positions,
                                                ev.velocities)
                pred = runner.process(sample)
                if pred is not None:
                    preds.append(pred)
        except InputError as err:
            runner.reject(err.reason, nut_state=ev.kind == "nut_state")
    return preds


def replay(bag, out, config=None, settings=NodeParameters(), topics=Topics(), progress=True):
    """
    Replay ``bag`` into directory ``out``; return the summary dict.

    ``settings``: the node's parameters (``nut_joint``, ``model_rate_hz`` and
    ``max_axial_load_n`` shape the predictions); ``config`` is the model file (default:
    ``settings.config_file``, else the bundled ``config/ball_screw.yaml``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    events, counts = read_events(bag, topics)
    runner = build_runner(config or settings.config_file or bundled_config("ball_screw.yaml"),
                          settings.model_rate_hz)
    assembler = InputAssembler(settings.nut_joint, settings.max_axial_load_n)
    t0 = time.perf_counter()
    preds = run_events(events, runner, assembler, progress=progress)
    wall = time.perf_counter() - t0

    t = np.array([p.stamp_s for p in preds])
    pred = np.array([p.torque_total_nm for p in preds])
    meas = measured_torque_at(events, t) if preds else None
    write_prediction_csv(out / "prediction.csv", preds, meas)
    span = float(t.max() - t.min()) if t.size > 1 else 0.0
    summary = {
        "bag": str(bag),
        "messages": counts,
        "samples": len(preds),
        "rejected": dict(runner.stats.rejected),
        "resets": runner.stats.resets,
        "model_steps": runner.stats.model_steps,
        "nonconverged_steps": runner.stats.nonconverged_steps,
        "duration_s": span,
        "wall_s": wall,
        "speed_vs_realtime": span / wall if wall > 0 else None,
        "model_rate_hz": settings.model_rate_hz,
    }
    if meas is not None:
        ok = np.isfinite(meas)
        summary["rmse_nm"] = float(np.sqrt(np.mean((meas[ok] - pred[ok]) ** 2))) \
            if ok.any() else None
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    if preds:
        plot_replay(out, preds, meas)
    return summary


def write_prediction_csv(path, preds, meas=None):
    """
    Write one row per nut-state sample.

    ``torque_meas_nm`` is added when measured, ``torque_empirical_nm`` (last) when the model
    carries fitted terms; the first six columns never move.
    """
    empirical = any(p.torque_empirical_nm != 0.0 for p in preds)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS + (["torque_meas_nm"] if meas is not None else [])
                   + (["torque_empirical_nm"] if empirical else []))
        for i, p in enumerate(preds):
            row = [f"{p.stamp_s:.9f}", repr(p.nut_angle_rad), repr(p.nut_velocity_rad_s),
                   repr(p.axial_load_n), repr(p.torque_total_nm), repr(p.torque_b2b_nm)]
            if meas is not None:
                row.append(repr(float(meas[i])))
            if empirical:
                row.append(repr(p.torque_empirical_nm))
            w.writerow(row)


def plot_replay(out, preds, meas):
    """Predicted vs measured torque, and the B2B groups over time."""
    from matplotlib.figure import Figure
    t = np.array([p.stamp_s for p in preds])
    t = t - t[0]
    fig = Figure(figsize=(10, 8))
    ax = fig.subplots(3, 1, sharex=True)
    if meas is not None:
        ax[0].plot(t, meas, lw=0.6, color="0.5", label="measured")
    ax[0].plot(t, [p.torque_total_nm for p in preds], lw=1.0, label="predicted (total)")
    ax[0].plot(t, [p.torque_b2b_nm for p in preds], lw=1.0, label="predicted B2B part")
    ax[0].set_ylabel("friction torque [N m]")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, [p.nut_velocity_rad_s for p in preds], lw=0.8)
    ax[1].set_ylabel("nut speed [rad/s]")
    ax2 = ax[1].twinx()
    ax2.plot(t, [p.axial_load_n for p in preds], lw=0.8, color="C3")
    ax2.set_ylabel("axial load [N]", color="C3")
    ax[2].step(t, [len(p.groups) for p in preds], where="post", label="groups")
    ax[2].step(t, [max((len(g[0]) for g in p.groups), default=0) for p in preds],
               where="post", label="largest group (balls)")
    ax[2].set_ylabel("B2B contact groups")
    ax[2].set_xlabel("time [s]")
    ax[2].legend(fontsize=8)
    for a in ax:
        a.grid(True)
    fig.tight_layout()
    fig.savefig(Path(out) / "replay_torque_and_groups.png", dpi=110)
