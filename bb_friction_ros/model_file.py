"""
The model file: a ball-screw config with optional empirical terms (``augmented.yaml``).

The one reader and the one writer of its layout::

    ball_screw:          # BallScrewConfig (ball_screw/parameters.py); edge units allowed
      geometry: {...}
      ...
    empirical_terms:     # optional: fitted terms (empirical_terms.py) added to the physics
      - {name: viscous_drag, params: {c_nm_s_per_rad: 0.004}}

A file without the ``ball_screw`` key holds the ball-screw sections at top level (next to
``empirical_terms``).  The bundled ``config/ball_screw.yaml`` is a model file without terms;
the discrepancy workflow writes ``augmented.yaml`` with them; the node and replay read both.
"""

import yaml

from bb_friction_ros.ball_screw.parameters import BallScrewConfig
from bb_friction_ros.config import ConfigError, from_mapping, load_yaml
from bb_friction_ros.empirical_terms import load_terms, TermSet

SECTION = "ball_screw"
TERMS = "empirical_terms"


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
        section = {k: v for k, v in raw.items() if k != TERMS}
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


def write_model_file(path, ball_screw, terms=TermSet(), header=""):
    """
    Write a model file: the ball-screw mapping ``ball_screw`` and the TermSet ``terms``.

    ``header`` (comment lines) goes first.  Returns ``path``.
    """
    doc = {SECTION: ball_screw, TERMS: terms.to_list()}
    path.write_text(header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=False))
    return path
