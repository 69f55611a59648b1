"""
Input validation shared by the live node and replay: messages in, InputSamples out.

``InputAssembler`` turns the two input streams (nut state, axial load) into samples exactly as
the node receives them; anything unusable is an ``InputError`` with a counted reason.
"""

from dataclasses import dataclass
import math

from bb_friction_ros.config import BBFrictionError


@dataclass(frozen=True)
class InputSample:
    """One nut-state sample with the axial load held at its stamp (SI units)."""

    stamp_s: float
    nut_angle_rad: float
    nut_velocity_rad_s: float
    axial_load_n: float


class InputError(BBFrictionError):
    """An input message is rejected; ``reason`` is a short key counted in diagnostics."""

    def __init__(self, reason, detail):
        """Keep the counted reason key and the human-readable detail."""
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def joint_state_sample(names, positions, velocities, joint):
    """
    Return (angle, velocity) of ``joint`` from JointState arrays, or raise InputError.

    Reasons: ``empty``, ``wrong_joint``, ``missing_velocity``, ``non_finite``.
    """
    if len(names) == 0 or len(positions) == 0:
        raise InputError("empty", "JointState has no joints")
    try:
        i = list(names).index(joint)
    except ValueError:
        raise InputError("wrong_joint", f"no joint named {joint!r} (got {list(names)})")
    if i >= len(positions):
        raise InputError("empty", f"joint {joint!r} has no position")
    if i >= len(velocities):
        raise InputError("missing_velocity", f"joint {joint!r} has no velocity")
    angle, velocity = float(positions[i]), float(velocities[i])
    if not (math.isfinite(angle) and math.isfinite(velocity)):
        raise InputError("non_finite", f"position {angle}, velocity {velocity}")
    return angle, velocity


def axial_load_value(force_z_n, max_axial_load_n):
    """
    Return the axial load [N] from WrenchStamped force.z, or raise InputError.

    The sign is kept (it says which flank carries the load); magnitudes above
    ``max_axial_load_n`` are rejected as ``absurd_load``.
    """
    value = float(force_z_n)
    if not math.isfinite(value):
        raise InputError("non_finite", f"force.z = {value}")
    if abs(value) > max_axial_load_n:
        raise InputError("absurd_load", f"|force.z| = {abs(value):.6g} N exceeds "
                         f"max_axial_load_n = {max_axial_load_n:.6g} N")
    return value


class InputAssembler:
    """
    Turn the two input streams into InputSamples, exactly as the node receives them.

    Axial-load messages update the held load; each nut-state message becomes a sample with
    the load held at that moment (arrival order, as ``ros2 bag play`` reproduces it).
    Raises InputError with a counted reason for anything unusable.
    """

    def __init__(self, nut_joint, max_axial_load_n):
        """Validate nut-state messages against ``nut_joint`` and loads against the limit."""
        self.load_n = None
        self._refused_load = None   # held load refused by a lowered limit: (load, limit)
        self.nut_joint = nut_joint
        self.max_axial_load_n = max_axial_load_n

    @property
    def max_axial_load_n(self):
        """Largest accepted |axial load| [N]."""
        return self._max_axial_load_n

    @max_axial_load_n.setter
    def max_axial_load_n(self, value):
        # A limit lowered at runtime applies to the load already held too: samples are
        # refused until a load within the new limit arrives.
        self._max_axial_load_n = value
        if self.load_n is not None and abs(self.load_n) > value:
            self._refused_load = (self.load_n, value)
            self.load_n = None

    @property
    def nut_joint(self):
        """Name of the nut joint in JointState messages (never empty)."""
        return self._nut_joint

    @nut_joint.setter
    def nut_joint(self, name):
        # an empty name matches no JointState entry: every input would be rejected
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"nut_joint must be a non-empty joint name, got {name!r}")
        self._nut_joint = name

    def on_axial_load(self, force_z_n):
        """Hold a new axial load [N]."""
        self.load_n = axial_load_value(force_z_n, self.max_axial_load_n)
        self._refused_load = None

    def on_nut_state(self, stamp_s, names, positions, velocities):
        """Return the InputSample of a nut-state message."""
        if not math.isfinite(stamp_s):
            raise InputError("non_finite", f"stamp {stamp_s}")
        angle, velocity = joint_state_sample(names, positions, velocities, self.nut_joint)
        if self.load_n is None:
            if self._refused_load is not None:
                load, limit = self._refused_load
                raise InputError("absurd_load", f"held |force.z| = {abs(load):.6g} N exceeds "
                                 f"max_axial_load_n = {limit:.6g} N (lowered while held); "
                                 "waiting for a new axial_load")
            raise InputError("no_load_yet", "no valid axial_load received yet")
        return InputSample(stamp_s, angle, velocity, self.load_n)
