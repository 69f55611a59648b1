"""
Elastic load distribution along the nut: axial bars of shaft and nut between the balls.

The paper's whole screw (Sec. 3.4) follows its ref. [19] (Lin, Okwudire & Wou 2018): an
800 mm screw, free to translate axially at both ends, loaded by W at one end, with a nut that
only rotates.  Bulk axial deformation of shaft and nut makes each ball's load vary along the
nut.  The standard low-order formulation (Mei, Tsutsumi et al. 2003; the "spring-bar" model of
threaded joints) is used:

- Balls are ordered along the nut by their position in the loaded track, k = 0..N-1 (k = 0 at
  the track start, the low-z end of the nut).  Ball k carries P_k = -axial_k into the nut
  (the force of the ball on the nut along +z; sum P_k = W).
- Between balls k and k+1 the shaft and the nut are bars of length dz_k = p dphi_k / 2pi with
  axial stiffness E A / dz_k (``ElasticBodies``: E A of each body).  With the cumulative
  load C_k = P_0 + ... + P_k, the bar forces (tension > 0) are
      shaft: T_s = C_k - W   (W enters at the track-start end)  or  C_k   (at the track end)
      nut:   T_n = W - C_k   (flange at the track start)  or  -C_k  (at the track end),
             and no deformation when the nut is held on its outer surface.
- Compatibility: the nut-minus-shaft axial displacement at the balls, v_k, changes between
  neighbours by the bars' elongations,
      v_{k+1} - v_k = dz_k (T_n / EA_n - T_s / EA_s) = a_k - b_k C_k,
  with a_k = W (S_n c_n + L_s c_s), b_k = c_n + c_s, c = dz_k / E A per bar, and the
  selectors S_n (flange at the track start) and L_s (load at the track start).
- Each ball's Hertz contacts see its own v_k (the rigid model has one u for all balls).  The
  Hertz deflections and this compatibility are solved together with the friction, in one
  Newton system that is block tridiagonal along the nut (``kernel.solve_active_elastic``).

With zero bar compliance (c -> 0) all v_k are equal and the rigid model is recovered exactly.
"""

import math

import numpy as np

from bb_friction_ros.ball_screw.single_ball import LENGTH_SCALE_M


def axial_order(track_azimuth_rad):
    """Ball ids sorted by their position in the loaded track (k = 0 at the track start)."""
    return np.ascontiguousarray(np.argsort(track_azimuth_rad, kind="stable"), dtype=np.int64)


def bar_compliances(track_azimuth_sorted_rad, lead_m, elastic):
    """
    Axial compliances [m/N] of the shaft and nut bars between neighbouring balls.

    ``track_azimuth_sorted_rad``: track azimuths in axial order; ``elastic``: an
    ``ElasticBodies``.  The bar between balls k and k+1 is dz_k = p (phi_{k+1} - phi_k) / 2pi
    long.  Returns (c_shaft, c_nut), each (N-1,); c_nut = 0 for a nut held on its outer
    surface.
    """
    dz = lead_m / (2.0 * math.pi) * np.diff(track_azimuth_sorted_rad)
    c_shaft = dz / elastic.shaft_axial_rigidity_n
    c_nut = np.zeros_like(dz) if elastic.nut_support == "outer_surface" \
        else dz / elastic.nut_axial_rigidity_n
    return c_shaft, c_nut


def compatibility_terms(c_shaft, c_nut, axial_load_n, elastic, scale):
    """
    (comp_a, comp_b) of v_{k+1} - v_k = comp_a[k] - comp_b[k] C_k / scale, in LENGTH_SCALE_M.

    a_k = W (S_n c_n + L_s c_s), b_k = c_n + c_s (module docstring); C is carried by the
    solver in units of ``scale`` [N].
    """
    s_n = 1.0 if elastic.nut_support == "flange_at_track_start" else 0.0
    l_s = 1.0 if elastic.shaft_load_end == "track_start" else 0.0
    comp_a = axial_load_n * (s_n * c_nut + l_s * c_shaft) / LENGTH_SCALE_M
    comp_b = (c_nut + c_shaft) * scale / LENGTH_SCALE_M
    return np.ascontiguousarray(comp_a), np.ascontiguousarray(comp_b)


def elastic_load_path(track_azimuth_rad, lead_m, elastic, axial_load_n, scale):
    """Return the solver's ``elastic`` argument (order, comp_a, comp_b) at these positions."""
    order = axial_order(track_azimuth_rad)
    c_shaft, c_nut = bar_compliances(np.asarray(track_azimuth_rad)[order], lead_m, elastic)
    return (order,) + compatibility_terms(c_shaft, c_nut, axial_load_n, elastic, scale)
