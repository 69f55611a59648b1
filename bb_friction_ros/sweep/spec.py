"""
Sweep specification: a YAML mapping ``sweep`` read, validated and frozen (docs/sweeps.md).

The samples of a sweep are the full-factorial grid of the ``grid`` axes times ``samples``
random draws of the ``random`` variables per grid point (one draw, no randomness, without
``random``).  Sample ``i`` is grid point ``i // samples`` (C order: the last axis runs
fastest) and draw ``k = i % samples``.

Seeding: variable ``v`` of draw ``k`` takes its value from its own generator,
``default_rng(SeedSequence(seed, spawn_key=(k, crc32(v))))``.  A sample's inputs therefore
depend only on (seed, k, v): not on the worker, the batch or the order the samples run in;
every grid point sees the same draws (common random numbers: differences between grid points
are not blurred by sampling noise); adding a variable leaves the draws of the others as they
were.

Names: a parameter is a model's case parameter or a numeric config field (dotted
``section.field`` for the ball screw).  Like config files, a spec may write the edge units
``*_deg``, ``*_mm``, ``*_um`` for a ``*_rad`` or ``*_m`` parameter; everything is SI inside
and in the results.  A bad spec raises ConfigError naming the key.
"""

import dataclasses
import hashlib
import json
import math
from pathlib import Path
import warnings
import zlib

import numpy as np

from bb_friction_ros.config import ConfigError, load_yaml, parse_number, si_key
from bb_friction_ros.sweep.models import MODELS

# Bump when the meaning of a spec or the layout of its results changes: an old results
# directory is then refused rather than resumed with different samples.
SPEC_FORMAT = 1
SPEC_KEYS = ("name", "model", "options", "base", "grid", "random", "outputs", "batch_size")
DISTRIBUTIONS = {            # kind -> its parameters, in the order the draw uses them
    "normal": ("mean", "std"),
    "uniform": ("low", "high"),
    "halfnormal": ("std",),          # |N(0, std)|: a signed amplitude is a phase shift by pi
    "integers": ("low", "high"),     # inclusive, for integer parameters (ball count)
    "choice": ("values",),           # equally likely
}


# Memory estimate of the results: every column is 8 bytes a row but the
# text ones: the converged flag, the status (offset and ~12 characters) and the reason
# (offset; null when ok) take about this much a row.
_ROW_TEXT_BYTES = 24
# results.parquet is compacted in memory: the parts read, then their sorted copy.
_COMPACT_COPIES = 2


@dataclasses.dataclass(frozen=True)
class Axis:
    """A grid axis: a parameter (SI name) and its values (SI)."""

    name: str
    values: tuple


@dataclasses.dataclass(frozen=True)
class Variable:
    """A random parameter: SI name, distribution kind and its SI parameters."""

    name: str
    kind: str
    params: tuple               # ((parameter, value), ...) in DISTRIBUTIONS order
    integer: bool = False

    def draw(self, rng):
        """Draw one value from numpy Generator ``rng``."""
        p = dict(self.params)
        if self.kind == "normal":
            return float(rng.normal(p["mean"], p["std"]))
        if self.kind == "uniform":
            return float(rng.uniform(p["low"], p["high"]))
        if self.kind == "halfnormal":
            return float(abs(rng.normal(0.0, p["std"])))
        if self.kind == "integers":
            return int(rng.integers(p["low"], p["high"], endpoint=True))
        values = p["values"]
        return values[int(rng.integers(len(values)))]

    def stream(self, seed, draw):
        """Return the generator of this variable for draw index ``draw``."""
        key = (int(draw), zlib.crc32(self.name.encode()))
        return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A validated sweep; see the module docstring for how samples are numbered and seeded."""

    name: str
    model: str
    options: tuple              # ((option, value), ...) sorted
    base: object                # the model's frozen config dataclass
    grid: tuple                 # Axis, ...
    variables: tuple            # Variable, ...
    samples: int                # draws per grid point
    seed: int
    outputs: tuple              # output names kept
    batch_size: int             # samples per Dask task
    config_names: frozenset     # parameters that are config fields (the rest: case parameters)
    source: str = ""            # where the spec came from (not part of the digest)

    @property
    def grid_shape(self):
        """Return the number of values of each grid axis."""
        return tuple(len(a.values) for a in self.grid)

    @property
    def n_grid(self):
        """Return the number of grid points (1 without grid)."""
        return int(np.prod(self.grid_shape, dtype=np.int64))

    @property
    def n_samples(self):
        """Return the number of samples of the sweep."""
        return self.n_grid * self.samples

    @property
    def n_batches(self):
        """Return the number of Dask tasks (batches of ``batch_size`` samples)."""
        return -(-self.n_samples // self.batch_size)

    @property
    def results_bytes(self):
        """Return the memory [bytes] the results need when they are compacted (an estimate)."""
        columns = 3 + len(self.input_names) + len(self.outputs)
        return _COMPACT_COPIES * self.n_samples * (8 * columns + _ROW_TEXT_BYTES)

    @property
    def input_names(self):
        """Return the parameters a sample sets: grid axes, then random variables."""
        return tuple(a.name for a in self.grid) + tuple(v.name for v in self.variables)

    @property
    def option_map(self):
        """Return the model options as a dict."""
        return dict(self.options)

    def batch_bounds(self, batch):
        """Return the sample range [start, stop) of batch number ``batch``."""
        start = batch * self.batch_size
        return start, min(start + self.batch_size, self.n_samples)

    def sample_inputs(self, start, stop):
        """Return {column: array} of samples [start, stop): sample, grid_index, draw, inputs."""
        idx = np.arange(start, stop, dtype=np.int64)
        grid_index, draw = np.divmod(idx, self.samples)
        cols = {"sample": idx, "grid_index": grid_index, "draw": draw}
        if self.grid:
            for axis, pos in zip(self.grid, np.unravel_index(grid_index, self.grid_shape)):
                cols[axis.name] = np.asarray(axis.values)[pos]
        for var in self.variables:
            cols[var.name] = np.array([var.draw(var.stream(self.seed, k)) for k in draw],
                                      dtype=np.int64 if var.integer else float)
        return cols

    def canonical(self):
        """Return the JSON-able form that identifies the samples and their results."""
        return {"format": SPEC_FORMAT, "model": self.model, "options": dict(self.options),
                "base": dataclasses.asdict(self.base),
                "grid": [[a.name, list(a.values)] for a in self.grid],
                "variables": [[v.name, v.kind, [list(p) if isinstance(p, tuple) else p
                                                for _, p in v.params]]
                              for v in self.variables],
                "samples": self.samples, "seed": self.seed, "outputs": list(self.outputs),
                "batch_size": self.batch_size}

    def digest(self):
        """Return a SHA-256 of the canonical form: equal digests mean equal samples."""
        text = json.dumps(self.canonical(), sort_keys=True, allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()


def load_spec(path, overrides=None):
    """Load and validate a sweep spec from YAML (key ``sweep``); ``overrides`` top-level keys."""
    raw = load_yaml(path)
    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: expected a mapping with key 'sweep'")
    data = raw.get("sweep", raw)
    if not isinstance(data, dict):
        raise ConfigError("sweep: expected a mapping")
    data = {**data, **(overrides or {})}
    return spec_from_mapping(data, Path(path).resolve().parent, Path(path).stem,
                             source=str(path))


def spec_from_mapping(data, base_dir=".", default_name="sweep", source=""):
    """Validate a spec mapping (the value of ``sweep``); relative paths from ``base_dir``."""
    _known_keys(data, SPEC_KEYS, "sweep")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise ConfigError(f"sweep.name: expected a non-empty string, got {name!r}")
    model_name = data.get("model")
    if model_name not in MODELS:
        raise ConfigError(f"sweep.model: must be one of {', '.join(MODELS)}, got "
                          f"{model_name!r}")
    model = MODELS[model_name]
    options = _options(model, data.get("options"))
    base = _base_config(model, data.get("base"), Path(base_dir))
    parameters = model.parameters(base)
    grid = _grid(data.get("grid"), parameters, model)
    variables, samples, seed = _random(data.get("random"), parameters, model)
    names = [a.name for a in grid] + [v.name for v in variables]
    for n in set(names):
        if names.count(n) > 1:
            raise ConfigError(f"sweep.random.variables: {n!r} is also a grid axis (or given "
                              "twice with different units)")
    if model_name == "linear_pair" and "theta_rad" in names \
            and {"dbeta_bl_rad", "dbeta_br_rad"} & set(names):
        raise ConfigError("sweep: theta_rad sets dbeta_BL = -theta and dbeta_BR = +theta; "
                          "give theta or dbeta_bl_rad/dbeta_br_rad, not both")
    outputs = _outputs(model, data.get("outputs"))
    batch = data.get("batch_size", model.batch_size.get(options.get("method"),
                                                        model.batch_size.get("default")))
    batch = _integer(batch, "sweep.batch_size", lo=1)
    return SweepSpec(name, model_name, tuple(sorted(options.items())), base, grid, variables,
                     samples, seed, outputs, batch,
                     frozenset(n for n, p in parameters.items() if p.config_field), source)


def _known_keys(data, known, path):
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping, got {type(data).__name__}")
    for key in data:
        if key not in known:
            raise ConfigError(f"{path}.{key}: unknown key (known: {', '.join(known)})")


def _options(model, data):
    data = {} if data is None else data
    _known_keys(data, tuple(model.options) or ("(none)",), "sweep.options")
    out = {}
    for key, (default, allowed) in model.options.items():
        value = data.get(key, default)
        if allowed is int:
            value = _integer(value, f"sweep.options.{key}", lo=0)
        elif value not in allowed:
            raise ConfigError(f"sweep.options.{key}: must be one of {', '.join(allowed)}, got "
                              f"{value!r}")
        out[key] = value
    return out


def _base_config(model, data, base_dir):
    data = {} if data is None else data
    _known_keys(data, ("config", "overrides"), "sweep.base")
    path = data.get("config")
    if path is not None:
        if not isinstance(path, str):
            raise ConfigError(f"sweep.base.config: expected a file path, got {path!r}")
        path = base_dir / path
    overrides = data.get("overrides") or {}
    if not isinstance(overrides, dict):
        raise ConfigError("sweep.base.overrides: expected a mapping of config keys")
    return model.load_base(path, overrides)


def _parameter(name, parameters, model, path):
    """Return (Parameter, factor to SI) for a name possibly written with an edge unit."""
    if not isinstance(name, str):
        raise ConfigError(f"{path}: parameter names are strings, got {name!r}")
    resolved = si_key(name, parameters)
    if resolved is not None:
        param = parameters[resolved[0]]
        if param.name != resolved[0]:       # an old name of a renamed config field
            warnings.warn(f"{path}: renamed to {param.name}; read as {param.name}, please "
                          f"write {param.name}", FutureWarning, stacklevel=2)
        return param, resolved[1]
    known = sorted(k for k, p in parameters.items() if p.name == k)
    raise ConfigError(f"{path}: unknown parameter of model {model.name} (known: "
                      f"{', '.join(known)}; edge units *_deg, *_mm, *_um)")


def _number(value, path):
    value = parse_number(value, path)
    if not math.isfinite(value):
        raise ConfigError(f"{path}: expected a finite number, got {value!r}")
    return value


def _integer(value, path, lo=None):
    value = _number(value, path)
    if value != int(value) or (lo is not None and value < lo):
        rel = "" if lo is None else f" >= {lo}"
        raise ConfigError(f"{path}: expected an integer{rel}, got {value!r}")
    return int(value)


def _si(value, param, factor, path):
    """Convert one value to SI; integer parameters must be integral (no unit factor)."""
    if param.integer:
        return _integer(value, path)
    return float(_number(value, path)) * factor


def _axis_values(spec, path):
    if isinstance(spec, list):
        if not spec:
            raise ConfigError(f"{path}: an empty list of values")
        return spec
    if not isinstance(spec, dict):
        raise ConfigError(f"{path}: expected a list of values or a range mapping "
                          "{start, stop, num} or {start, stop, step}")
    if "num" in spec:
        _known_keys(spec, ("start", "stop", "num"), path)
        num = _integer(spec["num"], f"{path}.num", lo=1)
        return list(np.linspace(_number(spec.get("start"), f"{path}.start"),
                                _number(spec.get("stop"), f"{path}.stop"), num))
    _known_keys(spec, ("start", "stop", "step"), path)
    start = _number(spec.get("start"), f"{path}.start")
    stop = _number(spec.get("stop"), f"{path}.stop")
    step = _number(spec.get("step"), f"{path}.step")
    if step <= 0 or stop < start:
        raise ConfigError(f"{path}: needs step > 0 and stop >= start")
    # Inclusive of stop up to rounding: the count is rounded, not floored.
    count = int(math.floor((stop - start) / step + 0.5)) + 1
    return [start + i * step for i in range(count)]


def _grid(data, parameters, model):
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError("sweep.grid: expected a mapping {parameter: values}")
    axes = []
    for key, spec in data.items():
        path = f"sweep.grid.{key}"
        param, factor = _parameter(key, parameters, model, path)
        values = _axis_values(spec, path)
        axes.append(Axis(param.name, tuple(_si(v, param, factor, f"{path}[{i}]")
                                           for i, v in enumerate(values))))
    return tuple(axes)


def _random(data, parameters, model):
    if data is None:
        return (), 1, 0
    _known_keys(data, ("samples", "seed", "variables"), "sweep.random")
    samples = _integer(data.get("samples"), "sweep.random.samples", lo=1)
    seed = _integer(data.get("seed"), "sweep.random.seed", lo=0)
    var_data = data.get("variables")
    if not isinstance(var_data, dict) or not var_data:
        raise ConfigError("sweep.random.variables: expected a non-empty mapping "
                          "{parameter: {dist: ..., ...}}")
    variables = []
    for key, spec in var_data.items():
        path = f"sweep.random.variables.{key}"
        param, factor = _parameter(key, parameters, model, path)
        variables.append(_variable(param, factor, spec, path))
    return tuple(variables), samples, seed


def _variable(param, factor, spec, path):
    if not isinstance(spec, dict) or spec.get("dist") not in DISTRIBUTIONS:
        raise ConfigError(f"{path}.dist: must be one of {', '.join(DISTRIBUTIONS)}")
    kind = spec["dist"]
    _known_keys(spec, ("dist",) + DISTRIBUTIONS[kind], path)
    if param.integer and kind not in ("integers", "choice"):
        raise ConfigError(f"{path}.dist: {param.name} is an integer: use integers or choice")
    if kind == "integers" and not param.integer:
        raise ConfigError(f"{path}.dist: integers is for integer parameters; use uniform")
    params = []
    for key in DISTRIBUTIONS[kind]:
        if key not in spec:
            raise ConfigError(f"{path}.{key}: missing (a {kind} distribution needs "
                              f"{', '.join(DISTRIBUTIONS[kind])})")
        if key == "values":
            values = _axis_values(spec[key], f"{path}.values")
            params.append((key, tuple(_si(v, param, factor, f"{path}.values[{i}]")
                                      for i, v in enumerate(values))))
        else:
            params.append((key, _si(spec[key], param, factor, f"{path}.{key}")))
    p = dict(params)
    if "std" in p and p["std"] < 0:
        raise ConfigError(f"{path}.std: must be >= 0, got {p['std']}")
    if "low" in p and p["high"] < p["low"]:
        raise ConfigError(f"{path}.high: must be >= low ({p['low']}), got {p['high']}")
    return Variable(param.name, kind, tuple(params), param.integer)


def _outputs(model, data):
    known = [o.name for o in model.outputs]
    if data is None:
        return tuple(known)
    if not isinstance(data, list) or not data:
        raise ConfigError("sweep.outputs: expected a non-empty list of output names")
    for name in data:
        if name not in known:
            raise ConfigError(f"sweep.outputs: unknown output {name!r} of model {model.name} "
                              f"(known: {', '.join(known)})")
    return tuple(dict.fromkeys(data))
