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
=================  ===========================================================  ============

omega: nut velocity [rad/s]; phi: nut angle [rad]; W: axial load [N] (force of the balls on
the nut along +z, as in the model); t: input stamp relative to the first sample of the run
(the runner passes stamp - first stamp since its last reset) [s].  ``e(phi)`` is the axial
position error of the nut relative to the nominal lead [m]: by virtual work it changes the
nut torque by W de/dphi, which the model (friction only; the ideal W p / 2 pi is excluded)
leaves out.

In ``augmented.yaml`` a term is ``{name: <name>, params: {<param>_<unit>: value}}``; SI keys,
or the project's edge units (``sin1_um`` for ``sin1_m``).  ``load_terms`` validates a list
of them and names a bad key with its dotted path, e.g.
``empirical_terms[1].params.c_nm_s_per_rad``.
"""

import dataclasses
from typing import Callable, Optional

import numpy as np

from bb_friction_ros.config import ConfigError, field, from_mapping, si_key

# Harmonics of the lead error per revolution that a term can carry.  Beyond the fourth the
# torque ripple of a ground screw is below any torque sensor's resolution.
MAX_LEAD_HARMONICS = 4


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
class Inputs:
    """The inputs a term sees, as numpy arrays (broadcast together)."""

    t_s: np.ndarray
    nut_angle_rad: np.ndarray
    nut_velocity_rad_s: np.ndarray
    axial_load_n: np.ndarray

    @classmethod
    def of(cls, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """Convert and broadcast the four inputs."""
        arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in
                                       (t_s, nut_angle_rad, nut_velocity_rad_s,
                                        axial_load_n)))
        return cls(*arrays)


def _drag_sign(x):
    return np.sign(x.nut_velocity_rad_s)


def _viscous_columns(x, nl, names):
    return np.stack([x.nut_velocity_rad_s], axis=-1)


def _seal_columns(x, nl, names):
    return np.stack([_drag_sign(x)], axis=-1)


def _stribeck_columns(x, nl, names):
    return np.stack([np.exp(-(x.nut_velocity_rad_s / nl) ** 2) * _drag_sign(x)], axis=-1)


def _load_columns(x, nl, names):
    return np.stack([np.abs(x.axial_load_n) * _drag_sign(x)], axis=-1)


def _lead_columns(x, nl, names):
    cols = []
    for name in names:
        kind, h = name[:3], int(name[3:].split("_")[0])
        phase = h * x.nut_angle_rad
        # d/dphi of sin(h phi) is h cos(h phi); of cos(h phi), -h sin(h phi)
        dshape = h * np.cos(phase) if kind == "sin" else -h * np.sin(phase)
        cols.append(x.axial_load_n * dshape)
    return np.stack(cols, axis=-1)


def _thermal_columns(x, nl, names):
    warm = -np.expm1(-np.maximum(x.t_s, 0.0) / nl)       # 1 - exp(-t/tau), exact near 0
    return np.stack([warm * _drag_sign(x)], axis=-1)


@dataclasses.dataclass(frozen=True)
class TermKind:
    """
    One entry of the library.

    The torque is linear in the ``linear`` params: ``columns(inputs, nl, names) @ values``,
    with ``nl`` the value of the one ``nonlinear`` param (or None).  The same function serves
    fitting and evaluation, so a fitted term predicts exactly what was fitted.
    """

    name: str
    params_cls: type
    linear: tuple
    columns: Callable
    nonlinear: Optional[str] = None
    nonnegative: frozenset = frozenset()    # linear params that physics keeps >= 0
    required: tuple = ()
    meaning: str = ""

    def torque_nm(self, params, inputs):
        """Return this term's torque [N m] for validated ``params`` at ``inputs``."""
        nl = getattr(params, self.nonlinear) if self.nonlinear else None
        names = tuple(n for n in self.linear if getattr(params, n) != 0.0) \
            if self.name == "lead_error" else self.linear
        if not names:
            return np.zeros_like(inputs.t_s)
        values = np.array([getattr(params, n) for n in names])
        return self.columns(inputs, nl, names) @ values


_LEAD_NAMES = tuple(f"{k}{h}_m" for h in range(1, MAX_LEAD_HARMONICS + 1)
                    for k in ("sin", "cos"))

LIBRARY = {k.name: k for k in (
    TermKind("viscous_drag", ViscousDragParams, ("c_nm_s_per_rad",), _viscous_columns,
             nonnegative=frozenset({"c_nm_s_per_rad"}), required=("c_nm_s_per_rad",),
             meaning="viscous drag of the lubricant, proportional to the nut speed"),
    TermKind("seal_drag", SealDragParams, ("torque_nm",), _seal_columns,
             nonnegative=frozenset({"torque_nm"}), required=("torque_nm",),
             meaning="constant drag against the motion: seals, wipers, or a preload change"),
    TermKind("stribeck", StribeckParams, ("torque_nm",), _stribeck_columns,
             nonlinear="velocity_rad_s", nonnegative=frozenset({"torque_nm"}),
             required=("torque_nm", "velocity_rad_s"),
             meaning="extra friction at low speed (boundary lubrication, Stribeck curve)"),
    TermKind("load_dependent", LoadDependentParams, ("k_nm_per_n",), _load_columns,
             required=("k_nm_per_n",),
             meaning="friction proportional to the axial load: the model's friction "
             "coefficient is off"),
    TermKind("lead_error", LeadErrorParams, _LEAD_NAMES, _lead_columns,
             meaning="periodic lead error: load torque W de/dphi, once per revolution and "
             "harmonics"),
    TermKind("thermal_drift", ThermalDriftParams, ("delta_torque_nm",), _thermal_columns,
             nonlinear="time_constant_s", required=("delta_torque_nm", "time_constant_s"),
             meaning="slow change of the drag with time (warm-up)"),
)}


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
        if self.name == "lead_error":
            values = {k: v for k, v in values.items() if v != 0.0}
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

    def parts_nm(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """Return each term's torque [N m] (a list of arrays, in order)."""
        x = Inputs.of(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)
        return [t.torque_nm(x) for t in self.terms]

    def torque_nm(self, t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n):
        """
        Return the added friction torque [N m] of all terms (numpy-vectorised, pure).

        ``t_s`` is the stamp relative to the first sample of the run (used by
        ``thermal_drift`` only); the other inputs are as the model receives them.
        """
        x = Inputs.of(t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n)
        total = np.zeros_like(x.t_s)
        for t in self.terms:
            total = total + t.torque_nm(x)
        return total if total.ndim else float(total)

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
    return TermSet(_load_one(e, f"{path}[{i}]") for i, e in enumerate(raw_list))
