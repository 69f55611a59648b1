"""
The model file: a ball-screw config with optional empirical terms (``augmented.yaml``).

The one reader and the one writer of its layout::

    ball_screw:          # BallScrewConfig (ball_screw/parameters.py); edge units allowed
      geometry: {...}
      ...
    empirical_terms:     # optional: fitted terms (empirical_terms.py) added to the physics
      - {name: viscous_drag, params: {c_nm_s_per_rad: 0.004}}

A file without the ``ball_screw`` key holds the ball-screw sections at top level (next to
``empirical_terms``).  A file with no ball-screw values at all (empty, or only
``ball_screw:``) is refused, naming the file: it would otherwise run as the paper's screw.
The bundled ``config/ball_screw.yaml`` is a model file without terms; the discrepancy
workflow writes ``augmented.yaml`` with them; the node and replay read both.
"""

import yaml

from bb_friction_ros.ball_screw.parameters import BallScrewConfig
from bb_friction_ros.config import ConfigError, from_mapping, load_yaml
from bb_friction_ros.empirical_terms import load_terms, TermSet

SECTION = "ball_screw"
TERMS = "empirical_terms"
# Top-level key: which physics the runner adds the terms to.  "none" is written by
# ``discrepancy --baseline zero``: its terms were fitted to the whole
# measured torque, so adding them to the ball-screw model counted the friction twice.
PHYSICS = "physics"
PHYSICS_CHOICES = ("ball_screw", "none")


def _parts(path):
    """Return (the ball-screw mapping as written, the raw empirical-terms list or None)."""
    raw = load_yaml(path)
    if SECTION in raw:
        section = raw[SECTION]
        if section is None:
            section = {}
        if not isinstance(section, dict):
            raise ConfigError(f"{path}: {SECTION}: expected a mapping, got "
                              f"{type(section).__name__}")
    else:
        section = {k: v for k, v in raw.items() if k not in (TERMS, PHYSICS)}
    if not section:
        # An empty file (or only ``ball_screw:``), e.g. a custom screw truncated by a failed
        # copy, used to run silently as the paper's screw.
        raise ConfigError(f"{path}: no ball-screw values: the file is empty or its "
                          f"'{SECTION}' mapping is; a model file must describe the screw "
                          f"(copy config/ball_screw.yaml and edit it)")
    return section, raw.get(TERMS)


def _merge(base, extra):
    """Recursively merge mapping ``extra`` into a copy of ``base``."""
    out = dict(base)
    for key, value in (extra or {}).items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def load_ball_screw(path=None, overrides=None):
    """
    Return the validated BallScrewConfig of a model file and/or nested dict ``overrides``.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        Model file; its keys are SI or the edge units ``*_deg``, ``*_mm``, ``*_um``.
        Default: the built-in values (paper Table 4).
    overrides : dict, optional
        Nested mapping merged over the file, e.g. ``{"errors": {"theta_amplitude_deg": 1}}``.

    Returns
    -------
    BallScrewConfig
        Every field in SI units.

    Raises
    ------
    ConfigError
        On an unknown, mistyped or out-of-range key, naming it.

    """
    section = {} if path is None else _parts(path)[0]
    return from_mapping(BallScrewConfig, _merge(section, overrides), SECTION)


def physics_of(path):
    """
    Return the physics a model file's terms add to: ``"ball_screw"`` (default) or ``"none"``.

    ``"none"``: the terms are the whole torque (``discrepancy --baseline zero``); the runner
    predicts with them alone (``NoPhysics``), not on top of the ball-screw model.
    """
    value = load_yaml(path).get(PHYSICS, PHYSICS_CHOICES[0])
    if value not in PHYSICS_CHOICES:
        raise ConfigError(f"{path}: {PHYSICS}: must be one of {', '.join(PHYSICS_CHOICES)}, "
                          f"got {value!r}")
    return value


class NoPhysics:
    """
    The screw model of a ``physics: none`` model file: zero torque, always converged.

    It stands in for ``WholeScrew`` in the runner (same ``reset``/``step`` interface), so
    replay and the node predict the empirical terms alone, as the discrepancy workflow
    fitted them.
    """

    class _Result:
        torque_total_nm = 0.0
        torque_b2g_nm = 0.0
        torque_b2b_nm = 0.0
        groups = ()
        azimuth_rad = ()
        converged = True

    def reset(self, nut_angle_rad):
        """Nothing to forget."""

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        """Return a zero-torque, converged step result."""
        return self._Result()


def read_model_file(path):
    """Return (the ball-screw mapping as written, its validated TermSet)."""
    section, raw_terms = _parts(path)
    return section, load_terms(raw_terms)


def load_model_file(path):
    """
    Return the ball-screw config and the empirical terms of a model file, both validated.

    Parameters
    ----------
    path : str or pathlib.Path
        Model file (``config/ball_screw.yaml``, or ``augmented.yaml`` of the discrepancy
        workflow).

    Returns
    -------
    config : BallScrewConfig
        Every field in SI units.
    terms : TermSet
        The fitted terms (empty without ``empirical_terms``); their torque adds to the physics.

    Raises
    ------
    ConfigError
        On an unreadable file or a bad key, naming it.

    """
    section, terms = read_model_file(path)
    return from_mapping(BallScrewConfig, section, SECTION), terms


def write_model_file(path, ball_screw, terms=TermSet(), header="", physics=None):
    """
    Write a model file: the ball-screw mapping ``ball_screw`` and the TermSet ``terms``.

    ``header`` (comment lines) goes first; ``physics`` ("none": the terms alone, see
    ``physics_of``) is written as a top-level key when given.  Returns ``path``.
    """
    doc = {SECTION: ball_screw, TERMS: terms.to_list()}
    if physics is not None:
        if physics not in PHYSICS_CHOICES:
            raise ValueError(f"physics must be one of {PHYSICS_CHOICES}, got {physics!r}")
        doc = {PHYSICS: physics, **doc}
    path.write_text(header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=False))
    return path
