"""
Look-ahead profiles: the torque at a row of nut angles ahead of a model step.

After a step, a copy of the model state is stepped ahead along the extrapolated motion (same
velocity and load) to give the torque at a row of nut angles ahead of the input, spaced in
angle; a controller interpolates in it (``feedforward.FeedforwardInterpolator``).
"""

from dataclasses import dataclass
import math

from bb_friction_ros.inputs import InputSample
from bb_friction_ros.schedule import _sign, ANGLE_RESOLUTION_RAD, STAMP_RESOLUTION_S


@dataclass(frozen=True)
class ProfileSeed:
    """A model state right after a step, to be stepped ahead by ``look_ahead_profile``."""

    screw: object
    sample: InputSample
    torque_total_nm: float      # the step's own torque (model only, no empirical terms)
    converged: bool
    period_s: float             # the schedule's time floor [s]
    terms: object
    run_time_s: float           # stamp since the run's first sample (empirical terms' time)
    # the inertia term's causal acceleration at the sample, held over the horizon (the
    # extrapolated velocity is constant, but the filter's alpha is the best guess of the
    # inertia torque for the next few ms); None without an inertia term
    nut_accel_rad_s2: object = None
    step_rad: float = 0.0       # the schedule's nut rotation between steps [rad]
    # the largest step the copy takes between two points [rad] (max_model_step_deg): steps
    # are cheapest per degree there, and the live node can abandon a profile between them
    max_step_rad: float = math.inf
    mean_b2b: object = None     # the runner's: the profile's physics averaged too


def profile_horizon_rad(seed, horizon_periods):
    """
    Nut rotation the look-ahead covers [rad]: ``horizon_periods`` model periods of motion.

    A model period is the time floor's (``period_s``, the look-ahead the profile had when
    the model stepped by the clock), or, when the nut creeps so slowly that it turns less
    than one model step in it, the model step: the profile never covers less than
    ``horizon_periods`` steps of the angle schedule.
    """
    return _horizon_rad(abs(seed.sample.nut_velocity_rad_s), seed.period_s, seed.step_rad,
                        horizon_periods)


def _horizon_rad(w_abs, period_s, step_rad, horizon_periods):
    return horizon_periods * max(w_abs * period_s, step_rad)


def _profile_substeps(horizon_rad, n_points, max_step_rad):
    """Model steps from one profile point to the next (each at most ``max_step_rad``)."""
    return max(1, math.ceil(horizon_rad / (n_points - 1) / max_step_rad - ANGLE_RESOLUTION_RAD))


def profile_due(last, sample):
    """
    Return True if a step at ``sample`` should start a new look-ahead profile.

    ``last`` is the ProfileSeed of the last profile published (None: none yet).  A profile
    covers ``profile_horizon_periods`` (at least 2) model periods of motion ahead, so one per
    model period keeps a controller covered a period ahead at all times: a new one is due
    when the nut has turned one period of motion (``profile_horizon_rad(last, 1)``: at
    least one model step) since the last, its stamps have advanced one model period (a load
    change), or the direction changed (start, stop, reversal: at once).  At every step, the
    old rule, a 20 rev/s motion asked for 500-4000 profiles/s of 5-20 ms each.
    """
    if last is None:
        return True
    prev = last.sample
    return _sign(sample.nut_velocity_rad_s) != _sign(prev.nut_velocity_rad_s) \
        or abs(sample.nut_angle_rad - prev.nut_angle_rad) \
        >= profile_horizon_rad(last, 1.0) - ANGLE_RESOLUTION_RAD \
        or not 0.0 <= sample.stamp_s - prev.stamp_s < last.period_s - STAMP_RESOLUTION_S


def look_ahead_profile(seed, horizon_periods=2.0, n_points=3, should_stop=None):
    """
    Predicted friction torque ahead of a model step, at constant velocity and load.

    Points, in the nut-angle domain: the step's own angle psi_0 (its torque equals the
    prediction there), then ``n_points - 1`` angles evenly spaced up to
    psi_0 + sign(omega) * ``profile_horizon_rad``; a copy of the model is stepped to each in
    turn (the time between points, for the empirical terms and the step, is the angle over
    |omega|).  Points further apart than ``seed.max_step_rad`` are reached in equal
    sub-steps no longer than it: at 20 rev/s two points are 72 deg apart, and one 72 deg step
    cost 28 ms per profile against 18 ms in 14.4 deg steps (load 7 on 2 cores,
    docs/model_schedule.md), and held the model thread all that time.
    At standstill (omega = 0) the profile is the single point psi_0.
    Returns (angles [rad], torques [N m], converged), or None if ``should_stop()`` became
    true between two steps (the live node gives way to a pending model step).
    """
    s = seed.sample
    w = s.nut_velocity_rad_s

    def extra(t_s, angle):
        if seed.terms is None:
            return 0.0
        return float(seed.terms.torque_nm(seed.run_time_s + t_s, angle, w, s.axial_load_n,
                                          seed.nut_accel_rad_s2))

    def physics(own_nm):
        """Return a point's torque of the physics: its own, or the mean over arrangements."""
        if seed.mean_b2b is None:
            return own_nm
        return seed.mean_b2b.total_at(s.axial_load_n, w)

    angles = [s.nut_angle_rad]
    torques = [physics(seed.torque_total_nm) + extra(0.0, s.nut_angle_rad)]
    converged = seed.converged
    if w == 0.0 or n_points < 2:
        return angles, torques, converged
    screw = seed.screw
    horizon = profile_horizon_rad(seed, horizon_periods)
    d_angle = math.copysign(horizon / (n_points - 1), w)
    dt = d_angle / w
    n_sub = _profile_substeps(horizon, n_points, seed.max_step_rad)
    path = hasattr(screw, "step_path")
    for i in range(1, n_points):
        if path:
            # a point's sub-steps and its answered step in one call (WholeScrew.step_path)
            if should_stop is not None and should_stop():
                return None
            points = [s.nut_angle_rad + d_angle * (i - 1 + j / n_sub)
                      for j in range(1, n_sub + 1)]
            res = screw.step_path(points, [w] * n_sub, [s.axial_load_n] * n_sub, dt / n_sub)
            converged = converged and bool(res.converged) and not res.substeps_not_converged
            angle = points[-1]
        for j in range(1, n_sub + 1) if not path else ():
            if should_stop is not None and should_stop():
                return None
            angle = s.nut_angle_rad + d_angle * (i - 1 + j / n_sub)
            # only each point's last sub-step is answered (published)
            res = screw.step(angle, w, s.axial_load_n, dt / n_sub, substep=j < n_sub)
            converged = converged and bool(res.converged)
        angles.append(angle)
        torques.append(physics(res.torque_total_nm) + extra(dt * i, angle))
    return angles, torques, converged


def profile_fits(schedule, step_time_s, sample, horizon_periods, n_points):
    """
    Return True if a look-ahead profile from ``sample`` can end before the next step.

    Its model steps (``look_ahead_profile``: ``n_points - 1`` points, each reached in
    sub-steps of at most the coarsest step) at the steps' mean wall time ``step_time_s``
    (None: none yet), against the input time to the next step due at this velocity under
    ``schedule`` (a model step of rotation, or the time floor).  The live node gives way to
    every due step, so a profile that cannot end before it is abandoned: at 20 rev/s with
    1 kHz inputs (a step due at every input, 1 ms apart) a 144 deg profile is ten 14.4 deg
    steps, 1.5-4 ms, and every one started was abandoned, at 0.3-0.4 of a core
    (docs/model_schedule.md).
    """
    w = abs(sample.nut_velocity_rad_s)
    if w == 0.0 or n_points < 2:
        return True
    step = schedule.step_rad * schedule.scale       # as ModelRunner.profile_seed gives them
    period = schedule.period_s * schedule.scale
    n_sub = _profile_substeps(_horizon_rad(w, period, step, horizon_periods), n_points,
                              schedule.step_rad * schedule.max_scale)
    cost_s = (n_points - 1) * n_sub * (step_time_s or 0.0)
    return cost_s < min(step / w, period)
