"""
The ball-to-ball friction averaged over the arrangements of the balls.

The B2B torque of a whole screw depends on where its balls are along the loop: which gaps
close as the balls orbit at speeds the contact-angle deviation theta(phi) makes unequal
(paper Sec. 3.4).  A machine never sees that arrangement, and a model reset at start-up
assumes one (evenly spaced, ``WholeScrew.reset``).  A feedforward of the model's own B2B
ripple is then a ripple of the wrong phase: in closed loop it made the cruise error 7-20x
worse than a plain Coulomb + viscous feedforward (docs/servo_test.md).

``mean_b2b`` is the expectation over arrangements instead: the mean B2B torque of runs from
random arrangements (the slack of the loop shared among the gaps uniformly at random, a
random rotation), after a burn-in in which the balls settle as they do on a running machine,
at a grid of axial loads.  It keeps the mean increase that theta causes, without a ripple
tied to one arrangement.  Measured on the bundled screw with theta 3 deg at 1500 N
(``bench/bench_arrangement.py``): the first revolution from an even or a random arrangement
averages 0.020-0.032 N m of B2B torque, the sixth 0.0004-0.0046 N m: the balls settle into
arrangements with few contacts within a few revolutions.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import field
from bb_friction_ros.contact.friction_maps import cached_arrays


@dataclasses.dataclass(frozen=True)
class ArrangementAverage:
    """How the mean over arrangements is taken (the figures behind each: module docstring)."""

    starts: int = field(2, "1", "random arrangements the mean is taken over (its spread "
                        "over starts is ~half the mean at 1500 N, ~1 % of the friction)",
                        lo=1, hi=256)
    burn_in_revolutions: float = field(
        8.0, "rev", "nut revolutions run before the mean is taken: the balls settle over a "
        "few (the first averages 4-50x the sixth)", lo=0.0, hi=1000.0)
    revolutions: float = field(2.0, "rev", "nut revolutions the mean is taken over",
                               lo=0.1, hi=1000.0)
    step_deg: float = field(1.8, "deg", "nut rotation per model step (the node's default)",
                            lo=0.05, hi=30.0)
    load_factors: tuple = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0)   # x the model's operating load
    seed: int = field(0, "1", "seed of the random arrangements", lo=0)


def random_arrangement(screw, rng):
    """Return ball azimuths [rad]: the loop's slack shared among the gaps at random."""
    slack = screw.loop - screw.n * screw.separation
    gaps = rng.dirichlet(np.ones(screw.n)) * slack
    start = rng.uniform(0.0, screw.loop)
    return start + np.arange(screw.n) * screw.separation + np.cumsum(gaps) - gaps[0]


def _run_mean(screw, azimuth, load_n, velocity, s):
    """Return the mean (total, B2B) torque [N m] of one run after its burn-in (positive)."""
    step = math.radians(s.step_deg)
    n_burn = int(round(s.burn_in_revolutions * 2.0 * math.pi / step))
    n_mean = max(1, int(round(s.revolutions * 2.0 * math.pi / step)))
    screw.reset(0.0)
    screw.azimuth = azimuth
    total = b2b = 0.0
    k = 0
    for i in range(n_burn + n_mean + 1):
        res = screw.step(i * step, velocity, load_n, step / velocity if i else 0.0)
        if i > n_burn and res.converged:
            total += res.torque_total_nm
            b2b += res.torque_b2b_nm
            k += 1
    return (total / k, b2b / k) if k else (math.nan, math.nan)


class MeanB2B:
    """
    The model's torque averaged over arrangements at a grid of axial loads.

    ``total_at``: the whole friction of the physics (ball-to-groove and B2B: the B2B contact
    forces change each ball's load, so the ball-to-groove part carries the arrangement's
    ripple too); ``at``: its B2B part.  Linear in |W| between the grid's loads.
    """

    def __init__(self, loads_n, torque_nm, spread_nm, total_nm=None):
        """Hold the table: |W| [N] ascending, mean B2B torque [N m], its spread, mean total."""
        self.loads_n = np.asarray(loads_n, dtype=float)
        self.torque_nm = np.asarray(torque_nm, dtype=float)
        self.spread_nm = np.asarray(spread_nm, dtype=float)
        self.total_nm = self.torque_nm if total_nm is None else np.asarray(total_nm, float)

    def _signed(self, table, axial_load_n, nut_velocity_rad_s):
        if nut_velocity_rad_s == 0.0:
            return 0.0
        value = float(np.interp(abs(axial_load_n), self.loads_n, table))
        return math.copysign(value, nut_velocity_rad_s)

    def at(self, axial_load_n, nut_velocity_rad_s):
        """Return the mean B2B torque [N m] at a load, with the sign of the velocity."""
        return self._signed(self.torque_nm, axial_load_n, nut_velocity_rad_s)

    def total_at(self, axial_load_n, nut_velocity_rad_s):
        """Return the mean torque of the physics [N m] at a load, with the velocity's sign."""
        return self._signed(self.total_nm, axial_load_n, nut_velocity_rad_s)


def mean_b2b(config, settings=ArrangementAverage()):
    """
    Return the MeanB2B of a ball-screw config (cached on disk, keyed on both), or None.

    Without a contact-angle deviation the balls orbit at one speed and never touch: nothing
    depends on their arrangement, the model state's own torque is exact (None, no run).
    """
    w_op = abs(config.operation.axial_load_n) or 1000.0
    loads = np.array([f * w_op for f in settings.load_factors])
    if config.errors.theta_amplitude_rad == 0.0:
        return None         # no B2B contact: nothing depends on the arrangement

    def build():
        screw = WholeScrew(config)
        rng = np.random.default_rng(settings.seed)
        arrangements = [random_arrangement(screw, rng) for _ in range(settings.starts)]
        velocity = abs(config.operation.nut_velocity_rad_s) or 2.0 * math.pi
        means = np.array([[_run_mean(screw, a, load, velocity, settings) for a in arrangements]
                          for load in loads])         # (loads, starts, (total, b2b))
        return {"loads_n": loads, "torque_nm": means[:, :, 1].mean(axis=1),
                "spread_nm": means[:, :, 1].std(axis=1),
                "total_nm": means[:, :, 0].mean(axis=1)}
    table = cached_arrays("mean_b2b_total", (repr(config), repr(settings)), build)
    return MeanB2B(table["loads_n"], table["torque_nm"], table["spread_nm"],
                   table["total_nm"])
