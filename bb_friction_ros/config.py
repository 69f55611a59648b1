"""
Validated configuration: frozen dataclasses with units in the field names, loaded from YAML.

Inside the core every value is SI (m, N, rad, s, Pa).  In YAML a user may also write the
edge units the project allows, named so: ``*_deg`` for an angle whose field is ``*_rad`` and
``*_mm`` for a length whose field is ``*_m`` (``*_mm_s`` for ``*_m_s``).  Each field carries
its unit, an admissible range and a one-line meaning in its metadata; a bad value is refused
with the dotted key and the reason.
"""

import dataclasses
import math
import os
from pathlib import Path
import stat
import warnings

import yaml


class BBFrictionError(ValueError):
    """
    Bad input from the user: a file, flag, recording or message that cannot be used as given.

    The parent of every input error of the package (``ConfigError``, ``BagError``,
    ``InputProblem``, ``InsufficientData``, ``InputError``, ``OutputPathError``, ...).  The
    CLI turns these, and only these, into exit status 2 with the message; any other exception
    is a bug and keeps its traceback (exit 1).  A ``ValueError`` so that callers catching
    ``ValueError`` keep working.
    """


class ConfigError(BBFrictionError):
    """A configuration value is missing, unknown or out of range; message names the key."""


def check_choice(key, value, choices):
    """Refuse (ConfigError naming ``key``) a ``value`` that is not one of ``choices``."""
    if value not in choices:
        raise ConfigError(f"{key}: must be one of {', '.join(choices)}, got {value!r}")


def field(default, unit, doc, lo=None, hi=None, lo_open=False, hi_open=False):
    """Declare a config field with its unit, meaning and admissible range [lo, hi]."""
    return dataclasses.field(default=default, metadata={
        "unit": unit, "doc": doc, "lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open})


# Memory a friction-map table or a sweep's results may need before it is refused [MiB]:
# 8 GiB, a third of a 24 GiB workstation.  The default of every ``*memory_limit_mib``
# setting; raise the setting, not this, for a bigger machine.
MEMORY_LIMIT_MIB = 8192.0
# The address the package's own Dask clusters (sweeps, physical trials) listen on: the
# loopback interface, so no worker is reachable from the network.
LOCALHOST = "127.0.0.1"


def format_bytes(n):
    """Return a byte count for people: ``'60.0 GiB'``, ``'512 MiB'``."""
    n = float(n)
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("kiB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def check_memory(need_bytes, limit_mib, path, what, limit_key):
    """Refuse (ConfigError naming ``path``) what needs more than ``limit_mib`` MiB."""
    if need_bytes > limit_mib * 2**20:
        raise ConfigError(f"{path}: {what} needs about {format_bytes(need_bytes)} of memory, "
                          f"above {limit_key} = {limit_mib:g} MiB; make it coarser or "
                          "raise the limit")


EDGE_UNITS = (   # (suffix in YAML, suffix of the SI field, factor to SI)
    ("_deg", "_rad", math.pi / 180.0),
    ("_mm_s", "_m_s", 1e-3),
    ("_mm", "_m", 1e-3),
    ("_um", "_m", 1e-6),
)


def si_key(key, names):
    """
    Return (SI name, factor to SI) of a key written with or without an edge unit.

    ``names`` holds the SI names (field names, or dotted parameter names: the unit is the
    suffix of the last part either way).  ``theta_deg`` gives ``("theta_rad", pi / 180)``
    when ``theta_rad`` is a name; a name gives itself with factor 1.  None when neither.
    """
    if key in names:
        return key, 1.0
    for edge, si, factor in EDGE_UNITS:
        if key.endswith(edge) and key[: -len(edge)] + si in names:
            return key[: -len(edge)] + si, factor
    return None


def current_name(cls, key, path):
    """
    Return the field name for ``key`` of config class ``cls``: ``key``, or its new name.

    A class lists its renamed keys in ``RENAMED = {old: new}``.  Files and scripts written
    before a rename keep working: the old key is read as the new one, with a FutureWarning
    that names both (``path`` is the dotted path of the key's mapping).
    """
    new = getattr(cls, "RENAMED", {}).get(key)
    if new is None:
        return key
    warnings.warn(f"{path}.{key}: renamed to {new}; read as {new}, please write {new}",
                  FutureWarning, stacklevel=3)
    return new


def parse_number(value, path, unit=""):
    """
    Return a YAML value as a number (int or float), or raise ConfigError naming ``path``.

    YAML 1.1 (PyYAML) reads ``1e1`` or ``2.1e11`` (no dot) as strings; users write them
    anyway, so a string that reads as a float is one.  Booleans are not numbers.  Parse
    first, then convert the unit: the factor applies to the number, never to the string.
    """
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        unit = f" in {unit}" if unit not in ("", "1", None) else ""
        raise ConfigError(f"{path}: expected a number{unit}, got {value!r}")
    return value


def _is_integer_field(f):
    return isinstance(f.default, int) and not isinstance(f.default, bool)


def _check_value(path, f, value):
    meta = f.metadata
    if isinstance(f.default, (list, tuple)):
        return value            # a sequence field: its owner converts and checks the items
    if isinstance(f.default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{path}: expected true or false, got {value!r}")
        return value
    if isinstance(f.default, str):
        if not isinstance(value, str):
            raise ConfigError(f"{path}: expected a string, got {value!r}")
        return value
    value = parse_number(value, path, meta.get("unit", ""))
    if not math.isfinite(value):
        raise ConfigError(f"{path}: must be finite, got {value!r}")
    if _is_integer_field(f):
        if value != int(value):
            raise ConfigError(f"{path}: must be an integer ({meta['doc']}), got {value!r}")
        value = int(value)
    else:
        value = float(value)
    lo, hi = meta.get("lo"), meta.get("hi")
    unit = "" if meta.get("unit") in (None, "1") else " " + meta["unit"]
    if lo is not None and (value < lo or (meta.get("lo_open") and value == lo)):
        rel = ">" if meta.get("lo_open") else ">="
        raise ConfigError(f"{path}: must be {rel} {lo}{unit} ({meta['doc']}), "
                          f"got {value}")
    if hi is not None and (value > hi or (meta.get("hi_open") and value == hi)):
        rel = "<" if meta.get("hi_open") else "<="
        raise ConfigError(f"{path}: must be {rel} {hi}{unit} ({meta['doc']}), "
                          f"got {value}")
    return value


def _nested_default(f):
    """Return the default instance of a nested config dataclass field, else None."""
    if f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
        return value if dataclasses.is_dataclass(value) else None
    return f.default if dataclasses.is_dataclass(f.default) else None


def from_mapping(cls, data, path):
    """Build dataclass ``cls`` from a mapping, converting edge units and validating ranges."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping, got {type(data).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in data.items():
        if not isinstance(key, str):
            raise ConfigError(f"{path}: key {key!r} is not a name (known: "
                              f"{', '.join(sorted(fields))})")
        resolved = si_key(current_name(cls, key, path), fields)
        if resolved is None:
            known = ", ".join(sorted(fields))
            raise ConfigError(f"{path}.{key}: unknown key (known: {known})")
        name, factor = resolved
        if name in kwargs:
            raise ConfigError(f"{path}.{key}: given twice (also as {name})")
        f = fields[name]
        sub = f"{path}.{key}"
        nested = _nested_default(f)
        if nested is not None:
            kwargs[name] = from_mapping(type(nested), value, sub)
            continue
        if factor != 1.0:
            value = parse_number(value, sub) * factor
        kwargs[name] = _check_value(sub, f, value)
    obj = cls(**kwargs)
    validate(obj, path)
    return obj


def validate(obj, path):
    """Range-check every field of a config dataclass (also defaults and programmatic values)."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            validate(value, f"{path}.{f.name}")
        elif "unit" in f.metadata:
            _check_value(f"{path}.{f.name}", f, value)
    check = getattr(obj, "check", None)
    if check is not None:
        check(path)


class _DuplicateKey(ValueError):
    pass


class _StrictLoader(yaml.SafeLoader):
    """safe_load that refuses a key given twice in one mapping (PyYAML keeps the last)."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                continue      # the base class refuses an unhashable key with its own message
            if key in seen:
                raise _DuplicateKey(f"line {key_node.start_mark.line + 1}: key {key!r} given "
                                    f"twice (first at line {seen[key].line + 1})")
            seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


# Largest config, model, params or sweep file read [bytes].  The bundled ones are 1-3 kB and
# a model file with every empirical term is a few kB; 4 MiB leaves room for long sweep value
# lists while `--config /dev/zero` or a mistaken recording can no longer be read until
# memory runs out.
MAX_CONFIG_BYTES = 4 * 2**20

_FILE_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
               (stat.S_ISSOCK, "a socket"))


def read_config_text(path, max_bytes=MAX_CONFIG_BYTES):
    """
    Return the text of a config file; ConfigError naming the file if it is not one.

    Refused: a missing or unreadable path, anything but a regular file (a FIFO would block
    the reader, ``/dev/zero`` never ends), a file larger than ``max_bytes``, and one that is
    not UTF-8 text.  The file is opened non-blocking and checked with ``fstat`` on the open
    descriptor, so a FIFO is never waited on and nothing can swap the file in between.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config ({exc.strerror})") from exc
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        kind = next((name for test, name in _FILE_KINDS if test(mode)), "not a file")
        raise ConfigError(f"{path}: is {kind}, not a regular file; a config must be a file")
    with os.fdopen(fd, "rb") as fh:
        try:
            data = fh.read(max_bytes + 1)
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read config ({exc.strerror})") from exc
    if len(data) > max_bytes:
        raise ConfigError(f"{path}: larger than {format_bytes(max_bytes)}; not a config file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text file (not UTF-8 at byte {exc.start})") from exc


def load_yaml(path):
    """
    Read a YAML file (safe types only); a problem with it is a ConfigError naming the file.

    Refused: a missing or unreadable file, anything but a regular file, one larger than
    ``MAX_CONFIG_BYTES``, one that is not text, a syntax error, a key given twice in one
    mapping, and a top level that is not a mapping.  An empty file gives {}.
    """
    text = read_config_text(path)
    try:
        data = yaml.load(text, Loader=_StrictLoader)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
    except _DuplicateKey as exc:
        raise ConfigError(f"{path}: {exc}") from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys at top level, got "
                          f"{type(data).__name__}")
    return data


def load_section(path, key):
    """
    Return the mapping under top-level ``key`` of a YAML file, or the whole file without it.

    A section that is not a mapping (``ball_screw: [1]``) is refused, not ignored.
    """
    raw = load_yaml(path)
    if key not in raw:
        return raw
    section = raw[key]
    if section is None:
        return {}
    if not isinstance(section, dict):
        raise ConfigError(f"{path}: {key}: expected a mapping, got {type(section).__name__}")
    return section


@dataclasses.dataclass(frozen=True)
class LinearBearingConfig:
    """Four-point-contact linear ball bearing module of the paper's Sec. 2 (Table 1)."""

    ball_radius_m: float = field(5e-3, "m", "ball radius R_B", lo=0.0, lo_open=True)
    conformity: float = field(0.56, "1", "groove radius / ball diameter", lo=0.5, hi=1.0,
                              lo_open=True)
    youngs_modulus_pa: float = field(210e9, "Pa", "Young's modulus of balls and rails",
                                     lo=0.0, lo_open=True)
    poisson_ratio: float = field(0.28, "1", "Poisson's ratio", lo=0.0, hi=0.5, hi_open=True)
    friction_coefficient: float = field(0.1, "1", "Coulomb coefficient mu, metal on metal",
                                        lo=0.0, hi=1.0, lo_open=True)
    nominal_contact_angle_rad: float = field(math.radians(45.0), "rad", "nominal contact "
                                             "angle beta_0", lo=0.0, hi=math.pi / 2,
                                             lo_open=True, hi_open=True)
    vertical_load_n: float = field(100.0, "N", "vertical load N_y on each ball", lo=0.0,
                                   lo_open=True)
    side_force_ratio: float = field(-0.6, "1", "rho = N_x / N_y on ball 1 (ball 2: -rho)",
                                    lo=-1.0, hi=1.0, lo_open=True, hi_open=True)
    groove_velocity_m_s: float = field(10e-3, "m/s", "velocity v of the top groove", lo=0.0,
                                       lo_open=True)
    k_f: float = field(1.38, "1", "slope of the linearised friction force, Eq. (14); the "
                       "paper's value", lo=0.0, lo_open=True)
    b2b_gap_tolerance_m: float = field(1e-9, "m", "gap below which two balls count as "
                                       "touching", lo=0.0)
    solver_tolerance: float = field(1e-12, "1", "Newton residual tolerance, relative to "
                                    "mu N_y", lo=0.0, lo_open=True, hi=1e-3)
    min_contact_load_n: float = field(1e-6, "N", "a contact with less load is unloaded: "
                                      "result flagged two-point", lo=0.0)
    map_nodes: int = field(4096, "1", "nodes of the tabulated friction map", lo=256,
                           hi=1 << 20)
    map_memory_limit_mib: float = field(MEMORY_LIMIT_MIB, "MiB", "largest memory the "
                                        "friction map's build may need; more is refused "
                                        "before it starts", lo=0.0, lo_open=True)
    # Sec. 2.4.1 statics: 'rigid' solves each ball's and its top groove's equilibrium with
    # the deviated angles; 'diagonal' uses the paper's F_BL = F_TR = sqrt(2)/2 (N_y - N_x).
    contact_force_model: str = dataclasses.field(default="rigid")

    def check(self, path):
        """Cross-field checks."""
        if self.contact_force_model not in ("rigid", "diagonal"):
            raise ConfigError(f"{path}.contact_force_model: must be 'rigid' or 'diagonal', "
                              f"got {self.contact_force_model!r}")
        from bb_friction_ros.contact.friction_maps import line_map_bytes
        check_memory(line_map_bytes(self.map_nodes), self.map_memory_limit_mib,
                     f"{path}.map_nodes", f"a friction map of {self.map_nodes} nodes",
                     f"{path}.map_memory_limit_mib")


def load_linear_bearing(path=None, overrides=None):
    """Load a LinearBearingConfig from YAML (key ``linear_bearing``) and/or overrides."""
    data = {} if path is None else dict(load_section(path, "linear_bearing"))
    data.update(overrides or {})
    return from_mapping(LinearBearingConfig, data, "linear_bearing")


def bundled_config(name):
    """
    Return the path of a bundled config file such as ``ball_screw.yaml``.

    Looks in the source tree (editable installs, as in .venv) and then in the installed
    share directory (colcon: ``share/bb_friction_ros/config``).
    """
    import sys
    here = Path(__file__).resolve().parent.parent / "config" / name
    candidates = [here, Path(sys.prefix) / "share" / "bb_friction_ros" / "config" / name]
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory("bb_friction_ros")) / "config" / name)
    except Exception:       # no ament index (plain venv) or package not registered
        pass
    for path in candidates:
        if path.is_file():
            return path
    raise ConfigError(f"{name}: bundled config not found (looked in "
                      f"{', '.join(str(c.parent) for c in candidates)})")
