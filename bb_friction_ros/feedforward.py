"""
Controller side of the look-ahead feedforward: torque at a measured nut angle from profiles.

``friction_node`` publishes, once per model period of motion (``runner.profile_due``), a
``bb_friction_msgs/FeedforwardProfile``: the predicted friction torque at a row of nut
angles from the angle of the step's input ahead in the direction of motion (see
``runner.look_ahead_profile``).  A controller keeps the newest profile and, in every
cycle, reads the torque at its own measured angle: no round trip to the node, and the
torque follows the balls' positions between model steps.

``FeedforwardInterpolator`` is that controller side.  It imports nothing (not even numpy)
and uses only arrays of doubles, comparisons and one division, so that it ports line by line
to C++ (a ``ros2_control`` controller: keep the profile in a
``realtime_tools::RealtimeBuffer``, call ``torque_at`` in ``update()``; the binary search is
``std::upper_bound``).  Rules, in the order they are applied:

1. **Non-finite measurement** (a NaN or infinite angle, velocity or, with load scaling, load):
   0 N m, status ``invalid_input``.  A controller should count these cycles: its sensor
   path is broken, and no friction is better than a NaN in the torque command.
2. **No usable profile yet** (none received, or none converged): 0 N m, status ``empty``.
3. **Stale profile** (only with ``max_profile_age_s``): the newest profile's stamp is more
   than ``max_profile_age_s`` away from the controller's clock ``now_s``: 0 N m, status
   ``stale``.  If the node dies or stalls, the last profile is not used for ever; the
   controller sees ``stale`` and falls back on its own (e.g. a static friction estimate).
   Both clocks must be the same (ROS time of the node's input stamps).
4. **Non-converged profiles are ignored** (``converged = false``): the last converged one
   stays in use (the node's feedforward policy, README "Live node").
5. **Standstill** (the profile's velocity is 0, or the measured velocity is 0): 0 N m,
   status ``standstill``.  The model has no static friction (it is indeterminate at rest),
   and a held torque would push the axis in the direction it last moved.
6. **Reversal** (the measured velocity has the opposite sign of the profile's, or, without a
   measured velocity, the angle lies behind the profile's first point by more than
   ``reversal_tolerance_rad``): 0 N m, status ``reversed``.  The old direction's friction
   is never extrapolated; the node steps at once on a direction change, so the next profile
   (one round trip later) covers the new direction.
7. **Inside** the profile: linear interpolation in angle, status ``inside``.  Slightly behind
   the first point (within the tolerance, or with the measured velocity still in the
   profile's direction): the first point's torque.
8. **Beyond the last point** (the profile is older than its horizon): the last point's
   torque, status ``beyond``; a controller should count these cycles.

Optionally (``scale_with_load``), the torque is scaled by measured load / profile load when
both have the same sign and the profile's load is nonzero: quasi-static Coulomb friction is
proportional to the normal loads, which scale with the axial load (paper Eqs. 1-3); it
follows load changes between model steps to first order.  The measured load's magnitude is
capped at ``max_axial_load_n``, the model's load range (``WholeScrew.max_axial_load_n``,
10.2 kN for the paper's screw; the model solves no load above it), so a load spike or a
broken load cell cannot scale the torque without bound; ``load_capped`` counts the cycles.

A malformed profile (lengths differ, empty, angles not strictly monotonic in the direction
of motion, or any non-finite angle, torque, velocity or load) raises ``ValueError``; the
interpolator keeps its previous profile.
"""

EMPTY = "empty"
STANDSTILL = "standstill"
REVERSED = "reversed"
INSIDE = "inside"
BEYOND = "beyond"
INVALID_INPUT = "invalid_input"
STALE = "stale"


def _finite(x):
    """Return True for a finite float (no math import: this ports line by line to C++)."""
    return x == x and x - x == 0.0     # NaN != NaN; inf - inf is NaN


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
    max_axial_load_n : float or None
        The model's load range [N]: the measured load's magnitude is capped here before
        scaling.  Required with ``scale_with_load``.
    max_profile_age_s : float or None
        A profile whose stamp is further than this from ``torque_at``'s ``now_s`` is stale
        (0 N m, status ``stale``) [s].  None: profiles never expire.

    """

    def __init__(self, reversal_tolerance_rad=0.0, scale_with_load=False,
                 max_axial_load_n=None, max_profile_age_s=None):
        """Start with no profile (torque 0, status ``empty``)."""
        if not (_finite(reversal_tolerance_rad) and reversal_tolerance_rad >= 0.0):
            raise ValueError("reversal_tolerance_rad must be >= 0, got "
                             f"{reversal_tolerance_rad}")
        if scale_with_load and max_axial_load_n is None:
            raise ValueError("scale_with_load needs max_axial_load_n (the model's load range "
                             "[N]), so that the scale is bounded")
        if max_axial_load_n is not None and not (_finite(max_axial_load_n)
                                                 and max_axial_load_n > 0.0):
            raise ValueError(f"max_axial_load_n must be a finite number > 0 N, got "
                             f"{max_axial_load_n}")
        if max_profile_age_s is not None and not (_finite(max_profile_age_s)
                                                  and max_profile_age_s > 0.0):
            raise ValueError(f"max_profile_age_s must be a finite number > 0 s, got "
                             f"{max_profile_age_s}")
        self.reversal_tolerance_rad = float(reversal_tolerance_rad)
        self.scale_with_load = bool(scale_with_load)
        self.max_axial_load_n = None if max_axial_load_n is None else float(max_axial_load_n)
        self.max_profile_age_s = None if max_profile_age_s is None else float(max_profile_age_s)
        self.load_capped = 0
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
        converge.  Raises ValueError for a malformed profile (lengths differ, empty, the
        angles not monotonic in the direction of motion, a non-finite number, or no stamp
        while ``max_profile_age_s`` is set); the previous profile then stays in use.
        """
        if not converged:
            self.ignored_nonconverged += 1
            return False
        n = len(nut_angle_rad)
        if n == 0 or n != len(torque_total_nm):
            raise ValueError(f"profile: {n} angles and {len(torque_total_nm)} torques")
        # before the monotonic check: every comparison with NaN is false, so a NaN angle
        # would pass it
        for name, values in (("nut_angle_rad", nut_angle_rad),
                             ("torque_total_nm", torque_total_nm)):
            for i in range(n):
                if not _finite(values[i]):
                    raise ValueError(f"profile: {name}[{i}] is not finite ({values[i]})")
        for name, value in (("nut_velocity_rad_s", nut_velocity_rad_s),
                            ("axial_load_n", axial_load_n)):
            if not _finite(value):
                raise ValueError(f"profile: {name} is not finite ({value})")
        if self.max_profile_age_s is not None and (stamp_s is None or not _finite(stamp_s)):
            raise ValueError(f"profile: stamp_s is needed (got {stamp_s}) when "
                             "max_profile_age_s is set")
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

    def torque_at(self, nut_angle_rad, nut_velocity_rad_s=None, axial_load_n=None, now_s=None):
        """
        Return the feedforward friction torque [N m] at the measured angle (rules above).

        ``now_s`` is the controller's clock [s], in the clock of the profiles' stamps;
        required when ``max_profile_age_s`` is set (ValueError otherwise).
        """
        if (not _finite(nut_angle_rad)
                or (nut_velocity_rad_s is not None and not _finite(nut_velocity_rad_s))
                or (self.scale_with_load and axial_load_n is not None
                    and not _finite(axial_load_n))):
            self.status = INVALID_INPUT
            return 0.0
        if self.max_profile_age_s is not None and (now_s is None or not _finite(now_s)):
            raise ValueError(f"torque_at: now_s is needed (got {now_s}) when "
                             "max_profile_age_s is set")
        if not self._angle:
            self.status = EMPTY
            return 0.0
        # a stamp far ahead of the clock is as untrustworthy as one far behind it
        if self.max_profile_age_s is not None and not (
                -self.max_profile_age_s <= now_s - self.stamp_s <= self.max_profile_age_s):
            self.status = STALE
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
            load = axial_load_n
            if abs(load) > self.max_axial_load_n:
                load = self.max_axial_load_n if load > 0.0 else -self.max_axial_load_n
                self.load_capped += 1
            torque *= load / self._load
        return torque


BEFORE = "before"
AFTER = "after"
PLANNED = "planned"


class PlannedPlayback:
    """
    Play a planned feedforward back by time: the controller side of ``bb-friction feedforward``.

    A plan is rows of (time [s], friction torque [N m]) computed along the commanded
    trajectory (``planned.planned_feedforward``, the node's ``friction/planned_feedforward``),
    each torque at its own row's time.  ``torque_at_time(now_s)`` gives the row at ``now_s``,
    linear between rows (a controller whose clock falls between them), on the plan's clock.
    Before the first row, after the last one, or without a plan: 0 N m (status ``before``,
    ``after``, ``empty``): a plan is never extrapolated.  A new plan replaces the old one from
    its own start time on; the old rows before it stay.  Like ``FeedforwardInterpolator`` it
    imports nothing and ports line by line to C++.  A malformed plan (lengths differ, empty,
    times not strictly increasing, anything non-finite) raises ``ValueError`` and the old one
    stays.
    """

    def __init__(self):
        """Start without a plan."""
        self._t = []
        self._torque = []
        self.status = EMPTY

    def set_plan(self, t_s, torque_nm):
        """Take a plan; it replaces the rows of the old one from its first time on."""
        t, q = [float(x) for x in t_s], [float(x) for x in torque_nm]
        if len(t) != len(q) or not t:
            raise ValueError("a plan needs as many torques as times, and at least one row")
        for i in range(len(t)):
            if not (_finite(t[i]) and _finite(q[i])):
                raise ValueError(f"plan row {i} is not finite")
            if i and not t[i] > t[i - 1]:
                raise ValueError(f"plan row {i}: times must increase")
        keep = 0
        while keep < len(self._t) and self._t[keep] < t[0]:
            keep += 1
        self._t = self._t[:keep] + t
        self._torque = self._torque[:keep] + q

    def torque_at_time(self, now_s):
        """Return the planned friction torque at ``now_s`` [N m] (see the class docstring)."""
        n = len(self._t)
        if n == 0 or not _finite(now_s):
            self.status = EMPTY if n == 0 else INVALID_INPUT
            return 0.0
        if now_s < self._t[0]:
            self.status = BEFORE
            return 0.0
        if now_s > self._t[n - 1]:
            self.status = AFTER
            return 0.0
        self.status = PLANNED
        lo, hi = 0, n - 1              # invariant: t(lo) <= now <= t(hi)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if self._t[mid] <= now_s:
                lo = mid
            else:
                hi = mid
        if now_s == self._t[hi]:
            return self._torque[hi]
        w = (now_s - self._t[lo]) / (self._t[hi] - self._t[lo]) if hi > lo else 0.0
        return self._torque[lo] + w * (self._torque[hi] - self._torque[lo])
