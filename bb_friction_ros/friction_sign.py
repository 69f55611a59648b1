"""The friction-sign check of a model file: friction must never push along the motion."""

import math

import numpy as np

from bb_friction_ros.config import ConfigError
from bb_friction_ros.empirical_terms import TermSet


# Loads at which a model's friction sign is checked, as multiples of its operating load: the
# physics and the load-dependent terms are close to linear in |W|, so the ends and the middle of
# twice the operating range find a term that overturns the physics there.
SIGN_CHECK_LOAD_FACTORS = (0.0, 1.0, 2.0)


# Points along a stroke_position term's fitted stroke (its polynomial is held beyond it).
SIGN_CHECK_STROKE_POINTS = 9


# Run time at which a thermal_drift term is taken as settled [s] (its exp(-t/tau) is 0).
SIGN_CHECK_SETTLED_S = 1e12


class FrictionSignError(ConfigError):
    """A model whose friction has the sign opposite to the nut velocity: it would push along."""


def friction_sign_violations(screw, terms, axial_load_n, nut_velocity_rad_s):
    """
    Return the states where a model's friction does not have the sign of the nut velocity.

    Friction is dissipated at the contacts: on the nut it acts against the motion, so in the
    model's convention (the torque the drive spends on it) it has the sign of the velocity.
    A model that gives the opposite sign would make every controller that feeds it forward
    push the axis along its motion.  The physics (a cold step of ``screw``) plus the terms
    that are friction (``empirical_terms.NOT_FRICTION`` left out) are evaluated in both
    directions at |W| = ``SIGN_CHECK_LOAD_FACTORS`` x ``axial_load_n``, at the start and after
    the warm-up of a ``thermal_drift`` term, and along a ``stroke_position`` term's stroke.
    Returns a list of (load N, velocity rad/s, friction N m), empty when the sign holds.
    """
    speed = abs(nut_velocity_rad_s) or 1.0
    if terms is not None:       # in steady motion a pre-rolling term is 0 (z = sign omega);
        # after a reversal the answers cut its friction at 0 (ModelRunner._with_terms)
        terms = TermSet(t for t in terms.terms if t.name != "pre_rolling")
    angles = [0.0]
    for t in (terms.terms if terms is not None else ()):
        if t.name == "stroke_position":
            p = t.params
            angles += list(p.center_rad + p.half_range_rad
                           * np.linspace(-1.0, 1.0, SIGN_CHECK_STROKE_POINTS))
    angles = np.array(angles)
    bad = []
    for factor in SIGN_CHECK_LOAD_FACTORS:
        load = factor * abs(axial_load_n)
        for w in (speed, -speed):
            sign = math.copysign(1.0, w)
            screw.reset(0.0)
            # friction x sign(velocity): >= 0 for a torque that dissipates
            along = sign * float(screw.step(0.0, w, load, 0.0).torque_total_nm)
            if terms is not None and len(terms):
                along = along + np.minimum(
                    sign * terms.friction_nm(0.0, angles, w, load),
                    sign * terms.friction_nm(SIGN_CHECK_SETTLED_S, angles, w, load)).min()
            if along < 0.0:
                bad.append((load, w, sign * float(along)))
    return bad


def check_friction_sign(screw, terms, config_path, axial_load_n, nut_velocity_rad_s):
    """
    Refuse a model whose friction follows the motion (``friction_sign_violations``).

    Raises FrictionSignError (a config error: the CLI exits 2, the node refuses to start)
    naming the file and the first state; a model fitted to a measured torque of the wrong
    sign (a motor current positive in the other direction) is the usual cause.
    """
    bad = friction_sign_violations(screw, terms, axial_load_n, nut_velocity_rad_s)
    if bad:
        load, w, torque = bad[0]
        raise FrictionSignError(
            f"{config_path}: its friction follows the motion (friction {torque:.4g} N m at nut "
            f"velocity {w:.4g} rad/s and |axial load| {load:.4g} N; {len(bad)} of "
            f"{2 * len(SIGN_CHECK_LOAD_FACTORS)} checked states): friction has the sign of the "
            "nut velocity, so a controller feeding this model forward would push the axis "
            "along its motion; was it fitted to a measured torque or motor current of the "
            "opposite sign convention?")
