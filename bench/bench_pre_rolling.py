"""
Pre-rolling: why it is a fitted term, and how well the workflow recovers a hidden travel.

1. The travel the contact mechanics alone would give: Mindlin's full-slip displacement of a
   Hertz contact under a tangential load mu Q (Johnson, Contact Mechanics, eq. 7.42, with the
   circle of the ellipse's area), for the bundled screw's ball, groove and steel at three axial
   loads.  The nut travels about twice the contact's slip (rolling).
2. Hidden pre-rolling travels on servo moves (1 kHz, 12 s), fitted by the discrepancy
   workflow: the travel found against the hidden one.

Usage: .venv/bin/python bench/bench_pre_rolling.py
"""

import math
import time

from bb_friction_ros.config import bundled_config
from bb_friction_ros.contact.hertz import HertzContact
from bb_friction_ros.discrepancy.servo_moves import Drive, servo_recording
from bb_friction_ros.discrepancy.settings import DiscrepancySettings
from bb_friction_ros.discrepancy.workflow import analyse
from bb_friction_ros.model_file import load_model_file


def mindlin_table():
    cfg, _ = load_model_file(bundled_config("ball_screw.yaml"))
    g, m = cfg.geometry, cfg.material
    h = HertzContact.ball_in_straight_groove(g.ball_radius_m, g.conformity,
                                             m.youngs_modulus_pa, m.poisson_ratio)
    shear = m.youngs_modulus_pa / (2.0 * (1.0 + m.poisson_ratio))
    n = cfg.track.n_balls
    print("axial load N | ball load N | a x b um | Mindlin slip um | nut travel um | rad")
    for load in (500.0, 1500.0, 3000.0):
        q = load / (n * math.sin(g.nominal_contact_angle_rad))
        a = h.coef_a_m_per_n13 * q ** (1.0 / 3.0)
        b = h.ellipticity * a
        slip = 3.0 * (2.0 - m.poisson_ratio) * m.friction_coefficient * q \
            / (8.0 * shear * math.sqrt(a * b))
        travel = 2.0 * slip
        print(f"{load:12.0f} | {q:11.1f} | {a * 1e6:.0f} x {b * 1e6:.0f} | {slip * 1e6:15.3f} | "
              f"{travel * 1e6:13.2f} | {travel / g.lead_m * 2.0 * math.pi:.2e}")


def recovery_table():
    print("\nhidden travel rad | found rad | ratio | T_p found / hidden | s")
    for travel, seed in ((0.001, 5), (0.003, 3), (0.01, 4), (0.03, 6)):
        drive = Drive(coulomb_nm=0.03, pre_rolling_rad=travel)
        rec, _ = servo_recording(1000.0, 12.0, drive, seed=seed)
        t0 = time.perf_counter()
        a = analyse(rec, DiscrepancySettings())
        took = time.perf_counter() - t0
        found = {t.name: t.params for t in a.terms.terms}.get("pre_rolling")
        if found is None:
            print(f"{travel:17.4g} | not named | - | - | {took:.1f}")
            continue
        print(f"{travel:17.4g} | {found.travel_rad:9.4g} | {found.travel_rad / travel:5.2f} | "
              f"{found.torque_nm / drive.coulomb_nm:18.2f} | {took:.1f}")


if __name__ == "__main__":
    mindlin_table()
    recovery_table()
