"""
The library of empirical friction terms: small parametric models with a physical name.

Each term adds a torque [N m] on the nut to the physics prediction, with the model's sign
convention: friction torque has the sign of the nut velocity.  The dissipative terms are
``sign(omega) * magnitude`` (or ``c * omega``) and so vanish at standstill; ``lead_error`` is a
load-torque error, not a dissipation, and does not.

=================  ===========================================================  ============
name               torque [N m]                                                 typical cause
=================  ===========================================================  ============
viscous_drag       c omega                                                      lubricant
seal_drag          T_s sign(omega)                                              wipers/seals,
                                                                                preload change
stribeck           T_st exp(-(omega/omega_s)^2) sign(omega)                     boundary
                                                                                lubrication
load_dependent     k abs(W) sign(omega)                                         wrong mu
lead_error         W de/dphi, e = sum_h s_h sin(h phi) + c_h cos(h phi)         lead error
thermal_drift      dT (1 - exp(-t/tau)) sign(omega)                             warm-up
inertia            J alpha                                                      moving parts
offset             T0                                                           gravity,
                                                                                sensor bias
coulomb_asymmetry  (Delta/2) |sign(omega)|                                      wear, gravity
viscous_asymmetry  (Delta_c/2) |omega|                                          wear, gravity
stroke_position    sign(omega) sum_k a_k P_k(xi), xi = (phi - phi_c)/phi_h       wear along
                                                                                the stroke
angle_ripple       sum_h a_h sin(h phi) + b_h cos(h phi)                        runout,
                                                                                coupling
pre_rolling        T_p (z - sign(omega)), dz/dphi = (sign(dphi) - z) / phi_p    rolling
                                                                                contacts'
                                                                                elasticity
=================  ===========================================================  ============

``pre_rolling`` carries a state: z in [-1, 1] follows the nut's travel (a Dahl element with
the characteristic rotation phi_p), so after a reversal the part T_p of the drag builds up over
a few phi_p instead of flipping; at steady motion z = sign(omega) and the term is 0.  The
runner never lets the friction it answers oppose the motion (``runner.ModelRunner._answer``),
so right after a reversal the answered friction builds up from 0 (docs/pre_rolling.md).

omega: nut velocity [rad/s]; alpha: nut acceleration [rad/s^2] (low-pass filtered derivative of
omega: ``AccelerationFilter``); phi: nut angle [rad] (cumulative: the nut's travel along the
screw for ``stroke_position``, P_k the Legendre polynomials, xi clipped to [-1, 1]); W: axial
load [N] (force of the balls on the nut along +z, as in the model); t: input stamp relative to
the first sample of the run (the runner passes stamp - first stamp since its last reset) [s].
``e(phi)`` is the axial position error of the nut relative to the nominal lead [m]: by virtual
work it changes the nut torque by W de/dphi, which the model (friction only; the ideal W p / 2
pi is excluded) leaves out.

In ``augmented.yaml`` a term is ``{name: <name>, params: {<param>_<unit>: value}}``; SI keys,
or the project's edge units (``sin1_um`` for ``sin1_m``).  ``load_terms`` validates a list
of them and names a bad key with its dotted path, e.g.
``empirical_terms[1].params.c_nm_s_per_rad``.
"""

import dataclasses
import functools
import math
from typing import Callable, Optional

import numpy as np

from bb_friction_ros.acceleration import (AccelerationFilter, filter_lag_s,  # noqa: F401
                                          FILTER_STEP_RESOLUTION_S, segments,
                                          zero_phase_acceleration)
from bb_friction_ros.config import ConfigError, field, from_mapping, si_key

# Harmonics of the lead error per revolution that a term can carry.  Beyond the fourth the
# torque ripple of a ground screw is below any torque sensor's resolution.
MAX_LEAD_HARMONICS = 4
# Harmonics of a load-independent angle ripple (runout, coupling misalignment): the same bound.
MAX_RIPPLE_HARMONICS = 4
# Order of the stroke polynomial: wear, misalignment and lubricant distribution along a stroke
# are smooth; beyond a cubic the term would fit noise of one recording.
MAX_STROKE_ORDER = 3


@dataclasses.dataclass(frozen=True)
class ViscousDragParams:
    """Viscous drag of the lubricant: T = c omega."""

    c_nm_s_per_rad: float = field(0.0, "N m s/rad", "viscous drag coefficient c", lo=0.0,
                                  hi=10.0)


@dataclasses.dataclass(frozen=True)
class SealDragParams:
    """Constant drag against the motion (seals, wipers, a preload change): T_s sign(omega)."""

    torque_nm: float = field(0.0, "N m", "drag torque magnitude T_s", lo=0.0, hi=100.0)


@dataclasses.dataclass(frozen=True)
class StribeckParams:
    """Extra friction at low speed: T_st exp(-(omega/omega_s)^2) sign(omega)."""

    torque_nm: float = field(0.0, "N m", "Stribeck excess at zero speed T_st", lo=0.0,
                             hi=100.0)
    velocity_rad_s: float = field(1.0, "rad/s", "Stribeck nut velocity omega_s", lo=0.0,
                                  hi=1e4, lo_open=True)


@dataclasses.dataclass(frozen=True)
class PreRollingParams:
    """Pre-rolling: T_p (z - sign(omega)), z a Dahl state of the nut travel (phi_p)."""

    torque_nm: float = field(0.0, "N m", "the drag T_p that builds up over the pre-rolling "
                             "travel after a reversal (its whole Coulomb part: ~the drag at low "
                             "speed)", lo=0.0, hi=100.0)
    travel_rad: float = field(1e-3, "rad", "characteristic nut rotation phi_p of the build-up "
                              "(axial travel = phi_p x lead / 2 pi)", lo=0.0, hi=10.0,
                              lo_open=True)


@dataclasses.dataclass(frozen=True)
class LoadDependentParams:
    """Friction proportional to the axial load (a wrong mu): k abs(W) sign(omega)."""

    k_nm_per_n: float = field(0.0, "N m/N", "extra friction torque per newton of axial "
                              "load k (signed: the model's mu may be too high or too low)",
                              lo=-1e-2, hi=1e-2)


def _lead_fields():
    out = []
    for h in range(1, MAX_LEAD_HARMONICS + 1):
        for kind in ("sin", "cos"):
            out.append((f"{kind}{h}_m", float, field(
                0.0, "m", f"{kind} amplitude of harmonic {h} of the axial position error "
                "e(phi) per nut revolution", lo=-1e-3, hi=1e-3)))
    return out


LeadErrorParams = dataclasses.make_dataclass(
    "LeadErrorParams", _lead_fields(), frozen=True,
    namespace={"__doc__": "Periodic lead error: T = W de/dphi, "
               "e = sum_h sin_h sin(h phi) + cos_h cos(h phi) [m]."})


@dataclasses.dataclass(frozen=True)
class ThermalDriftParams:
    """Slow change of the drag with warm-up: dT (1 - exp(-t/tau)) sign(omega)."""

    delta_torque_nm: float = field(0.0, "N m", "drag change reached after warm-up dT "
                                   "(negative: friction falls as the lubricant warms)",
                                   lo=-100.0, hi=100.0)
    time_constant_s: float = field(60.0, "s", "warm-up time constant tau", lo=0.0, hi=1e7,
                                   lo_open=True)


@dataclasses.dataclass(frozen=True)
class InertiaParams:
    """
    Torque that accelerates the moving parts: T = J alpha.

    A motor-current or torque-sensor recording contains it; a friction model does not.  The
    acceleration is not measured: it is the derivative of the nut velocity low-pass filtered
    at ``accel_cutoff_hz`` (``AccelerationFilter``; zero-phase for the analysis, causal in the
    node and replay), the filter restarting after a gap longer than ``max_gap_s``.
    """

    j_kg_m2: float = field(0.0, "kg m^2", "moment of inertia J reduced to the nut angle",
                           lo=0.0, hi=1e3)
    accel_cutoff_hz: float = field(10.0, "Hz", "cut-off of the 2nd-order Butterworth low-pass "
                                   "on the nut velocity whose derivative is alpha", lo=0.0,
                                   hi=1e5, lo_open=True)
    max_gap_s: float = field(0.1, "s", "a step between samples longer than this restarts the "
                             "acceleration filter (a new continuous segment)", lo=0.0, hi=1e6,
                             lo_open=True)


@dataclasses.dataclass(frozen=True)
class OffsetParams:
    """A constant torque, not signed by the motion: gravity on an inclined axis, sensor bias."""

    torque_nm: float = field(0.0, "N m", "offset torque T0", lo=-100.0, hi=100.0)


@dataclasses.dataclass(frozen=True)
class CoulombAsymmetryParams:
    """
    Constant friction that differs between the directions: +Delta/2 moving +, -Delta/2 moving -.

    In torque (friction has the sign of omega) that is +Delta/2 on every moving sample:
    ``seal_drag`` keeps the mean of both directions.  On moving samples this column equals
    ``offset``; only standstill samples tell the two apart.
    """

    delta_torque_nm: float = field(0.0, "N m", "drag of the positive minus the negative "
                                   "direction Delta", lo=-100.0, hi=100.0)


@dataclasses.dataclass(frozen=True)
class ViscousAsymmetryParams:
    """Viscous drag that differs between the directions: (c +/- Delta_c/2) omega."""

    delta_c_nm_s_per_rad: float = field(0.0, "N m s/rad", "viscous coefficient of the "
                                        "positive minus the negative direction Delta_c",
                                        lo=-10.0, hi=10.0)


def _stroke_fields():
    out = [("center_rad", float, field(0.0, "rad", "nut angle at the middle of the fitted "
                                       "stroke phi_c")),
           ("half_range_rad", float, field(1.0, "rad", "half the fitted stroke phi_h; beyond "
                                           "it the polynomial is held at its end value",
                                           lo=0.0, hi=1e12, lo_open=True))]
    for k in range(1, MAX_STROKE_ORDER + 1):
        out.append((f"p{k}_nm", float, field(
            0.0, "N m", f"amplitude of the Legendre polynomial of order {k} of the drag "
            "along the stroke", lo=-100.0, hi=100.0)))
    return out


StrokePositionParams = dataclasses.make_dataclass(
    "StrokePositionParams", _stroke_fields(), frozen=True,
    namespace={"__doc__": "Drag that changes along the stroke: sign(omega) sum_k p_k "
               "P_k((phi - center) / half_range)."})


def _ripple_fields():
    out = []
    for h in range(1, MAX_RIPPLE_HARMONICS + 1):
        for kind in ("sin", "cos"):
            out.append((f"{kind}{h}_nm", float, field(
                0.0, "N m", f"{kind} amplitude of harmonic {h} of the torque ripple per nut "
                "revolution", lo=-100.0, hi=100.0)))
    return out


AngleRippleParams = dataclasses.make_dataclass(
    "AngleRippleParams", _ripple_fields(), frozen=True,
    namespace={"__doc__": "Load-independent ripple per revolution (runout, coupling "
               "misalignment): sum_h sin_h sin(h phi) + cos_h cos(h phi) [N m]."})


@dataclasses.dataclass(frozen=True)
class Inputs:
    """The inputs a term sees, as numpy arrays (broadcast together)."""

    t_s: np.ndarray
    nut_angle_rad: np.ndarray
    nut_velocity_rad_s: np.ndarray
    axial_load_n: np.ndarray
    nut_accel_rad_s2: Optional[np.ndarray] = None     # only ``inertia`` reads it

    @classmethod
    def of(cls, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n, nut_accel_rad_s2=None):
        """Convert and broadcast the inputs (the acceleration is optional)."""
        given = [t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n]
        if nut_accel_rad_s2 is not None:
            given.append(nut_accel_rad_s2)
        arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in given))
        return cls(*arrays)


def _drag_sign(x):
    return np.sign(x.nut_velocity_rad_s)


def _viscous_columns(x, nl, names):
    return [x.nut_velocity_rad_s]


def _seal_columns(x, nl, names):
    return [_drag_sign(x)]


def _stribeck_columns(x, nl, names):
    return [np.exp(-(x.nut_velocity_rad_s / nl) ** 2) * _drag_sign(x)]


def _load_columns(x, nl, names):
    return [np.abs(x.axial_load_n) * _drag_sign(x)]


def _lead_columns(x, nl, names):
    cols = []
    for name in names:
        kind, h = name[:3], int(name[3:].split("_")[0])
        phase = h * x.nut_angle_rad
        # d/dphi of sin(h phi) is h cos(h phi); of cos(h phi), -h sin(h phi)
        dshape = h * np.cos(phase) if kind == "sin" else -h * np.sin(phase)
        cols.append(x.axial_load_n * dshape)
    return cols


def _thermal_columns(x, nl, names):
    warm = -np.expm1(-np.maximum(x.t_s, 0.0) / nl)       # 1 - exp(-t/tau), exact near 0
    return [warm * _drag_sign(x)]


def _inertia_columns(x, nl, names, fixed=None):
    if x.nut_accel_rad_s2 is None:
        raise ValueError("the inertia term needs the nut acceleration (nut_accel_rad_s2)")
    return [x.nut_accel_rad_s2]


def _offset_columns(x, nl, names):
    return [np.ones_like(x.t_s)]


def _coulomb_asymmetry_columns(x, nl, names):
    # +Delta/2 moving either way: the positive direction's drag is Delta/2 above the mean,
    # the negative one's Delta/2 below it, and friction torque has the sign of omega
    return [0.5 * np.abs(_drag_sign(x))]


def _viscous_asymmetry_columns(x, nl, names):
    return [0.5 * np.abs(x.nut_velocity_rad_s)]


def dahl_state(nut_angle_rad, t_s, travel_rad, nut_velocity_rad_s):
    """
    Return the pre-rolling state z [-1, 1] at each sample of a sequence (a Dahl element).

    dz/dphi = (sign(dphi) - z) / phi_p, solved exactly over each sample's rotation dphi:
    z_k = s + (z_k-1 - s) exp(-|dphi| / phi_p), s = sign(dphi); unchanged where the nut does
    not turn.  A run (``t_s`` going back: the runner reset) starts at z = sign(omega), the
    steady state of its first motion.  ``PreRollingState`` is the same per sample.
    """
    phi = np.atleast_1d(np.asarray(nut_angle_rad, dtype=float))
    t = np.broadcast_to(np.asarray(t_s, dtype=float), phi.shape)
    w = np.broadcast_to(np.asarray(nut_velocity_rad_s, dtype=float), phi.shape)
    z = np.empty(phi.shape)
    if not phi.size:
        return z
    angle = phi.tolist()
    restart = np.concatenate(([True], np.diff(t) < 0.0)).tolist()
    start = np.sign(w).tolist()
    out = z.tolist()
    zk = 0.0
    for k in range(phi.size):
        if restart[k]:
            zk = start[k]
        else:
            zk = _dahl_step(zk, angle[k] - angle[k - 1], travel_rad)
        out[k] = zk
    return np.array(out).reshape(phi.shape)


def _dahl_step(z, d_rad, travel_rad):
    """Return the Dahl state after a rotation ``d_rad`` (exact for a constant direction)."""
    if d_rad == 0.0:
        return z
    s = 1.0 if d_rad > 0.0 else -1.0
    return s + (z - s) * math.exp(-abs(d_rad) / travel_rad)


class PreRollingState:
    """The Dahl state of ``dahl_state`` one sample at a time (the runner's terms)."""

    def __init__(self, travel_rad):
        """Start with no sample seen."""
        self.travel_rad = travel_rad
        self.reset()

    def reset(self):
        """Forget the state: the next sample starts a run."""
        self._angle = None
        self.z = 0.0

    def update(self, nut_angle_rad, nut_velocity_rad_s):
        """Advance to a sample; return z."""
        angle = float(nut_angle_rad)
        if self._angle is None:
            self.z = float(np.sign(nut_velocity_rad_s))
        else:
            self.z = _dahl_step(self.z, angle - self._angle, self.travel_rad)
        self._angle = angle
        return self.z


def _pre_rolling_columns(x, nl, names):
    return [dahl_state(x.nut_angle_rad, x.t_s, nl, x.nut_velocity_rad_s) - _drag_sign(x)]


def stroke_coordinate(nut_angle_rad, center_rad, half_range_rad):
    """Return xi = (phi - center) / half_range, held at +/-1 beyond the fitted stroke."""
    return np.clip((np.asarray(nut_angle_rad, float) - center_rad) / half_range_rad, -1.0, 1.0)


def _stroke_columns(x, nl, names, fixed):
    xi = stroke_coordinate(x.nut_angle_rad, fixed["center_rad"], fixed["half_range_rad"])
    sign = _drag_sign(x)
    cols = []
    for name in names:
        k = int(name[1:].split("_")[0])
        coef = np.zeros(k + 1)
        coef[k] = 1.0
        cols.append(np.polynomial.legendre.legval(xi, coef) * sign)
    return cols


def _ripple_columns(x, nl, names):
    cols = []
    for name in names:
        kind, h = name[:3], int(name[3:].split("_")[0])
        phase = h * x.nut_angle_rad
        cols.append(np.sin(phase) if kind == "sin" else np.cos(phase))
    return cols


@dataclasses.dataclass(frozen=True)
class TermKind:
    """
    One entry of the library.

    The torque is linear in the ``linear`` params: ``design(inputs, nl, names, fixed) @
    values``, with ``nl`` the value of the one ``nonlinear`` param (or None) and ``fixed`` the
    params set from the data before fitting (the stroke's centre and range, the acceleration
    filter's settings).  The same function serves fitting and evaluation, so a fitted term
    predicts exactly what was fitted.
    """

    name: str
    params_cls: type
    linear: tuple
    columns: Callable
    nonlinear: Optional[str] = None
    nonnegative: frozenset = frozenset()    # linear params that physics keeps >= 0
    required: tuple = ()
    meaning: str = ""
    fixed: tuple = ()                       # params set from the data, not fitted
    sparse: bool = False                    # amplitudes that are 0 are left out of the YAML

    def _columns(self, x, nl, names, fixed):
        """Return the design columns of ``names`` at inputs ``x``, as a list."""
        if self.fixed:
            return self.columns(x, nl, names, fixed)
        return self.columns(x, nl, names)

    def design(self, x, nl, names, fixed=None):
        """Return the design columns of ``names`` at inputs ``x`` (shape (..., len(names)))."""
        return np.stack(self._columns(x, nl, names, fixed), axis=-1)

    def _resolved(self, params):
        """Return (nl, names, values, fixed) of validated ``params``; names: non-zero only."""
        nl = getattr(params, self.nonlinear) if self.nonlinear else None
        names = tuple(n for n in self.linear if getattr(params, n) != 0.0) \
            if self.sparse else self.linear
        values = np.array([getattr(params, n) for n in names])
        fixed = {n: getattr(params, n) for n in self.fixed}
        return nl, names, values, fixed

    def torque_nm(self, params, inputs):
        """Return this term's torque [N m] for validated ``params`` at ``inputs``."""
        nl, names, values, fixed = self._resolved(params)
        if not names:
            return np.zeros_like(inputs.t_s)
        return self.design(inputs, nl, names, fixed) @ values

    def sample_evaluator(self, params):
        """
        Return f(x) -> this term's torque [N m] at one sample, or None (no amplitude set).

        ``x`` holds np.float64 scalars (``LiveTerms``).  The same column functions as
        ``torque_nm``, with the parameters resolved once: a 0-d evaluation spends ~60 us per
        term in numpy's array machinery (np.stack, matmul), which made the fitted terms cost
        replay more than half its time (profiled).  The result equals ``torque_nm``'s bit
        for bit (tested): one column is the product numpy's one-element dot computes, more
        go through the same dot on the same array.
        """
        nl, names, values, fixed = self._resolved(params)
        if not names:
            return None
        columns = functools.partial(self._columns, nl=nl, names=names, fixed=fixed)
        if len(names) == 1:
            value = values[0]
            return lambda x: columns(x)[0] * value
        return lambda x: np.array(columns(x)) @ values


_LEAD_NAMES = tuple(f"{k}{h}_m" for h in range(1, MAX_LEAD_HARMONICS + 1)
                    for k in ("sin", "cos"))
_RIPPLE_NAMES = tuple(f"{k}{h}_nm" for h in range(1, MAX_RIPPLE_HARMONICS + 1)
                      for k in ("sin", "cos"))
_STROKE_NAMES = tuple(f"p{k}_nm" for k in range(1, MAX_STROKE_ORDER + 1))

LIBRARY = {k.name: k for k in (
    TermKind("viscous_drag", ViscousDragParams, ("c_nm_s_per_rad",), _viscous_columns,
             nonnegative=frozenset({"c_nm_s_per_rad"}), required=("c_nm_s_per_rad",),
             meaning="viscous drag of the lubricant, proportional to the nut speed (mean of "
             "both directions)"),
    TermKind("seal_drag", SealDragParams, ("torque_nm",), _seal_columns,
             nonnegative=frozenset({"torque_nm"}), required=("torque_nm",),
             meaning="constant drag against the motion: seals, wipers, or a preload change "
             "(mean of both directions)"),
    TermKind("stribeck", StribeckParams, ("torque_nm",), _stribeck_columns,
             nonlinear="velocity_rad_s", nonnegative=frozenset({"torque_nm"}),
             required=("torque_nm", "velocity_rad_s"),
             meaning="extra friction at low speed (boundary lubrication, Stribeck curve)"),
    TermKind("load_dependent", LoadDependentParams, ("k_nm_per_n",), _load_columns,
             required=("k_nm_per_n",),
             meaning="friction proportional to the axial load: the model's friction "
             "coefficient is off"),
    TermKind("lead_error", LeadErrorParams, _LEAD_NAMES, _lead_columns, sparse=True,
             meaning="periodic lead error: load torque W de/dphi, once per revolution and "
             "harmonics"),
    TermKind("thermal_drift", ThermalDriftParams, ("delta_torque_nm",), _thermal_columns,
             nonlinear="time_constant_s", required=("delta_torque_nm", "time_constant_s"),
             meaning="slow change of the drag with time (warm-up)"),
    TermKind("inertia", InertiaParams, ("j_kg_m2",), _inertia_columns,
             nonnegative=frozenset({"j_kg_m2"}), fixed=("accel_cutoff_hz", "max_gap_s"),
             required=("j_kg_m2", "accel_cutoff_hz", "max_gap_s"),
             meaning="torque that accelerates the moving parts, J alpha (alpha from the "
             "filtered velocity)"),
    TermKind("offset", OffsetParams, ("torque_nm",), _offset_columns, required=("torque_nm",),
             meaning="constant torque not signed by the motion: gravity on an inclined axis "
             "or a sensor bias"),
    TermKind("coulomb_asymmetry", CoulombAsymmetryParams, ("delta_torque_nm",),
             _coulomb_asymmetry_columns, required=("delta_torque_nm",),
             meaning="constant drag that differs between the two directions (wear, gravity "
             "on a self-locking drive); zero-mean: seal_drag keeps the mean"),
    TermKind("viscous_asymmetry", ViscousAsymmetryParams, ("delta_c_nm_s_per_rad",),
             _viscous_asymmetry_columns, required=("delta_c_nm_s_per_rad",),
             meaning="viscous drag that differs between the two directions; zero-mean: "
             "viscous_drag keeps the mean"),
    TermKind("stroke_position", StrokePositionParams, _STROKE_NAMES, _stroke_columns,
             fixed=("center_rad", "half_range_rad"), required=("center_rad", "half_range_rad"),
             sparse=True,
             meaning="drag that changes along the stroke (wear, misalignment, lubricant "
             "distribution): a low-order polynomial of the nut's travel"),
    TermKind("pre_rolling", PreRollingParams, ("torque_nm",), _pre_rolling_columns,
             nonlinear="travel_rad", nonnegative=frozenset({"torque_nm"}),
             required=("torque_nm", "travel_rad"),
             meaning="pre-rolling: after a reversal the drag builds up over a characteristic "
             "nut travel instead of flipping (elastic micro-slip of the rolling contacts)"),
    TermKind("angle_ripple", AngleRippleParams, _RIPPLE_NAMES, _ripple_columns, sparse=True,
             meaning="torque ripple once per nut revolution and harmonics, independent of "
             "the load (runout, coupling misalignment)"),
)}

# Terms whose columns coincide on moving samples; only standstill samples separate them.
AMBIGUOUS_PAIRS = (("offset", "coulomb_asymmetry"),)

# The terms whose torque is friction: dissipated at the contacts, so with the physics it has the
# sign of the nut velocity (a model whose friction does not is refused:
# ``runner.check_friction_sign``).  The others are not friction and may take either sign: the
# torque that accelerates the moving parts, gravity or a sensor bias, and the load-torque and
# runout ripples of lead error and angle ripple.
NOT_FRICTION = frozenset({"inertia", "offset", "lead_error", "angle_ripple"})


def units_of(kind_name):
    """Return {param: unit} of a term kind."""
    cls = LIBRARY[kind_name].params_cls
    return {f.name: f.metadata["unit"] for f in dataclasses.fields(cls)}


@dataclasses.dataclass(frozen=True)
class Term:
    """A term of the library with validated parameter values."""

    name: str
    params: object

    @property
    def kind(self):
        """Return the TermKind."""
        return LIBRARY[self.name]

    def torque_nm(self, inputs):
        """Return this term's torque [N m] at ``inputs``."""
        return self.kind.torque_nm(self.params, inputs)

    def param_dict(self):
        """Return {param: value} (SI keys); zero lead-error harmonics are left out."""
        values = dataclasses.asdict(self.params)
        if self.kind.sparse:
            values = {k: v for k, v in values.items()
                      if v != 0.0 or k not in self.kind.linear}
        return {k: float(v) for k, v in values.items()}


class TermSet:
    """An ordered set of empirical terms added to the physics prediction."""

    def __init__(self, terms=()):
        """Hold ``terms`` (Term objects) in order."""
        self.terms = tuple(terms)

    @property
    def names(self):
        """Return the term names, in order."""
        return tuple(t.name for t in self.terms)

    def __len__(self):
        """Return the number of terms."""
        return len(self.terms)

    def parts_nm(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n,
                 nut_accel_rad_s2=None):
        """Return each term's torque [N m] (a list of arrays, in order)."""
        x = Inputs.of(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n, nut_accel_rad_s2)
        return [t.torque_nm(x) for t in self.terms]

    def torque_nm(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n,
                  nut_accel_rad_s2=None):
        """
        Return the added friction torque [N m] of all terms (numpy-vectorised, pure).

        ``t_s`` is the stamp relative to the first sample of the run (used by
        ``thermal_drift`` only); ``nut_accel_rad_s2`` is needed by ``inertia`` only; the other
        inputs are as the model receives them.
        """
        x = Inputs.of(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n, nut_accel_rad_s2)
        total = np.zeros_like(x.t_s)
        for t in self.terms:
            total = total + t.torque_nm(x)
        return total if total.ndim else float(total)

    def friction_nm(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """Return the torque [N m] of the terms that are friction (not in ``NOT_FRICTION``)."""
        x = Inputs.of(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)
        total = np.zeros_like(x.t_s)
        for t in self.terms:
            if t.name not in NOT_FRICTION:
                total = total + t.torque_nm(x)
        return total

    def acceleration_filter(self):
        """Return the (cutoff_hz, max_gap_s) of the inertia terms' filter, or None."""
        for t in self.terms:
            if t.name == "inertia":
                return (t.params.accel_cutoff_hz, t.params.max_gap_s)
        return None

    def live(self):
        """Return a stateful per-sample evaluator (``LiveTerms``) for the runner."""
        return LiveTerms(self)

    def to_list(self):
        """Return the YAML form: [{name, params: {key: value}}]."""
        return [{"name": t.name, "params": t.param_dict()} for t in self.terms]

    def effects(self):
        """Return [{name, params, units}] as summary.json reports them."""
        out = []
        for t in self.terms:
            params = t.param_dict()
            units = units_of(t.name)
            out.append({"name": t.name, "params": params,
                        "units": {k: units[k] for k in params}})
        return out


def make_term(name, values):
    """Build a Term from SI ``values`` (validated like a YAML entry)."""
    return _load_one({"name": name, "params": dict(values)}, f"term {name}")


def _given_fields(params, cls):
    """Return the SI field names that the keys of ``params`` set (edge units resolved)."""
    names = {f.name for f in dataclasses.fields(cls)}
    return {si_key(key, names)[0] for key in params if si_key(key, names) is not None}


def _load_one(entry, path):
    if not isinstance(entry, dict):
        raise ConfigError(f"{path}: expected a mapping {{name, params}}, got "
                          f"{type(entry).__name__}")
    unknown = sorted(set(entry) - {"name", "params"})
    if unknown:
        raise ConfigError(f"{path}.{unknown[0]}: unknown key (known: name, params)")
    name = entry.get("name")
    if name not in LIBRARY:
        raise ConfigError(f"{path}.name: unknown term {name!r} (known: "
                          f"{', '.join(sorted(LIBRARY))})")
    kind = LIBRARY[name]
    params = entry.get("params", {})
    if params is None:
        params = {}
    if not isinstance(params, dict):
        raise ConfigError(f"{path}.params: expected a mapping, got {type(params).__name__}")
    values = from_mapping(kind.params_cls, params, f"{path}.params")    # unknown keys first
    given = _given_fields(params, kind.params_cls)
    for req in kind.required:
        if req not in given:
            raise ConfigError(f"{path}.params.{req}: missing "
                              f"({units_of(name)[req]}; {kind.meaning})")
    return Term(name, values)


def load_terms(raw_list, path="empirical_terms"):
    """
    Validate the ``empirical_terms`` list of a config and return its TermSet.

    None (no key) gives an empty set.  An unknown term name or parameter, a missing or
    out-of-range value is refused with a ConfigError naming the dotted key, e.g.
    ``empirical_terms[1].params.c_nm_s_per_rad``.
    """
    if raw_list is None:
        return TermSet()
    if not isinstance(raw_list, list):
        raise ConfigError(f"{path}: expected a list of {{name, params}}, got "
                          f"{type(raw_list).__name__}")
    terms = TermSet(_load_one(e, f"{path}[{i}]") for i, e in enumerate(raw_list))
    filters = {(i, (t.params.accel_cutoff_hz, t.params.max_gap_s))
               for i, t in enumerate(terms.terms) if t.name == "inertia"}
    if len({f for _, f in filters}) > 1:
        i = max(i for i, _ in filters)
        raise ConfigError(f"{path}[{i}].params.accel_cutoff_hz: every inertia term of a model "
                          "must use the same acceleration filter (one alpha per sample)")
    return terms


class LiveTerms:
    """
    A TermSet evaluated one sample at a time, with the causal acceleration filter.

    The runner (node and replay alike) calls ``torque_nm`` per sample and ``reset`` when it
    resets, so live equals replay; the analysis evaluates the same terms with the zero-phase
    acceleration instead.
    """

    def __init__(self, terms):
        """Wrap ``terms``; build its acceleration filter if it has an inertia term."""
        self.terms = terms
        spec = terms.acceleration_filter()
        self.filter = AccelerationFilter(*spec) if spec else None
        self.last_accel_rad_s2 = None
        self.last_friction_nm = 0.0         # the friction terms' share of the last sample's
        self._states = []                   # the pre-rolling terms' Dahl states
        # terms without an amplitude add 0.0 (exactly: the sum starts at +0.0) and are left out
        self._evaluators = []               # (f(x), is friction)
        for t in terms.terms:
            if t.name == "pre_rolling":
                f = self._pre_rolling(t.params)
            else:
                f = t.kind.sample_evaluator(t.params)
            if f is not None:
                self._evaluators.append((f, t.name not in NOT_FRICTION))

    def _pre_rolling(self, params):
        """Return the evaluator of a pre-rolling term: its column from a state of its own."""
        if params.torque_nm == 0.0:
            return None
        state = PreRollingState(params.travel_rad)
        self._states.append(state)
        amplitude = params.torque_nm
        return lambda x: (state.update(x.nut_angle_rad, x.nut_velocity_rad_s)
                          - np.sign(x.nut_velocity_rad_s)) * amplitude

    def reset(self):
        """Restart the acceleration filter and the pre-rolling states."""
        self.last_accel_rad_s2 = None       # alpha at the last sample (None: no filter)
        if self.filter is not None:
            self.filter.reset()
        for state in self._states:
            state.reset()

    def torque_nm(self, stamp_s, t_run_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """Return the terms' torque [N m] at one sample (updates the filter)."""
        accel = None
        if self.filter is not None:
            accel = self.filter.update(stamp_s, nut_velocity_rad_s)
        self.last_accel_rad_s2 = accel
        # np.float64 scalars: every operation then takes numpy's scalar path, the one the
        # 0-d arrays of TermSet.torque_nm take after their first ufunc, so the sums agree
        x = _Sample(_f64(t_run_s), _f64(nut_angle_rad), _f64(nut_velocity_rad_s),
                    _f64(axial_load_n), None if accel is None else _f64(accel))
        total = friction = 0.0
        for f, is_friction in self._evaluators:
            value = f(x)
            total = total + value
            if is_friction:
                friction = friction + value
        self.last_friction_nm = float(friction)
        return float(total)


_f64 = np.float64


class _Sample:
    """One sample's inputs as np.float64 scalars: ``Inputs``' fields, without its checks."""

    __slots__ = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n",
                 "nut_accel_rad_s2")

    def __init__(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n,
                 nut_accel_rad_s2):
        self.t_s = t_s
        self.nut_angle_rad = nut_angle_rad
        self.nut_velocity_rad_s = nut_velocity_rad_s
        self.axial_load_n = axial_load_n
        self.nut_accel_rad_s2 = nut_accel_rad_s2
