"""
The servo test's driver: the plant and the loop stepped together, one run per mode.

Per servo sample t_k: the encoder reads the plant's angle, the loop estimates the velocity,
the mode answers its feedforward, the cascade computes the command (``controller``), and
the plant moves one period under the command applied then plus the recording's command
offset (``plant``).  Every mode runs the same reference on a plant of its own, started in
the same state (at rest at the first measured angle, or the reference's first value).

The baselines are fitted on a calibration run (``calibrate``): a recording given with
``--calibration``, or else the plant itself in the loop (no feedforward) over constant-speed
moves at fractions of the test's largest speed, its drive torque and encoder angle taken as
a user would log them.
"""

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from bb_friction_ros.config import BBFrictionError, ConfigError
from bb_friction_ros.empirical_terms import zero_phase_acceleration
from bb_friction_ros.model_file import load_model_file
from bb_friction_ros.runner import InputSample
from bb_friction_ros.servo import baselines, modes as modes_mod
from bb_friction_ros.servo.controller import Cascade
from bb_friction_ros.servo.metrics import standing_mask
from bb_friction_ros.servo.plant import (lead_of, ModelFriction, Plant, plant_inertia,
                                         plant_presliding_rad, quantise,
                                         RigidBodyFriction)
from bb_friction_ros.servo.reference import _moves, Axis, load_reference, Reference
from bb_friction_ros.discrepancy.servo_moves import sample_moves

MEASURED_CHANNELS = ("nut_angle_rad", "torque_meas_nm")


@dataclasses.dataclass
class AxisRun:
    """One axis of one mode's run, sample by sample (SI)."""

    t_s: np.ndarray
    ref_rad: np.ndarray
    angle_rad: np.ndarray           # the plant's angle at t_k
    velocity_rad_s: np.ndarray      # the plant's velocity at t_k
    measured_rad: np.ndarray        # the encoder's reading
    command_nm: np.ndarray          # computed at t_k, after the limit, offset included
    applied_nm: np.ndarray          # acting from t_k, offset included
    friction_nm: np.ndarray         # the plant's friction at t_k (the held torque at rest)
    feedforward_nm: np.ndarray
    counters: dict

    @property
    def error_rad(self):
        """Return the following error reference - angle [rad]."""
        return self.ref_rad - self.angle_rad


def run_in(process, t0_s, angle_rad, load_n, revolutions, speed_rad_s):
    """
    Turn a runner's balls ``revolutions`` back, then forward to ``angle_rad`` at ``t0_s``.

    ``process(t, angle, velocity, load)`` feeds one sample.  Ends moving forward: the
    run-in arrangement of the forward direction (groups of balls after some turns).
    """
    if revolutions <= 0.0:
        return
    travel = 2.0 * math.pi * revolutions
    dt = min(math.radians(0.36) / speed_rad_s, 1e-3)
    n = max(2, int(math.ceil(travel / speed_rad_s / dt)))
    t = t0_s - (2 * n + 3) * dt
    for w, start in ((-speed_rad_s, angle_rad), (speed_rad_s, angle_rad - travel)):
        for i in range(n + 1):
            process(t, start + math.copysign(travel, w) * i / n, w, load_n)
            t += dt


class Setup:
    """What every run of one servo test shares: settings, files, fits, reference."""

    def __init__(self, settings, model_path, plant_path=None, model_path_y=None):
        """Check the files and the inertia; nothing is simulated yet."""
        self.settings = settings
        self.model_path = str(model_path)
        self.plant_path = str(plant_path or model_path)
        self.model_path_y = str(model_path_y) if model_path_y else None
        for p in (self.model_path, self.plant_path, self.model_path_y):
            if p is not None:
                load_model_file(p)          # a bad file is refused before any work
        self.inertia = plant_inertia(settings.plant.inertia_kg_m2, self.plant_path,
                                     settings.source or "LOOP.yaml")
        self.lead_m = lead_of(self.model_path)
        self.default_load = float(load_model_file(self.plant_path)[0].operation.axial_load_n)
        self.presliding_rad = [plant_presliding_rad(settings.plant.presliding_rad, p)
                               for p in (self.plant_path, self.model_path_y or self.plant_path)]
        self.fits = {}
        self.safety_gate = True     # False: every mode's feedforward passes ungated (a study)

    # --- the parts of a run ---------------------------------------------------------------

    def plant_law(self, axis_index=0):
        """Return a fresh friction law of the plant (run in when the settings say so)."""
        ps = self.settings.plant
        path = self.plant_path if axis_index == 0 or not self.model_path_y \
            else self.model_path_y
        # the plant's Dahl element carries the pre-sliding: the term would count it twice
        drop = ("pre_rolling",) if self.presliding_rad[axis_index] > 0.0 else ()
        return ModelFriction(path, ps.model_rate_hz, ps.model_step_deg, drop)

    def prepare_law(self, law, angle0, load0):
        """Run a plant law in when the plant's ball state is ``run_in``."""
        ps = self.settings.plant
        if ps.ball_state == "run_in":
            run_in(law.torque, 0.0, angle0, load0, ps.run_in_revolutions, ps.run_in_speed_rad_s)
        return law

    def mode(self, name, angle0, load0, axis_index=0, reference=None, axis=None):
        """Return the Mode object ``name`` for one axis (``planned``: of its reference)."""
        if name == "none":
            return modes_mod.Mode("none")
        if name == "planned":
            return self.planned_mode(reference, axis, axis_index)
        if name.startswith("coulomb_viscous"):
            return modes_mod.CoulombViscousMode(name, self.fits["coulomb_viscous"])
        if name.startswith("lugre"):
            return modes_mod.LuGreMode(name, self.fits["lugre"])
        if name.startswith("model"):
            path = self.model_path if axis_index == 0 or not self.model_path_y \
                else self.model_path_y
            runner = modes_mod.model_runner(path, self.settings.model)
            if self.settings.model.ball_state == "run_in":
                ps = self.settings.plant
                run_in(lambda *a: runner.process(InputSample(*a)), 0.0, angle0, load0,
                       ps.run_in_revolutions, ps.run_in_speed_rad_s)
            return modes_mod.ModelMode(name, runner)
        if name == "truth":
            return modes_mod.TruthMode(name, self.prepare_law(self.plant_law(axis_index),
                                                              angle0, load0),
                                       self.presliding_rad[axis_index])
        raise ConfigError(f"--modes: unknown mode {name!r} (known: "
                          f"{', '.join(modes_mod.ALL_MODES)})")

    def planned_mode(self, reference, axis, axis_index):
        """Return the ``planned`` mode: the reference's planned feedforward, computed ahead."""
        from bb_friction_ros.planned import planned_feedforward, PlannedSettings
        path = self.model_path if axis_index == 0 or not self.model_path_y \
            else self.model_path_y
        t = reference.t_s
        w_ref = axis.ref_velocity(t)
        ms = self.settings.model
        ff = planned_feedforward(t, axis.ref_rad, w_ref, self.loads(reference, axis), path,
                                 PlannedSettings(model_step_deg=ms.model_step_deg,
                                                 b2b_feedforward=ms.b2b_feedforward))
        return modes_mod.PlannedMode("planned", t, ff.torque_ff_nm, w_ref, ff.breakaway)

    def loads(self, reference, axis):
        """Return the axial load of every sample [N]."""
        n = reference.t_s.size
        if axis.axial_load_n is not None:
            return axis.axial_load_n
        load = reference.axial_load_n if reference.axial_load_n is not None \
            else self.default_load
        return np.full(n, load)

    # --- a run ----------------------------------------------------------------------------

    def simulate_axis(self, reference, axis, mode, law=None, inertia=None, axis_index=0):
        """Run one axis with feedforward ``mode``; return its AxisRun."""
        loop = self.settings.loop
        t = reference.t_s
        j = self.inertia if inertia is None else inertia
        load = self.loads(reference, axis)
        offset = axis.command_offset_nm if axis.command_offset_nm is not None \
            else np.zeros(t.size)
        angle0 = float(axis.meas_rad[0]) if axis.meas_rad is not None else float(axis.ref_rad[0])
        # a law given here (the rigid-body reference) has no pre-sliding of its own
        presliding = None
        if law is None:
            law = self.prepare_law(self.plant_law(axis_index), angle0, float(load[0]))
            presliding = self.presliding_rad[axis_index]
        plant = Plant(law, j, self.settings.plant, angle0, presliding)
        mode.gate = self.safety_gate
        ctl = Cascade(loop, j)
        w_ref = axis.ref_velocity(t)
        a_ref = axis.ref_accel(t)
        n = t.size
        out = {k: np.zeros(n)
               for k in ("angle", "velocity", "meas", "cmd", "applied", "friction", "ff")}
        period = loop.period_s
        counts = loop.encoder_counts_per_rev
        ref = axis.ref_rad
        for k in range(n):
            meas = quantise(plant.angle, counts)
            w_est = ctl.velocity_estimate(meas)
            ff = mode.value(t[k], meas, w_est, ref[k], w_ref[k], load[k], plant.velocity)
            cmd, applied = ctl.step(meas, w_est, ref[k], w_ref[k], a_ref[k], ff)
            out["angle"][k] = plant.angle
            out["velocity"][k] = plant.velocity
            out["meas"][k] = meas
            out["cmd"][k] = cmd + offset[k]
            out["applied"][k] = applied + offset[k]
            out["ff"][k] = ff
            out["friction"][k] = plant.advance(t[k], period, applied + offset[k], load[k])
        counters = {"stick_substeps": plant.stick_substeps, "breakaways": plant.breakaways,
                    "torque_limited": ctl.limited, "feedforward_wrong_sign": mode.wrong_sign,
                    "feedforward_against_motion": mode.against_motion,
                    "plant_model_errors": law.errors,
                    "plant_nonconverged_steps": _nonconverged(law),
                    "feedforward_nonconverged_steps": _nonconverged(mode),
                    "feedforward_model_errors": getattr(mode, "errors", 0)}
        return AxisRun(t, ref, out["angle"], out["velocity"], out["meas"], out["cmd"],
                       out["applied"], out["friction"], out["ff"], counters)

    def run_mode(self, reference, name):
        """Run every axis of ``reference`` with mode ``name``; return [AxisRun]."""
        runs = []
        for i, axis in enumerate(reference.axes):
            load = self.loads(reference, axis)
            angle0 = float(axis.meas_rad[0]) if axis.meas_rad is not None \
                else float(axis.ref_rad[0])
            mode = self.mode(name, angle0, float(load[0]), i, reference, axis)
            try:
                runs.append(self.simulate_axis(reference, axis, mode, axis_index=i))
            finally:
                mode.close()
        return runs

    # --- calibration ----------------------------------------------------------------------

    def calibration_reference(self, reference):
        """Return the calibration run's reference: constant-speed moves (module docstring)."""
        loop, cs = self.settings.loop, self.settings.calibration
        t = reference.t_s
        w_max = max(float(np.abs(a.ref_velocity(t)).max()) for a in reference.axes)
        a_max = max(float(np.abs(a.ref_accel(t)).max()) for a in reference.axes)
        w_max = max(w_max, 0.1)
        accel = max(min(a_max, 50.0 * w_max), w_max / 0.05)
        speeds = [f * w_max for f in cs.fractions()]
        times, alphas, end = [], [], 0.0
        for w in speeds:
            stroke = w * cs.cruise_s + w * w / accel
            tt, aa, dur = _moves([w], stroke, accel, 0.1, 1)
            times.extend((tt[:-1] + end).tolist())
            alphas.extend(aa[:-1].tolist())
            end += dur
        times.append(end)
        alphas.append(0.0)
        tc = np.arange(0.0, end + 0.2, loop.period_s)
        start = float(reference.axes[0].ref_rad[0])
        phi, _, _ = sample_moves(np.array(times), np.array(alphas), tc)
        load = self.loads(reference, reference.axes[0])
        axis = Axis("calibration", start + phi,
                    axial_load_n=np.full(tc.size, float(np.median(load))))
        return Reference(tc, [axis], "calibration", "calibration run of the plant")

    def calibrate(self, reference, calibration_csv=None):
        """Fit the baselines (module docstring); return the Calibration used."""
        cs = self.settings.calibration
        if calibration_csv is not None:
            cal = read_calibration(calibration_csv, cs.accel_cutoff_hz)
        else:
            cref = self.calibration_reference(reference)
            run = self.simulate_axis(cref, cref.axes[0], modes_mod.Mode("none"))
            w = np.gradient(run.measured_rad, run.t_s)
            a = zero_phase_acceleration(run.t_s, w, cs.accel_cutoff_hz, math.inf)
            cal = baselines.Calibration(run.t_s, run.measured_rad, w, a, run.applied_nm,
                                        cref.source)
        self.fits["coulomb_viscous"] = baselines.CoulombViscous.fit(cal, self.inertia)
        self.fits["lugre"] = baselines.fit_lugre(cal, self.inertia, cs.lugre_max_evaluations)
        return cal

    # --- the measured loop ----------------------------------------------------------------

    def rigid_body_reference(self, calibration_csv=None):
        """
        Return (coefficients {j, c, T_c, T_0}, where from) of the rigid-body reference.

        Fitted here on ``--calibration``; else the discrepancy workflow's own fit on all
        usable samples of its fit recording (``summary.json`` beside the model file); else
        (None, why not).
        """
        from bb_friction_ros.discrepancy.reference import PARAMS, RigidBody
        if calibration_csv is not None:
            cal = read_calibration(calibration_csv, self.settings.calibration.accel_cutoff_hz)
            x = _Inputs(cal.velocity_rad_s, cal.accel_rad_s2)
            fit = RigidBody.fit(x, cal.torque_nm)
            return fit.params(), f"least squares on {calibration_csv}"
        summary = Path(self.model_path).parent / "summary.json"
        try:
            data = json.loads(summary.read_text())
            params = data["reference"]["params_all_samples"]
            if params and all(k in params for k in PARAMS):
                return ({k: float(params[k]) for k in PARAMS},
                        f"{summary}: reference.params_all_samples (the discrepancy "
                        "workflow's least squares on its fit recording)")
        except (OSError, ValueError, KeyError, TypeError):
            pass
        return None, ("no calibration recording: give --calibration, or a model file "
                      "written by bb-friction discrepancy (its summary.json beside it)")

    def measured_loop(self, reference, none_run, calibration_csv=None):
        """
        Compare the ``none`` run with the recording, and the rigid-body reference beside it.

        Returns the summary's ``measured_loop`` mapping: relative errors
        ||sim - meas|| / ||meas|| of the angle (from the first sample), the velocity (central
        differences of both) and the torque (the applied command with its offset, against
        ``torque_meas_nm``).
        """
        axis = reference.axes[0]
        out = {"none": relative_errors(reference.t_s, none_run, axis)}
        coef, source = self.rigid_body_reference(calibration_csv)
        out["rigid_body_source"] = source
        if coef is None:
            out["rigid_body"] = None
        elif coef["j_kg_m2"] <= 0.0:
            out["rigid_body"] = None
            out["rigid_body_source"] += (f"; its fitted inertia {coef['j_kg_m2']:.3g} kg m^2 "
                                         "is not positive: it cannot be simulated")
        else:
            law = RigidBodyFriction(coef["c_nm_s_per_rad"], coef["coulomb_nm"],
                                    coef["offset_nm"])
            run = self.simulate_axis(reference, axis, modes_mod.Mode("none"), law=law,
                                     inertia=coef["j_kg_m2"])
            out["rigid_body"] = relative_errors(reference.t_s, run, axis)
            out["rigid_body_params"] = coef
            out["rigid_body_run"] = run
        if out.get("rigid_body"):
            out["none_torque_error_at_most_rigid_body"] = bool(
                out["none"]["torque"] <= out["rigid_body"]["torque"])
        return out


def _nonconverged(obj):
    """Return the model steps that did not converge of a law or mode with a runner (else 0)."""
    runner = getattr(obj, "runner", None) or getattr(getattr(obj, "law", None), "runner", None)
    return runner.stats.nonconverged_steps if runner is not None else 0


@dataclasses.dataclass
class _Inputs:
    nut_velocity_rad_s: np.ndarray
    nut_accel_rad_s2: np.ndarray


def relative_errors(t_s, run, axis):
    """
    Return {angle, velocity, torque, torque_by_phase}: ||sim - meas|| / ||meas||.

    ``torque_by_phase``: the torque's relative error split by the reference's motion,
    {moving, standing}, each ||sim - meas|| over that phase's samples / ||meas|| over all
    (so moving^2 + standing^2 = torque^2): where the simulation loses, while the axis moves
    or while it is commanded to stand (see measured_loop).
    """
    def rel(sim, meas):
        d = float(np.linalg.norm(meas))
        return float(np.linalg.norm(sim - meas) / d) if d > 0.0 else math.nan
    meas = axis.meas_rad
    a0 = float(meas[0])
    torque = axis.torque_meas_nm
    scale = float(np.linalg.norm(torque))
    standing = standing_mask(axis.ref_velocity(t_s))
    by_phase = {name: float(np.linalg.norm((run.applied_nm - torque)[mask]) / scale)
                if scale > 0.0 else math.nan
                for name, mask in (("moving", ~standing), ("standing", standing))}
    return {"angle": rel(run.measured_rad - a0, meas - a0),
            "velocity": rel(np.gradient(run.measured_rad, t_s), np.gradient(meas, t_s)),
            "torque": rel(run.applied_nm, torque), "torque_by_phase": by_phase}


def read_calibration(path, cutoff_hz):
    """Return the Calibration of a recording CSV (the discrepancy workflow's columns)."""
    from bb_friction_ros.servo.reference import ReferenceError
    cols = read_csv_any(path, ("t_s", "nut_angle_rad", "torque_meas_nm"))
    t = cols["t_s"]
    w = cols.get("nut_velocity_rad_s")
    if w is None:
        w = np.gradient(cols["nut_angle_rad"], t)
    a = zero_phase_acceleration(t, w, cutoff_hz, math.inf)
    if not np.all(np.isfinite(a)):
        raise ReferenceError(f"{path}: too short to derive an acceleration")
    return baselines.Calibration(t, cols["nut_angle_rad"], w, a, cols["torque_meas_nm"],
                                 str(path))


def read_csv_any(path, required):
    """Return {column: array} of a CSV with the ``required`` columns (others kept)."""
    import csv
    from bb_friction_ros.servo.reference import ReferenceError
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise ReferenceError(f"{path}: cannot read ({exc.strerror})") from exc
    with fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        missing = [c for c in required if c not in header]
        if missing:
            raise ReferenceError(f"{path}: calibration recording lacks column(s) "
                                 f"{', '.join(missing)} (has: {', '.join(header)})")
        rows = list(reader)
    out = {}
    for c in header:
        try:
            out[c] = np.array([float(r[c]) for r in rows])
        except (TypeError, ValueError):
            if c in required:
                raise ReferenceError(f"{path}: column {c}: not all numbers") from None
    if out["t_s"].size < 10:
        raise ReferenceError(f"{path}: {out['t_s'].size} rows: a calibration needs more")
    return out


def load(recording, settings, model_path, need=(), model_path_y=None):
    """Return the Reference of RECORDING for ``settings`` (leads from the model files)."""
    leads = [lead_of(model_path)] + ([lead_of(model_path_y)] if model_path_y else [])
    return load_reference(recording, settings.loop.rate_hz, leads, need)


def check_modes(names):
    """Refuse unknown mode names; return them with ``none`` first (always run)."""
    out = ["none"]
    for name in names:
        if name not in modes_mod.ALL_MODES:
            raise BBFrictionError(f"--modes: unknown mode {name!r} (known: "
                                  f"{', '.join(modes_mod.ALL_MODES)})")
        if name not in out:
            out.append(name)
    return out
