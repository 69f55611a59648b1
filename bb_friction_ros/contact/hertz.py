"""
Hertz contact of a ball on a grooved body: exact elliptic solution (Johnson, Contact Mechanics).

All quantities SI: m, N, Pa.  The contact ellipse has semi-axis ``a`` along the direction of
smaller relative curvature (across a conforming groove) and ``b`` along the other
(the rolling direction), ``b <= a``.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eq. (15) and Table 1 (Psi), Eq. (53) (load from approach), Eq. (A7) (peak pressure).
.. [2] Johnson, K. L., 1985, Contact Mechanics, Cambridge University Press (the paper's
   ref. [20]): the elliptical Hertz contact.

"""

from dataclasses import dataclass
import math

import numpy as np

from bb_friction_ros.contact.friction_maps import cached_arrays


def effective_modulus(youngs_modulus_pa, poisson_ratio):
    """Contact modulus E* of two bodies of the same steel: 1/E* = 2 (1 - nu^2) / E  [Pa]."""
    return youngs_modulus_pa / (2.0 * (1.0 - poisson_ratio ** 2))


def ellipticity_from_curvatures(curv_a_per_m, curv_b_per_m):
    """
    Return k = b/a of the Hertz ellipse for relative curvatures across (a) and along (b).

    Solves B/A = (E(e)/k^2 - K(e)) / (K(e) - E(e)) with e^2 = 1 - k^2 (Johnson Eq. 4.39),
    where A = curv_a/2 < B = curv_b/2.
    """
    if not 0.0 < curv_a_per_m <= curv_b_per_m:
        raise ValueError(
            f"relative curvatures must satisfy 0 < curv_a <= curv_b, got {curv_a_per_m}, "
            f"{curv_b_per_m} (is the groove radius larger than the ball radius?)")
    return _ellipse(curv_b_per_m / curv_a_per_m)[0]


def _ellipse(ratio):
    """
    (k, E(e), K(e)) of the Hertz ellipse for the curvature ratio B/A >= 1.

    Kept in the table cache (``friction_maps.cached_arrays``): computed with scipy once,
    then read back bit for bit; importing scipy.optimize and scipy.special cost 0.26 s of
    the node's start-up (measured), more than everything else the core imports.
    """
    def build():
        from scipy.optimize import brentq
        from scipy.special import ellipe, ellipk

        def residual(k):
            m = 1.0 - k * k
            return (ellipe(m) / k ** 2 - ellipk(m)) / (ellipk(m) - ellipe(m)) - ratio

        k = 1.0 if ratio - 1.0 < 1e-12 else \
            brentq(residual, 1e-6, 1.0 - 1e-12, xtol=1e-15, rtol=1e-15)
        m = 1.0 - k * k
        return {"k_e_k": np.array([k, float(ellipe(m)), float(ellipk(m))])}

    k, big_e, big_k = cached_arrays("hertz-ellipse", (float(ratio),), build)["k_e_k"].tolist()
    return k, big_e, big_k


@dataclass(frozen=True)
class HertzContact:
    """
    Load-independent coefficients of one Hertz contact; arrays of loads broadcast.

    a = coef_a_m_per_n13 * Q^(1/3), b = k * a, approach = coef_delta * Q^(2/3).
    """

    ellipticity: float          # k = b/a
    coef_a_m_per_n13: float     # a / Q^(1/3)   [m N^(-1/3)]
    coef_delta_m_per_n23: float  # delta / Q^(2/3) [m N^(-2/3)]
    elliptic_e: float           # E(e), complete elliptic integral of the 2nd kind

    @classmethod
    def from_curvatures(cls, curv_a_per_m, curv_b_per_m, e_star_pa):
        """Build from relative curvatures (sum of both bodies, 1/m) and contact modulus E*."""
        ellipticity_from_curvatures(curv_a_per_m, curv_b_per_m)     # checks the curvatures
        k, big_e, big_k = _ellipse(curv_b_per_m / curv_a_per_m)
        a_plus_b = 0.5 * (curv_a_per_m + curv_b_per_m)
        # Q = (2/3) pi a b p0 and p0 = E* b (A+B) / E(e)  =>  a^3 = 3 Q E(e) / (2 pi k^2 E* (A+B))
        coef_a = (3.0 * big_e / (2.0 * math.pi * k * k * e_star_pa * a_plus_b)) ** (1.0 / 3.0)
        # delta = p0 b K(e) / E*  =  3 Q K(e) / (2 pi a E*)
        coef_delta = 3.0 * big_k / (2.0 * math.pi * coef_a * e_star_pa)
        return cls(k, coef_a, coef_delta, big_e)

    @classmethod
    def ball_in_straight_groove(cls, ball_radius_m, conformity, youngs_modulus_pa,
                                poisson_ratio):
        """
        Ball in a circular-arc groove of radius 2 conf R_B on a straight rail (Table 1).

        Parameters
        ----------
        ball_radius_m : float
            Ball radius R_B  [m].
        conformity : float
            Groove radius / ball diameter, > 0.5  [1].
        youngs_modulus_pa : float
            Young's modulus of ball and groove (same steel)  [Pa].
        poisson_ratio : float
            Poisson's ratio  [1].

        Returns
        -------
        HertzContact

        """
        groove_radius = 2.0 * conformity * ball_radius_m
        return cls.from_curvatures(1.0 / ball_radius_m - 1.0 / groove_radius,
                                   1.0 / ball_radius_m,
                                   effective_modulus(youngs_modulus_pa, poisson_ratio))

    def psi(self, ball_radius_m):
        """
        Psi of Eq. (15): a = Psi R_B^(1/3) F^(1/3).

        Parameters
        ----------
        ball_radius_m : float
            Ball radius R_B  [m].

        Returns
        -------
        float
            Psi  [(m^2/N)^(1/3)]; Table 1 prints 5.307e-4 (``paper.PSI``).

        """
        return self.coef_a_m_per_n13 / ball_radius_m ** (1.0 / 3.0)

    def semi_axes(self, load_n):
        """Semi-axes (a, b) [m] for normal load(s) [N]; zero for non-positive loads."""
        q = np.maximum(np.asarray(load_n, dtype=float), 0.0)
        a = self.coef_a_m_per_n13 * np.cbrt(q)
        return a, self.ellipticity * a

    def peak_pressure(self, load_n):
        """Eq. (A7): sigma_0 = 3 Q / (2 pi a b)  [Pa]."""
        a, b = self.semi_axes(load_n)
        q = np.asarray(load_n, dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(q > 0.0, 1.5 * q / (math.pi * a * b), 0.0)

    def approach(self, load_n):
        """Elastic approach delta [m] of the two bodies under load Q."""
        q = np.maximum(np.asarray(load_n, dtype=float), 0.0)
        return self.coef_delta_m_per_n23 * q ** (2.0 / 3.0)

    def load_from_approach(self, approach_m):
        """Inverse of ``approach``: Q = (delta / coef)^(3/2), zero when delta <= 0  [N]."""
        d = np.maximum(np.asarray(approach_m, dtype=float), 0.0)
        return (d / self.coef_delta_m_per_n23) ** 1.5

    def stiffness(self, load_n):
        """Tangent contact stiffness dQ/d(delta) = 1.5 Q / delta  [N/m]."""
        q = np.maximum(np.asarray(load_n, dtype=float), 0.0)
        return 1.5 * np.cbrt(q) / self.coef_delta_m_per_n23
