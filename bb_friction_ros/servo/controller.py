"""
The controller: the common P position / PI velocity cascade at the servo rate.

At each sample t_k, from the measured angle phi_m (the encoder's reading) and the reference
(phi_r, omega_r, alpha_r)::

    omega_est = (phi_m[k] - phi_m[k - N]) / (N T)              N = velocity_estimate_span_samples
    omega_c   = K_p (phi_r - phi_m) + k_v omega_r               velocity command
    e_w       = omega_c - omega_est
    u         = K_v e_w + K_i I + k_a J alpha_r + T_ff          T_ff: the friction feedforward
    I        += e_w T          (not while u is limited and e_w would drive it further out)

and the command is u limited to +-torque_limit_nm.  The command computed from the sample
at t_k acts from t_(k+d) to t_(k+d+1) (zero-order hold), d = compute_delay_samples; before
the first command arrives the drive applies 0 N m.  Before N samples exist the velocity is
the difference over the samples there are (0 at the first).
"""

import collections
import math


class Cascade:
    """The cascade of the module docstring; ``step`` is called once per servo sample."""

    def __init__(self, loop, inertia_kg_m2):
        """``loop``: LoopSettings; ``inertia_kg_m2``: J of the acceleration feedforward."""
        self.loop = loop
        self.j = float(inertia_kg_m2)
        self.period = loop.period_s
        self.span = loop.velocity_estimate_span_samples
        self.history = collections.deque(maxlen=self.span + 1)
        self.integral = 0.0
        self.pending = collections.deque([0.0] * loop.compute_delay_samples)
        self.limited = 0

    def velocity_estimate(self, measured_angle_rad):
        """Take the new measured angle; return the velocity estimate [rad/s]."""
        self.history.append(measured_angle_rad)
        n = len(self.history) - 1
        if n == 0:
            return 0.0
        return (self.history[-1] - self.history[0]) / (n * self.period)

    def step(self, measured_angle_rad, omega_est, ref_angle_rad, ref_velocity_rad_s,
             ref_accel_rad_s2, friction_ff_nm):
        """
        Return (command computed now [N m], command applied over the coming period [N m]).

        Both are after the limit; they differ by the compute delay only.
        """
        lp = self.loop
        omega_c = lp.position_gain_per_s * (ref_angle_rad - measured_angle_rad) \
            + lp.velocity_feedforward * ref_velocity_rad_s
        e_w = omega_c - omega_est
        u = lp.velocity_gain_nm_s_per_rad * e_w \
            + lp.velocity_integral_gain_nm_per_rad * self.integral \
            + lp.acceleration_feedforward * self.j * ref_accel_rad_s2 + friction_ff_nm
        limit = lp.torque_limit_nm
        if abs(u) > limit:
            self.limited += 1
            u_lim = math.copysign(limit, u)
            if e_w * u < 0.0:           # conditional integration: only back towards the range
                self.integral += e_w * self.period
        else:
            u_lim = u
            self.integral += e_w * self.period
        self.pending.append(u_lim)
        return u_lim, self.pending.popleft()
