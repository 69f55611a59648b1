"""
Controller side of the look-ahead feedforward: torque at a measured nut angle from profiles.

``friction_node`` publishes, at every model step, a ``bb_friction_msgs/FeedforwardProfile``:
the predicted friction torque at a row of nut angles from the angle of the step's input
ahead in the direction of motion (see ``runner.ModelRunner.profile``).  A controller keeps
the newest profile and, in every cycle, reads the torque at its own measured angle: no
round trip to the node, and the torque follows the balls' positions between model steps.

``FeedforwardInterpolator`` is that controller side.  It imports nothing (not even numpy)
and uses only arrays of doubles, comparisons and one division, so that it ports line by line
to C++ (a ``ros2_control`` controller: keep the profile in a
``realtime_tools::RealtimeBuffer``, call ``torque_at`` in ``update()``; the binary search is
``std::upper_bound``).  Rules, in the order they are applied:

1. **No usable profile yet** (none received, or none converged): 0 N m, status ``empty``.
2. **Non-converged profiles are ignored** (``converged = false``): the last converged one
   stays in use (the node's feedforward policy, README "Live node").
3. **Standstill** (the profile's velocity is 0, or the measured velocity is 0): 0 N m,
   status ``standstill``.  The model has no static friction (it is indeterminate at rest),
   and a held torque would push the axis in the direction it last moved.
4. **Reversal** (the measured velocity has the opposite sign of the profile's, or, without a
   measured velocity, the angle lies behind the profile's first point by more than
   ``reversal_tolerance_rad``): 0 N m, status ``reversed``.  The old direction's friction
   is never extrapolated; the node steps at once on a direction change, so the next profile
   (one round trip later) covers the new direction.
5. **Inside** the profile: linear interpolation in angle, status ``inside``.  Slightly behind
   the first point (within the tolerance, or with the measured velocity still in the
   profile's direction): the first point's torque.
6. **Beyond the last point** (the profile is older than its horizon): the last point's
   torque, status ``beyond``; a controller should count these cycles.

Optionally (``scale_with_load``), the torque is scaled by measured load / profile load when
both have the same sign and the profile's load is nonzero: quasi-static Coulomb friction is
proportional to the normal loads, which scale with the axial load (paper Eqs. 1-3); it
follows load changes between model steps to first order.
"""

EMPTY = "empty"
STANDSTILL = "standstill"
REVERSED = "reversed"
INSIDE = "inside"
BEYOND = "beyond"


class FeedforwardInterpolator:
    """
    Keep the newest converged profile and interpolate the friction torque at an angle.

    Parameters
    ----------
    reversal_tolerance_rad : float
        Without a measured velocity: how far behind the profile's first point an angle may
        lie (encoder noise, latency) before it counts as a reversal [rad].
    scale_with_load : bool
        Scale the torque by measured / profile axial load (see the module docstring).

    """

    def __init__(self, reversal_tolerance_rad=0.0, scale_with_load=False):
        """Start with no profile (torque 0, status ``empty``)."""
        if not reversal_tolerance_rad >= 0.0:
            raise ValueError("reversal_tolerance_rad must be >= 0, got "
                             f"{reversal_tolerance_rad}")
        self.reversal_tolerance_rad = float(reversal_tolerance_rad)
        self.scale_with_load = bool(scale_with_load)
        self._angle = []
        self._torque = []
        self._velocity = 0.0
        self._load = 0.0
        self._direction = 0.0
        self.stamp_s = None
        self.status = EMPTY
        self.ignored_nonconverged = 0

    def set_profile(self, nut_angle_rad, torque_total_nm, nut_velocity_rad_s, axial_load_n,
                    converged, stamp_s=None):
        """
        Take a profile (the fields of a FeedforwardProfile message).

        Returns True if it is now in use; False if it was ignored because it did not
        converge.  Raises ValueError for a malformed profile (lengths differ, empty, or the
        angles not monotonic in the direction of motion).
        """
        if not converged:
            self.ignored_nonconverged += 1
            return False
        n = len(nut_angle_rad)
        if n == 0 or n != len(torque_total_nm):
            raise ValueError(f"profile: {n} angles and {len(torque_total_nm)} torques")
        direction = 0.0
        if nut_velocity_rad_s > 0.0:
            direction = 1.0
        elif nut_velocity_rad_s < 0.0:
            direction = -1.0
        for i in range(1, n):
            if direction == 0.0 or (nut_angle_rad[i] - nut_angle_rad[i - 1]) * direction <= 0:
                raise ValueError("profile: nut_angle_rad must be strictly monotonic in the "
                                 "direction of motion (one point at standstill)")
        self._angle = [float(a) for a in nut_angle_rad]
        self._torque = [float(t) for t in torque_total_nm]
        self._velocity = float(nut_velocity_rad_s)
        self._load = float(axial_load_n)
        self._direction = direction
        self.stamp_s = stamp_s
        return True

    def set_profile_msg(self, msg):
        """Take a ``bb_friction_msgs/FeedforwardProfile`` message."""
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        return self.set_profile(msg.nut_angle_rad, msg.torque_total_nm,
                                msg.nut_velocity_rad_s, msg.axial_load_n, msg.converged,
                                stamp)

    def torque_at(self, nut_angle_rad, nut_velocity_rad_s=None, axial_load_n=None):
        """Return the feedforward friction torque [N m] at the measured angle (rules above)."""
        if not self._angle:
            self.status = EMPTY
            return 0.0
        d = self._direction
        if d == 0.0 or nut_velocity_rad_s == 0.0:
            self.status = STANDSTILL
            return 0.0
        # distance travelled past the first point, in the direction of motion
        s = (nut_angle_rad - self._angle[0]) * d
        if nut_velocity_rad_s is not None:
            reversed_ = nut_velocity_rad_s * d < 0.0
        else:
            reversed_ = s < -self.reversal_tolerance_rad
        if reversed_:
            self.status = REVERSED
            return 0.0
        n = len(self._angle)
        if s <= 0.0:
            torque = self._torque[0]
            self.status = INSIDE
        elif s >= (self._angle[n - 1] - self._angle[0]) * d:
            torque = self._torque[n - 1]
            self.status = BEYOND if s > (self._angle[n - 1] - self._angle[0]) * d else INSIDE
        else:
            lo, hi = 0, n - 1          # invariant: s(lo) <= s < s(hi)
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if (self._angle[mid] - self._angle[0]) * d <= s:
                    lo = mid
                else:
                    hi = mid
            a0, a1 = self._angle[lo], self._angle[hi]
            w = (nut_angle_rad - a0) / (a1 - a0)
            torque = self._torque[lo] + w * (self._torque[hi] - self._torque[lo])
            self.status = INSIDE
        if (self.scale_with_load and axial_load_n is not None and self._load != 0.0
                and axial_load_n * self._load > 0.0):
            torque *= axial_load_n / self._load
        return torque
