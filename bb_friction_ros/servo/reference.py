"""
The reference: read from a recording (CSV) or generated from a spec (YAML).

A recording is a CSV with the columns ``t_s`` and ``nut_angle_ref_rad`` (required) and
optionally ``nut_angle_rad`` (the measured angle), ``torque_meas_nm`` (the drive torque),
``command_offset_nm`` (a torque added to the controller's command, e.g. test pulses) and
``axial_load_n``.  Its rows must be at the loop's rate: one row per servo sample.

A spec is a YAML file with a ``reference:`` mapping (``ReferenceSpec``), sampled at the
loop's rate::

    reference:
      kind: reversal          # reversal | constant_speed | circle
      speeds_rev_s: [0.5, 1, 2]
      stroke_rev: 2.0
      accel_rev_s2: 20.0
      dwell_s: 0.0            # 0: reverse at once (the velocity passes through zero)
      cycles: 1
      axial_load_n: 1500.0    # default: the model file's operation.axial_load_n

``reversal``: for each speed, ``cycles`` moves forward and back over the stroke, trapezoidal
velocity.  ``constant_speed``: the same with a rest of ``dwell_s`` (at least 0.1 s) between
the moves.  ``circle``: the two-axis circular test of ISO 230-4 (``radius_mm``,
``feed_m_min``, ``directions``: ccw, cw or both), X = r cos(theta), Y = r sin(theta), each axis
a nut angle through its screw's lead, the feed ramped at ``accel_m_s2``.

The reference velocity and acceleration the loop uses are the sampled reference's central
differences (``numpy.gradient``), for a recording and a spec alike: a generated recording
and its simulation then see the same reference.
"""

import csv
import dataclasses
import math
from pathlib import Path
from typing import Optional

import numpy as np

from bb_friction_ros.config import BBFrictionError, ConfigError, field, from_mapping, load_yaml
from bb_friction_ros.discrepancy.servo_moves import sample_moves

REQUIRED = ("t_s", "nut_angle_ref_rad")
OPTIONAL = ("nut_angle_rad", "torque_meas_nm", "command_offset_nm", "axial_load_n")
KINDS = ("reversal", "constant_speed", "circle")
SPEC_SECTION = "reference"
# Rest after a generated reference ends, so the last reversal or stop settles [s].
SETTLE_S = 0.2
# Rows whose spacing departs from the loop period by more than this share are refused: the
# simulation holds each command one period, so the recording's rows must be those periods.
RATE_TOLERANCE = 0.01


class ReferenceError(BBFrictionError):
    """A recording or spec that cannot be used as a reference; the message names it."""


@dataclasses.dataclass
class Axis:
    """One axis's reference and recorded channels (None: not recorded)."""

    name: str
    ref_rad: np.ndarray
    meas_rad: Optional[np.ndarray] = None
    torque_meas_nm: Optional[np.ndarray] = None
    command_offset_nm: Optional[np.ndarray] = None
    axial_load_n: Optional[np.ndarray] = None

    def ref_velocity(self, t_s):
        """Return the reference velocity [rad/s] (central differences)."""
        return np.gradient(self.ref_rad, t_s)

    def ref_accel(self, t_s):
        """Return the reference acceleration [rad/s^2] (central differences, twice)."""
        return np.gradient(self.ref_velocity(t_s), t_s)


@dataclasses.dataclass
class Reference:
    """The time base, its axes (one, or X and Y of a circle) and where it came from."""

    t_s: np.ndarray
    axes: list
    kind: str
    source: str
    radius_m: float = 0.0           # circle only
    axial_load_n: Optional[float] = None   # a spec's load (None: the recording's or model's)
    leads_m: tuple = ()             # circle only: the lead of each axis [m]


@dataclasses.dataclass(frozen=True)
class ReferenceSpec:
    """A generated reference (module docstring)."""

    kind: str = dataclasses.field(default="reversal")
    stroke_rev: float = field(2.0, "rev", "nut travel of one move", lo=0.0, hi=1e5, lo_open=True)
    accel_rev_s2: float = field(20.0, "rev/s^2", "acceleration of the moves' ramps", lo=0.0,
                                hi=1e5, lo_open=True)
    dwell_s: float = field(0.0, "s", "rest between moves (0: reverse at once)", lo=0.0,
                           hi=1e4)
    cycles: int = field(1, "1", "forward-and-back moves per speed", lo=1, hi=10000)
    radius_mm: float = field(25.0, "mm", "circle radius", lo=0.0, hi=1e4, lo_open=True)
    feed_m_min: float = field(2.0, "m/min", "circle feed", lo=0.0, hi=1e3, lo_open=True)
    accel_m_s2: float = field(1.0, "m/s^2", "tangential acceleration of the circle's feed ramp",
                              lo=0.0, hi=1e3, lo_open=True)
    directions: str = dataclasses.field(default="both")

    def check(self, path):
        """Refuse an unknown kind or direction, naming the key."""
        if self.kind not in KINDS:
            raise ConfigError(f"{path}.kind: must be one of {', '.join(KINDS)}, got "
                              f"{self.kind!r}")
        if self.directions not in ("ccw", "cw", "both"):
            raise ConfigError(f"{path}.directions: must be ccw, cw or both, got "
                              f"{self.directions!r}")


def _speeds(raw, path):
    value = raw.pop("speeds_rev_s", [1.0])
    if not isinstance(value, list):
        value = [value]
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not 0.0 < v <= 1000.0:
            raise ConfigError(f"{path}.speeds_rev_s[{i}]: must be a number in (0, 1000] "
                              f"rev/s, got {v!r}")
        out.append(float(v))
    if not out:
        raise ConfigError(f"{path}.speeds_rev_s: empty")
    return out


def _load(raw, path):
    value = raw.pop("axial_load_n", None)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or abs(value) > 1e6:
        raise ConfigError(f"{path}.axial_load_n: must be a number within +-1e6 N, got "
                          f"{value!r}")
    return float(value)


def load_spec(path):
    """Return (ReferenceSpec, speeds [rev/s], load [N] or None) of a spec file."""
    raw = load_yaml(path)
    if SPEC_SECTION not in raw or not isinstance(raw[SPEC_SECTION], dict):
        raise ReferenceError(f"{path}: no '{SPEC_SECTION}:' mapping: a reference spec needs "
                             f"one (kind: {' | '.join(KINDS)}), a recording is a CSV")
    body = dict(raw[SPEC_SECTION])
    where = f"{path}: {SPEC_SECTION}"
    speeds = _speeds(body, where)
    load = _load(body, where)
    return from_mapping(ReferenceSpec, body, where), speeds, load


def _moves(speeds_rad_s, stroke_rad, accel, dwell_s, cycles):
    """Return (times, alphas) of trapezoidal moves forward and back at each speed."""
    times, alphas, t = [], [], 0.0
    for w in speeds_rad_s:
        ramp = w / accel
        cruise = stroke_rad / w - ramp
        if cruise < 0.0:                       # a triangle: the stroke is too short
            ramp, cruise = math.sqrt(stroke_rad / accel), 0.0
        for _ in range(cycles):
            for sign in (1.0, -1.0):
                for a, dur in ((sign * accel, ramp), (0.0, cruise), (-sign * accel, ramp),
                               (0.0, dwell_s)):
                    if dur > 0.0:
                        times.append(t)
                        alphas.append(a)
                        t += dur
    times.append(t)
    alphas.append(0.0)
    return np.array(times), np.array(alphas), t


def generate(spec, speeds_rev_s, rate_hz, leads_m, source):
    """
    Return the Reference of ``spec`` sampled at ``rate_hz``.

    ``leads_m``: the screw lead of each axis [m] (the circle's X and Y; the first otherwise).
    """
    dt = 1.0 / rate_hz
    if spec.kind in ("reversal", "constant_speed"):
        dwell = spec.dwell_s if spec.kind == "reversal" else max(spec.dwell_s, 0.1)
        two_pi = 2.0 * math.pi
        times, alphas, end = _moves([two_pi * s for s in speeds_rev_s], two_pi * spec.stroke_rev,
                                    two_pi * spec.accel_rev_s2, dwell, spec.cycles)
        t = np.arange(0.0, end + SETTLE_S, dt)
        phi, _, _ = sample_moves(times, alphas, t)
        return Reference(t, [Axis("axis", phi)], spec.kind, source)
    r = spec.radius_mm * 1e-3
    v = spec.feed_m_min / 60.0
    arc = 2.0 * math.pi * r
    signs = {"ccw": (1.0,), "cw": (-1.0,), "both": (1.0, -1.0)}[spec.directions]
    times, alphas, t_end = [], [], 0.0
    for sign in signs:
        ramp = v / spec.accel_m_s2
        # ramp up, a whole circle at the feed, ramp down: ISO 230-4's arc-in / arc-out
        for a, dur in ((sign * spec.accel_m_s2, ramp), (0.0, arc / v),
                       (-sign * spec.accel_m_s2, ramp), (0.0, 0.1)):
            times.append(t_end)
            alphas.append(a)
            t_end += dur
    times.append(t_end)
    alphas.append(0.0)
    t = np.arange(0.0, t_end + SETTLE_S, dt)
    s, _, _ = sample_moves(np.array(times), np.array(alphas), t)
    # the feed at constant speed starts after the first ramp: the arc measured from there
    theta = s / r
    lead_x, lead_y = leads_m[0], leads_m[-1]
    x, y = r * np.cos(theta), r * np.sin(theta)
    axes = [Axis("x", 2.0 * math.pi * x / lead_x), Axis("y", 2.0 * math.pi * y / lead_y)]
    return Reference(t, axes, "circle", source, radius_m=r, leads_m=(lead_x, lead_y))


def read_csv(path):
    """Return {column: array} of a recording CSV; refuse missing columns and non-numbers."""
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise ReferenceError(f"{path}: cannot read ({exc.strerror})") from exc
    with fh:
        reader = csv.DictReader(fh)
        try:
            header = reader.fieldnames or []
        except UnicodeDecodeError as exc:
            raise ReferenceError(f"{path}: not a UTF-8 text CSV ({exc.reason})") from None
        missing = [c for c in REQUIRED if c not in header]
        if missing:
            raise ReferenceError(
                f"{path}: no reference: the CSV lacks column(s) {', '.join(missing)} (needs "
                f"{', '.join(REQUIRED)}; optional {', '.join(OPTIONAL)}); has: "
                f"{', '.join(header) or 'no header'}")
        wanted = list(REQUIRED) + [c for c in OPTIONAL if c in header]
        cols = {c: [] for c in wanted}
        for line, row in enumerate(reader, start=2):
            for c in wanted:
                try:
                    value = float(row[c])
                except (TypeError, ValueError):
                    raise ReferenceError(f"{path}: line {line}, column {c}: not a number "
                                         f"({row[c]!r})") from None
                if not math.isfinite(value):
                    raise ReferenceError(f"{path}: line {line}, column {c}: not finite "
                                         f"({row[c]!r})")
                cols[c].append(value)
    out = {c: np.array(v, dtype=float) for c, v in cols.items()}
    if out["t_s"].size < 3:
        raise ReferenceError(f"{path}: {out['t_s'].size} rows: a reference needs at least 3")
    return out


def from_recording(path, rate_hz, need=()):
    """
    Return the Reference of a recording CSV at the loop's ``rate_hz``.

    ``need``: optional columns the run needs (e.g. ``nut_angle_rad`` and ``torque_meas_nm``
    for the measured-loop check); a recording without one is refused, naming it.
    """
    cols = read_csv(path)
    lacking = [c for c in need if c not in cols]
    if lacking:
        raise ReferenceError(f"{path}: lacks the measured channel(s) {', '.join(lacking)} "
                             f"asked for (has: {', '.join(cols)})")
    t = cols["t_s"]
    dt = np.diff(t)
    period = 1.0 / rate_hz
    bad = np.flatnonzero(np.abs(dt - period) > RATE_TOLERANCE * period)
    if bad.size:
        i = int(bad[0])
        raise ReferenceError(f"{path}: line {i + 3}: t_s steps by {dt[i]:.6g} s, not the "
                             f"loop period {period:.6g} s (loop.rate_hz = {rate_hz:g}): one "
                             "row per servo sample is needed")
    axis = Axis("axis", cols["nut_angle_ref_rad"], cols.get("nut_angle_rad"),
                cols.get("torque_meas_nm"), cols.get("command_offset_nm"),
                cols.get("axial_load_n"))
    return Reference(t - t[0], [axis], "recording", str(path))


def load_reference(path, rate_hz, leads_m, need=()):
    """Return the Reference of RECORDING: a CSV recording or a YAML spec (by suffix)."""
    p = Path(path)
    if not p.exists():
        raise ReferenceError(f"{path}: no such recording or reference spec")
    if p.suffix.lower() in (".yaml", ".yml"):
        spec, speeds, load = load_spec(p)
        if need:
            raise ReferenceError(f"{path}: a generated reference has no measured channels, "
                                 f"but {', '.join(need)} were asked for")
        ref = generate(spec, speeds, rate_hz, leads_m, str(path))
        ref.axial_load_n = load
        return ref
    return from_recording(p, rate_hz, need)
