"""
Feedforward along a planned trajectory: each row's friction torque at that row's time.

A controller that knows its path (a CNC program, a trajectory planner) can feed friction
forward at the *commanded* state instead of the measured one: at a reversal the measured
velocity is 0 while the axis sticks, and a feedforward of the measured state gives 0 N m until
the axis has moved.  Here the model is stepped along the planned nut angle, at every row (no
hold, no delay: the row's torque belongs to the row's time), sub-stepped where rows are
further apart than the model step, exactly as the runner steps.

What goes in ``torque_ff_nm``: friction only.  The model's physics and the fitted terms that
are friction (``empirical_terms.NOT_FRICTION`` left out: the loop feeds J alpha forward
itself, and gravity, lead error and runout ripple are not friction).  The runner's safety
rule holds: the friction answered never opposes the planned motion.

Breakaway: a standing row followed by a planned start within ``breakaway_lead_s`` carries the
breakaway torque in the direction of the coming motion (the model's friction an instant into
the motion); a standstill with nothing planned gets 0 N m.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.ball_screw.arrangement import mean_b2b
from bb_friction_ros.config import BBFrictionError, check_choice, field, from_mapping
from bb_friction_ros.empirical_terms import dahl_state, NOT_FRICTION, TermSet
from bb_friction_ros.model_file import NoPhysics
from bb_friction_ros.node_parameters import B2B_AVERAGED, B2B_FEEDFORWARDS, NodeParameters
from bb_friction_ros.drive import run_samples, SampleColumns, samples_of_events
from bb_friction_ros.runner import load_checked_model, ModelRunner

# The runner steps when the angle turned a model step, when the direction changed, or when a
# model period of stamps passed: a period far below any row spacing makes every row step.
EVERY_ROW_RATE_HZ = 1e9
# Speed at which the breakaway torque is asked of the model [rad/s]: an instant into the
# motion (1e-6 rad/s x 10 N m s/rad of viscous drag = 1e-5 N m).
BREAKAWAY_PROBE_RAD_S = 1e-6
COLUMNS = ("t_s", "torque_ff_nm", "torque_b2g_nm", "torque_b2b_nm", "torque_empirical_nm",
           "converged", "breakaway")


class PlannedTrajectoryError(BBFrictionError):
    """A planned trajectory that cannot be fed forward; the message names the row or field."""


@dataclasses.dataclass(frozen=True)
class PlannedSettings:
    """How a planned trajectory is fed forward (``feedforward:`` in a settings YAML)."""

    breakaway_lead_s: float = field(
        0.002, "s", "a standing row this close before a planned start carries the breakaway "
        "torque of the coming direction (2 ms: two servo periods at 1 kHz, so the command "
        "reaches breakaway as the start is commanded)", lo=0.0, hi=10.0)
    model_step_deg: float = field(
        1.8, "deg", "largest nut rotation between two model steps (sub-steps between rows "
        "further apart), as the node's model_step_deg", lo=0.01, hi=90.0)
    b2b_feedforward: str = field(
        B2B_AVERAGED, None, "the B2B torque fed forward: 'averaged' over the balls' "
        "arrangements, or the 'model' state's own (the node's b2b_feedforward)")

    def check(self, path):
        """Refuse an unknown ``b2b_feedforward``, naming it."""
        check_choice(f"{path}.b2b_feedforward", self.b2b_feedforward, B2B_FEEDFORWARDS)


def load_planned_settings(mapping, path="feedforward"):
    """Return validated PlannedSettings of a mapping (the dotted key is named)."""
    return from_mapping(PlannedSettings, mapping or {}, path)


@dataclasses.dataclass
class PlannedFeedforward:
    """The feedforward of a planned trajectory, one value per row (SI)."""

    t_s: np.ndarray
    torque_ff_nm: np.ndarray        # friction only; the sum of the three parts
    torque_b2g_nm: np.ndarray
    torque_b2b_nm: np.ndarray
    torque_empirical_nm: np.ndarray    # the friction terms' share
    converged: np.ndarray
    breakaway: np.ndarray           # the row carries the breakaway torque of a coming start
    terms_in: tuple                 # the fitted terms fed forward
    terms_out: tuple                # the fitted terms left out (not friction)
    friction_cut: int               # rows whose friction opposed the motion, cut to 0

    def summary(self):
        """Return summary.json's figures."""
        ff = self.torque_ff_nm
        return {"rows": int(ff.size), "nonconverged_rows": int((~self.converged).sum()),
                "breakaway_rows": int(self.breakaway.sum()),
                "friction_cut_rows": self.friction_cut,
                "max_abs_torque_ff_nm": float(np.max(np.abs(ff))) if ff.size else 0.0,
                "terms_fed_forward": list(self.terms_in),
                "terms_left_out": list(self.terms_out)}


def _check(t, phi, w, load):
    for name, v in (("t_s", t), ("nut_angle_rad", phi), ("nut_velocity_rad_s", w),
                    ("axial_load_n", load)):
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise PlannedTrajectoryError(f"{name}: row {int(bad[0])} is not finite ({v[bad[0]]})")
    if t.size == 0:
        raise PlannedTrajectoryError("the trajectory has no rows")
    back = np.flatnonzero(np.diff(t) <= 0.0)
    if back.size:
        i = int(back[0]) + 1
        raise PlannedTrajectoryError(f"t_s: row {i} ({t[i]:.9g} s) is not after row {i - 1} "
                                     f"({t[i - 1]:.9g} s); a plan's times must increase")


def planned_feedforward(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n, config_path,
                        settings=PlannedSettings()):
    """
    Return the PlannedFeedforward of a planned trajectory (module docstring).

    Parameters
    ----------
    t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n : array_like
        The plan's rows: time [s] (increasing), nut angle [rad], nut velocity [rad/s],
        axial load [N].
    config_path : path
        Model file (``config/ball_screw.yaml``, or a discrepancy ``augmented.yaml``).
    settings : PlannedSettings
        The breakaway lead and the model step.

    Returns
    -------
    PlannedFeedforward

    """
    t, phi, w, load = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (
        t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)))
    _check(t, phi, w, load)
    cfg, terms, screw = load_checked_model(config_path)
    mean = mean_b2b(cfg) if settings.b2b_feedforward == B2B_AVERAGED \
        and not isinstance(screw, NoPhysics) else None
    friction = TermSet(x for x in terms.terms if x.name not in NOT_FRICTION)
    runner = ModelRunner(screw, EVERY_ROW_RATE_HZ, friction if len(friction) else None,
                         settings.model_step_deg,
                         max(NodeParameters().max_model_step_deg, settings.model_step_deg), 0.0,
                         mean)
    n = t.size
    out = {c: np.zeros(n) for c in ("ff", "b2g", "b2b", "emp")}
    p = run_samples(runner, SampleColumns.of(t, phi, w, load), stop_at_error=True)
    if len(p) < n or not p.answered.all():
        raise PlannedTrajectoryError(f"row {len(p) - 1}: the model failed "
                                     f"({runner.stats.last_error})")
    moving = w != 0.0
    if mean is None:
        out["ff"][moving], out["b2g"][moving] = p.torque_total_nm[moving], p.torque_b2g_nm[moving]
        out["b2b"][moving] = p.torque_b2b_nm[moving]
    else:                               # the physics averaged over the balls' arrangements
        out["ff"][moving] = p.feedforward_nm[moving]
        for k in np.flatnonzero(moving):
            out["b2b"][k] = mean.at(load[k], w[k])
            out["b2g"][k] = mean.total_at(load[k], w[k]) - out["b2b"][k]
    out["emp"][moving] = p.torque_empirical_nm[moving]
    converged = p.converged
    breakaway = _breakaway_rows(t, w, settings.breakaway_lead_s)
    # the pre-rolling terms' state along the plan (as the runner's): a start against the
    # last motion has no breakaway peak, its friction builds up over the travel
    pre_rolling = [(x.params.torque_nm, dahl_state(phi, t, x.params.travel_rad, w))
                   for x in friction.terms if x.name == "pre_rolling"]
    for k in np.flatnonzero(breakaway):
        start = k + int(np.argmax(w[k:] != 0.0))
        direction = math.copysign(1.0, w[start])
        lag = sum(a * (z[k] - direction) for a, z in pre_rolling)
        total, b2g, b2b, emp = breakaway_torque(screw, friction, phi[k], direction, load[k],
                                                lag)
        if mean is not None and total != 0.0:   # the physics averaged over arrangements
            physics = mean.total_at(load[k], direction)
            total = emp + physics
            b2b = mean.at(load[k], direction)
            b2g = physics - b2b
        out["ff"][k], out["b2g"][k], out["b2b"][k], out["emp"][k] = total, b2g, b2b, emp
    return PlannedFeedforward(t, out["ff"], out["b2g"], out["b2b"], out["emp"], converged,
                              breakaway, friction.names,
                              tuple(x.name for x in terms.terms if x.name in NOT_FRICTION),
                              runner.stats.friction_cut)


def _breakaway_rows(t, w, lead_s):
    """Return the standing rows followed by a start within ``lead_s`` (mask)."""
    moving = w != 0.0
    rows = np.zeros(t.size, dtype=bool)
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    for s in starts:
        k = s - 1
        while k >= 0 and not moving[k] and t[s] - t[k] <= lead_s + 1e-12:
            rows[k] = True
            k -= 1
    return rows


def breakaway_torque(screw, terms, nut_angle_rad, direction, axial_load_n, pre_rolling_nm=0.0):
    """
    Return the friction an instant into a motion (total, b2g, b2b, terms) [N m].

    A cold model step at ``BREAKAWAY_PROBE_RAD_S`` in ``direction`` (the balls' arrangement
    of a start is not known ahead: a fresh one), plus the friction terms at that speed; the
    pre-rolling terms add ``pre_rolling_nm`` (their state at the start, not a fresh one).
    Cut to 0 where that friction would oppose the coming motion.
    """
    import copy
    probe = copy.copy(screw)
    probe.reset(nut_angle_rad)
    res = probe.step(nut_angle_rad, direction * BREAKAWAY_PROBE_RAD_S, axial_load_n, 0.0)
    steady = TermSet(x for x in terms.terms if x.name != "pre_rolling")
    emp = pre_rolling_nm + (float(steady.friction_nm(
        0.0, nut_angle_rad, direction * BREAKAWAY_PROBE_RAD_S, axial_load_n))
        if len(steady) else 0.0)
    total = float(res.torque_total_nm) + emp
    if total * direction < 0.0:         # never against the coming motion
        return 0.0, 0.0, 0.0, 0.0
    return total, float(res.torque_b2g_nm), float(res.torque_b2b_nm), emp


TRAJECTORY_COLUMNS = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n")


def read_trajectory(path, nut_joint="nut_joint"):
    """
    Return (t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n) of a CSV or a bag.

    CSV: a header row with ``TRAJECTORY_COLUMNS`` (other columns ignored).  Bag: the
    ``nut_state`` samples of ``nut_joint``, each with the axial load last received
    (``runner.InputAssembler``, the node's own checks).
    """
    from pathlib import Path
    path = Path(path)
    if path.is_dir():
        return _bag_trajectory(path, nut_joint)
    if not path.is_file():
        raise PlannedTrajectoryError(f"{path}: no such CSV file or bag directory")
    import csv
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.DictReader(fh)
            header = reader.fieldnames or []
            missing = [c for c in TRAJECTORY_COLUMNS if c not in header]
            if missing:
                raise PlannedTrajectoryError(
                    f"{path}: lacks column(s) {', '.join(missing)} (needs "
                    f"{', '.join(TRAJECTORY_COLUMNS)}; has: {', '.join(header) or 'no header'})")
            cols = {c: [] for c in TRAJECTORY_COLUMNS}
            for line, row in enumerate(reader, start=2):
                for c in TRAJECTORY_COLUMNS:
                    try:
                        cols[c].append(float(row[c]))
                    except (TypeError, ValueError):
                        raise PlannedTrajectoryError(f"{path}: line {line}, column {c}: not a "
                                                     f"number ({row[c]!r})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PlannedTrajectoryError(f"{path}: cannot read ({exc})") from None
    return tuple(np.array(cols[c]) for c in TRAJECTORY_COLUMNS)


def _bag_trajectory(path, nut_joint):
    from bb_friction_ros.bags import read_events
    events, _ = read_events(path)
    cols = samples_of_events(events, nut_joint, NodeParameters().max_axial_load_n)
    if not len(cols):
        raise PlannedTrajectoryError(f"{path}: no nut_state sample of joint {nut_joint!r} with "
                                     "an axial load before it")
    return cols.stamp_s, cols.nut_angle_rad, cols.nut_velocity_rad_s, cols.axial_load_n


def write_feedforward(out, ff, config_path, source):
    """Write ``out/feedforward.csv`` and ``out/summary.json`` (last, with ``complete``)."""
    import json
    from pathlib import Path
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "feedforward.csv", "w") as fh:
        fh.write(",".join(COLUMNS) + "\n")
        for row in zip(ff.t_s, ff.torque_ff_nm, ff.torque_b2g_nm, ff.torque_b2b_nm,
                       ff.torque_empirical_nm, ff.converged, ff.breakaway):
            fh.write(",".join(repr(float(v)) for v in row[:5])
                     + f",{int(row[5])},{int(row[6])}\n")
    summary = {"trajectory": str(source), "config": str(config_path), **ff.summary(),
               "complete": True}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False))
    return summary


def trajectory_rows(joint_names, times_from_start_s, positions, velocities, nut_joint,
                    start_s):
    """
    Return (t_s, nut_angle_rad, nut_velocity_rad_s, index of the nut joint) of a trajectory.

    The arrays of a ``trajectory_msgs/JointTrajectory`` (``joint_trajectory_controller``'s
    message): ``positions[k]`` and ``velocities[k]`` the k-th point's, one per joint (a point
    without velocities: central differences of the nut's positions in time).  ``start_s`` is
    the header stamp (the caller puts "now" for a stamp of 0, as the controller does).  Raises
    PlannedTrajectoryError naming what is missing.
    """
    names = list(joint_names)
    if nut_joint not in names:
        raise PlannedTrajectoryError(f"no joint named {nut_joint!r} in the trajectory "
                                     f"(joint_names {names})")
    j = names.index(nut_joint)
    if not len(positions):
        raise PlannedTrajectoryError("the trajectory has no points")
    phi, w = [], []
    for k, pos in enumerate(positions):
        if len(pos) != len(names):
            raise PlannedTrajectoryError(f"point {k}: {len(pos)} positions for {len(names)} "
                                         "joints")
        phi.append(float(pos[j]))
        v = velocities[k] if k < len(velocities) else ()
        w.append(float(v[j]) if len(v) == len(names) else math.nan)
    t = start_s + np.asarray(times_from_start_s, dtype=float)
    phi, w = np.array(phi), np.array(w)
    if np.isnan(w).any():
        if t.size < 2:
            raise PlannedTrajectoryError("a one-point trajectory needs its velocity")
        w = np.where(np.isnan(w), np.gradient(phi, t), w)
    return t, phi, w, j
