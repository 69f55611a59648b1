"""
The feedforwards a user has instead of the product, fitted on a calibration run.

Calibration data: the drive torque u, the angle phi and its velocity omega and acceleration
alpha (zero-phase filtered) of a run of the axis, from a recording (``--calibration``) or
from a calibration run of the simulated plant in the loop.  The friction seen there is
u - J alpha, J the plant's inertia (the one the loop's acceleration feedforward uses).

* **Coulomb + viscous**: T = c omega + T_c sign(omega), least squares on the moving samples
  (with an offset column T_0 fitted and left out of the feedforward: a constant torque is
  not friction, the integral gain takes it).  What drives and the common ros2_control
  friction controller offer.
* **LuGre** (Canudas de Wit et al. 1995): dz/dt = omega - sigma_0 |omega| z / g(omega),
  g = T_c + (T_s - T_c) exp(-(omega/omega_s)^2), T = sigma_0 z + sigma_2 omega.  The
  steady state (T_c, T_s, omega_s, sigma_2) by least squares on the constant-speed samples;
  the bristle stiffness sigma_0 by least squares of the simulated torque along the whole
  calibration run.  sigma_1 (micro-damping) is 0: its torque is sigma_1 dz/dt, and dz/dt
  of a measured velocity is the noise of the velocity estimate.  sigma_0 is reported as not
  identifiable when the cost hardly changes over its range (``LUGRE_FLAT``): then the data
  hold no pre-sliding the fit could see (too coarse an encoder, no reversal), and the fit
  says so instead of inventing one.
"""

import dataclasses
import math

import numpy as np

# Samples whose |omega| is below this share of the run's largest |omega| are standstill for
# the fits (the friction there is indeterminate: it holds whatever the drive applies).
MOVING_FRACTION = 0.02
# Constant-speed samples for LuGre's steady state: |alpha| below this share of the largest.
STEADY_ACCEL_FRACTION = 0.05
# ... and |omega| above this share of the largest: the start from rest (the loop building up
# torque against static friction) is not a point of the steady curve.
STEADY_SPEED_FRACTION = 0.05
# sigma_0 is searched over the pre-sliding travels g / sigma_0 in [1e-7, 1] rad.
PRESLIDING_RANGE_RAD = (1e-7, 1.0)
# The cost of the best sigma_0 must be at least this share below that of the stiffest
# (a plain sign switch) for the pre-sliding to count as identified.
LUGRE_FLAT = 0.01


@dataclasses.dataclass
class Calibration:
    """A calibration run: time, angle, velocity, acceleration, drive torque, load (SI)."""

    t_s: np.ndarray
    angle_rad: np.ndarray
    velocity_rad_s: np.ndarray
    accel_rad_s2: np.ndarray
    torque_nm: np.ndarray
    source: str

    def friction(self, inertia_kg_m2):
        """Return the friction the drive overcame: u - J alpha [N m]."""
        return self.torque_nm - inertia_kg_m2 * self.accel_rad_s2

    def moving(self):
        """Return the mask of moving samples."""
        w = np.abs(self.velocity_rad_s)
        return w > MOVING_FRACTION * max(float(w.max()), 1e-12)


@dataclasses.dataclass
class CoulombViscous:
    """Fitted c [N m s/rad], T_c [N m] (and the offset T_0 [N m], not fed forward)."""

    c_nm_s_per_rad: float
    coulomb_nm: float
    offset_nm: float

    @classmethod
    def fit(cls, cal, inertia_kg_m2):
        """Least squares of u - J alpha on [omega, sign(omega), 1], moving samples."""
        m = cal.moving()
        if m.sum() < 4:
            raise ValueError("calibration run: fewer than 4 moving samples")
        w = cal.velocity_rad_s[m]
        a = np.column_stack([w, np.sign(w), np.ones_like(w)])
        coef, *_ = np.linalg.lstsq(a, cal.friction(inertia_kg_m2)[m], rcond=None)
        return cls(float(coef[0]), float(coef[1]), float(coef[2]))

    def torque(self, velocity_rad_s):
        """Return the feedforward [N m] at a velocity (0 at standstill)."""
        if velocity_rad_s == 0.0:
            return 0.0
        return self.c_nm_s_per_rad * velocity_rad_s + math.copysign(self.coulomb_nm,
                                                                    velocity_rad_s)

    def summary(self):
        """Return the fitted values by name."""
        return {"c_nm_s_per_rad": self.c_nm_s_per_rad, "coulomb_nm": self.coulomb_nm,
                "offset_nm_not_fed_forward": self.offset_nm}


@dataclasses.dataclass
class LuGre:
    """Fitted LuGre parameters (module docstring) and how sound the fit is."""

    sigma0_nm_per_rad: float
    sigma2_nm_s_per_rad: float
    coulomb_nm: float
    stiction_nm: float
    stribeck_rad_s: float
    identified: bool = True
    note: str = ""
    offset_nm: float = 0.0

    def g(self, w):
        """Return the steady friction magnitude without viscous part [N m]."""
        return self.coulomb_nm + (self.stiction_nm - self.coulomb_nm) \
            * math.exp(-(w / self.stribeck_rad_s) ** 2)

    def steady(self, w):
        """Return the steady-state torque at velocity w [N m]."""
        if w == 0.0:
            return 0.0
        return math.copysign(self.g(w), w) + self.sigma2_nm_s_per_rad * w

    def simulate(self, angle_rad, dt_s, z0=0.0):
        """Return the torque along a sampled angle (exact z for each step's mean velocity)."""
        n = angle_rad.size
        out = np.zeros(n)
        z = z0
        s0 = self.sigma0_nm_per_rad
        for k in range(1, n):
            d = angle_rad[k] - angle_rad[k - 1]
            w = d / dt_s
            if d != 0.0:
                g = self.g(w)
                zss = math.copysign(g / s0, w)
                z = zss + (z - zss) * math.exp(-s0 * abs(d) / g)
            out[k] = s0 * z + self.sigma2_nm_s_per_rad * w
        return out

    def summary(self):
        """Return the fitted values by name, with the soundness note."""
        return {"sigma0_nm_per_rad": self.sigma0_nm_per_rad, "sigma1_nm_s_per_rad": 0.0,
                "sigma2_nm_s_per_rad": self.sigma2_nm_s_per_rad,
                "coulomb_nm": self.coulomb_nm, "stiction_nm": self.stiction_nm,
                "stribeck_rad_s": self.stribeck_rad_s,
                "presliding_rad": self.coulomb_nm / self.sigma0_nm_per_rad,
                "presliding_identified": self.identified, "note": self.note}


def fit_lugre(cal, inertia_kg_m2, max_evaluations=400):
    """Fit LuGre on ``cal`` (module docstring); return a LuGre with its soundness note."""
    from scipy.optimize import least_squares, minimize_scalar
    f = cal.friction(inertia_kg_m2)
    w = cal.velocity_rad_s
    a = cal.accel_rad_s2
    w_abs = np.abs(w)
    m = (w_abs >= STEADY_SPEED_FRACTION * max(float(w_abs.max()), 1e-12)) \
        & (np.abs(a) <= STEADY_ACCEL_FRACTION * max(float(np.abs(a).max()), 1e-12))
    if m.sum() < 8:
        m = cal.moving()
    wm, fm = w[m], f[m]
    cv = np.linalg.lstsq(np.column_stack([wm, np.sign(wm), np.ones_like(wm)]), fm,
                         rcond=None)[0]
    offset = float(cv[2])
    wmax = float(np.abs(wm).max())

    def resid(p):
        tc, dts, ws, s2 = p
        return np.sign(wm) * (tc + dts * np.exp(-(wm / ws) ** 2)) + s2 * wm + offset - fm

    tc0 = max(float(cv[1]), 1e-6)
    wmin = float(np.abs(wm).min())
    # the Stribeck speed is not sought below half the slowest steady speed: the data say
    # nothing about a rise there
    sol = least_squares(resid, [tc0, 0.1 * tc0, max(0.1 * wmax, wmin), max(float(cv[0]), 0.0)],
                        bounds=([0.0, 0.0, 0.5 * wmin, 0.0],
                                [np.inf, np.inf, wmax, np.inf]), max_nfev=max_evaluations)
    tc, dts, ws, s2 = (float(x) for x in sol.x)
    base = LuGre(1.0, s2, tc, tc + dts, ws, offset_nm=offset)
    dt = float(np.median(np.diff(cal.t_s)))
    gmax = max(tc + dts, 1e-12)

    def cost(log_travel):
        base.sigma0_nm_per_rad = gmax / math.exp(log_travel)
        e = base.simulate(cal.angle_rad, dt) + offset - f
        return float(e @ e)

    lo, hi = (math.log(x) for x in PRESLIDING_RANGE_RAD)
    res = minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                          options={"maxiter": max(10, max_evaluations // 10),
                                   "xatol": 0.05})
    best = float(res.x)
    stiff = cost(lo)
    c_best = cost(best)
    base.sigma0_nm_per_rad = gmax / math.exp(best)
    identified = stiff > 0.0 and (stiff - c_best) / stiff >= LUGRE_FLAT \
        and lo + 0.1 < best < hi - 0.1
    note = ""
    if not identified:
        if best >= hi - 0.1:
            note = ("pre-sliding not identifiable: the fit runs to the softest bristles "
                    f"({PRESLIDING_RANGE_RAD[1]:g} rad), the data do not constrain it")
        else:
            note = (f"pre-sliding not identifiable: the cost changes by "
                    f"{100.0 * (stiff - c_best) / max(stiff, 1e-300):.2g} % between a sign "
                    "switch and the best stiffness (the calibration shows no pre-sliding "
                    "above its encoder resolution and noise); sigma_0 kept at the stiff end")
            base.sigma0_nm_per_rad = gmax / PRESLIDING_RANGE_RAD[0]
    return LuGre(base.sigma0_nm_per_rad, s2, tc, tc + dts, ws, identified, note, offset)


class LuGreState:
    """A LuGre feedforward stepping its z along the angle it is given."""

    def __init__(self, params):
        """Start with relaxed bristles (z = 0)."""
        self.p = params
        self.z = 0.0
        self.last = None

    def torque(self, angle_rad, velocity_rad_s):
        """Advance z to ``angle_rad``; return sigma_0 z + sigma_2 omega [N m]."""
        p = self.p
        if self.last is not None:
            d = angle_rad - self.last
            if d != 0.0:
                g = p.g(velocity_rad_s if velocity_rad_s != 0.0 else 0.0)
                zss = math.copysign(g / p.sigma0_nm_per_rad, d)
                self.z = zss + (self.z - zss) * math.exp(-p.sigma0_nm_per_rad * abs(d) / g)
        self.last = angle_rad
        return p.sigma0_nm_per_rad * self.z + p.sigma2_nm_s_per_rad * velocity_rad_s
