"""
Compiled Newton kernel of the ball equilibrium for one B2B active set (numba).

Why compiled (measured, issue: whole-screw step <= 1 ms, 0.5 ms for 20x real-time replay):
the numpy evaluation of the 37 x 4 contacts costs 0.67 ms without and 1.1 ms with the
Jacobian, about 150 small numpy calls, almost all Python overhead.  A step needs at least two
evaluations, so numpy cannot reach the goal; the same arithmetic as scalar loops runs in tens
of microseconds.  Without numba the module still imports (the functions run as plain Python)
and ``HAVE_NUMBA`` is False: the solver then uses its numpy path.

The kernel is the numpy model of ``single_ball`` / ``b2b`` written per contact, plus two
changes of the solver, not of the model:

- The Jacobian includes the exact derivatives of the B2B friction direction.  The slip at a
  B2B contact is linear in the two balls' states, st = B_r x_r + B_f x_f
  (``B2BContactModel.linear_terms``), so d(st/|st|) = (I - e e^T) B / |st|.  This couples
  touching balls directly and gives quadratic convergence along long chains.
- The Newton system is block tridiagonal along each chain.  Block k holds ball k's six states
  and the force of the contact behind it; its rows are the ball's equations and the equal
  orbit rate across that contact.  It is bordered by the nut displacement u.  A block Thomas
  sweep per chain, with partial pivoting inside the 7 x 7 blocks, is followed by a Schur
  complement for u.  Cost per iteration is linear in N.

Derivatives with respect to u: u enters only through the nut arcs' z_3 shift, so each
derivative in u is -g cos(alpha) times the derivative in zeta.

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (54)-(61) (compiled form of ``solver``).

"""

import math

import numpy as np

from bb_friction_ros.ball_screw.single_ball import LENGTH_SCALE_M

from bb_friction_ros.compiled import HAVE_NUMBA  # noqa: F401  (re-exported: solver, tests)
from bb_friction_ros.compiled import back_substitute_block, bicubic_patch, bicubic_values
from bb_friction_ros.compiled import borrowed, carved, fused_multiply_add, gauss_solve
from bb_friction_ros.compiled import jit as _jit

_TINY = 1e-300
_TWO_PI = 2.0 * math.pi
_ANGLE_SIGN = (-1.0, 1.0, 1.0, -1.0)
_N_TRIAL = 12     # step halvings of the line search
# ``newton``'s "last iterate" guess: from norm r the next Newton iterate's norm is about
# c r^2; c measured 99 (median) to 287 (largest) over 9800 iterations of the 20 rev/s,
# 1.8 deg run with the norm between 1e-7 and 1e-5 (measured).  A wrong guess costs one
# evaluation; 500 keeps 1.7x margin over the largest c.
_LAST_FACTOR = 5e2
# The same guess for the first iteration from a warm start, where c is smaller: measured 20
# (median) to 68 (largest) over 397 steps of that run from the secant guess (2026-11-26).
# Only a sub-step (solver.substep_tolerance 1e-5) can meet its tolerance in one iteration
# from there (a norm of 4e-4 gives about 3e-6); the guess skips the Jacobian (7 us) and,
# when wrong, costs an evaluation without it (11 us), so it pays from a success rate of
# about 0.6: 50 is near the median c, not the largest.  It never changes an iterate.
_FIRST_FACTOR = 5e1


# --- The evaluation laid out for the vector units -------------------------------------------
#
# ``evaluate_lanes`` runs as passes over the balls, one contact type at a time, each pass a
# loop over the balls (the vector lanes) without calls or early exits, so that LLVM
# vectorises it: the contact geometry and loads (``_contact_loads``, compiled without
# fastmath: the loads are bit for bit the numpy model's), the slip kinematics and the map
# coordinates (``_contact_kinematics``), the friction map's patches (``_contact_maps``,
# scalar: a table lookup per contact, which the vectoriser would do with gathers, slow on
# this CPU), the forces and moments (``_contact_forces``) and the Jacobian
# (``_contact_jacobian``).  An open contact (delta <= 0) runs through every pass with q = 0
# and finite normals and adds exact zeros, as the scalar loop that skipped it did.
#
# The work arrays are flat, one row of _CHUNK lanes per quantity (and contact type), balls
# taken _CHUNK at a time: with rows a compile-time constant apart, LLVM sees that the rows
# of one array never overlap, so a pass needs no run-time alias checks (with the rows a
# run-time N apart it needed more than its limit allows and stayed scalar, measured).

_CHUNK = 64         # balls per pass (lanes); N = 37 is one chunk
_LANE_PAD = 8       # the passes' lanes are padded to a multiple of this (the vector width)
# Rows of ev (contact type k, row r: ev[(k * 6 + r) * _CHUNK + lane]): the contact.
_NX, _NZ, _DIST, _Q, _SQ, _POS = 0, 1, 2, 3, 4, 5
# Rows of ek (the same layout): the ellipse, slip, spin and map coordinates.
_A, _AS, _RX, _RY, _RHO, _S, _W, _SX, _SY = 0, 1, 2, 3, 4, 5, 6, 7, 8
# Rows of em: the map's fx, fy, m, p (0..3), their t- (4..6) and h-derivatives (8..10).
_VAL = 0
_DVT = 4
_DVH = 8
# Rows of acc (per ball: acc[row * _CHUNK + lane]): terms 0..8, then per column j of the
# Jacobian (j = 0..6) jac[r, j] at 9 + 7 j + r and dax[j] at 9 + 7 j + 6.  Rows of pco:
# per contact type k its loss (2 k) and axial force (2 k + 1).
_ACC_JAC = 9
_ACC_ROWS = 58
# One work array: ev (6 rows), ek (9), em (12) per contact type, acc, pco (8).  Each pass
# writes other arrays than it reads (else LLVM must check at run time whether a row it
# writes is one it reads, and gave up: measured).
# The passes' inputs are copied into xin first: rows x[:, j] (j = 0..5), the nut
# displacement u + u_ball (6), the arc centres' xi (7 + k) and zeta (11 + k): a pass that
# read x or the centres in place did not vectorise ("unsafe indirect dependence").
_XIN_U, _XIN_CX, _XIN_CZ = 6, 7, 11
_EV_BLOCK = 6 * _CHUNK
_EK_BLOCK = 9 * _CHUNK
_EM_BLOCK = 12 * _CHUNK
_EK_OFF = 4 * _EV_BLOCK
_EM_OFF = _EK_OFF + 4 * _EK_BLOCK
_ACC_OFF = _EM_OFF + 4 * _EM_BLOCK
_PCO_OFF = _ACC_OFF + _ACC_ROWS * _CHUNK
_XIN_OFF = _PCO_OFF + 8 * _CHUNK
WORK_SIZE = _XIN_OFF + 15 * _CHUNK

# atan2 as a polynomial the vectoriser can inline (libm's atan2 is a call per contact, and
# numba has no vector math library here: SVML is not operational).  Cephes' atan: on
# [0, 0.66] z + z^3 P(z^2) / Q(z^2), above that pi/4 + atan((z - 1) / (z + 1)); the other
# octants by symmetry.  Against libm over all quadrants and ratios 1e-8..1e8: at most 2 ulp
# of the result, so at most 4.5e-16 rad (tested in test_kernel_lanes).
_AT_P = (-8.750608600031904122785e-01, -1.615753718733365076637e+01,
         -7.500855792314704667340e+01, -1.228866684490136173410e+02,
         -6.485021904942025371773e+01)
_AT_Q = (2.485846490142306297962e+01, 1.650270098316988542046e+02,
         4.328810604912902668951e+02, 4.853903996359136964868e+02,
         1.945506571482613964425e+02)
_AT_MOREBITS = 6.123233995736765886130e-17
_HALF_PI = 0.5 * math.pi
_QUARTER_PI = 0.25 * math.pi


@_jit
def atan2_poly(y, x):
    """atan2(y, x) [rad] without a libm call, within 2 ulp of it (vectorisable)."""
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    # z = num / den; above 0.66 the reduced argument (z - 1) / (z + 1), written with one
    # division instead of two (divisions bound the kinematics pass: measured).
    red = num > 0.66 * den
    top = num - den if red else num
    bottom = num + den if red else den
    zz = top / bottom if bottom > 0.0 else 0.0
    z2 = zz * zz
    p = (((_AT_P[0] * z2 + _AT_P[1]) * z2 + _AT_P[2]) * z2 + _AT_P[3]) * z2 + _AT_P[4]
    q = ((((z2 + _AT_Q[0]) * z2 + _AT_Q[1]) * z2 + _AT_Q[2]) * z2 + _AT_Q[3]) * z2 + _AT_Q[4]
    r = zz * (z2 * p / q) + zz
    r = _QUARTER_PI + (r + 0.5 * _AT_MOREBITS) if red else r
    r = _HALF_PI - r + _AT_MOREBITS if swap else r
    r = math.pi - r if x < 0.0 else r
    return -r if y < 0.0 else r


# sin and cos as polynomials the vectoriser can inline, for the balls' theta(phi) and arc
# centres (``_theta_centres_into``): libm's are a call per value, 111 calls a step at N = 37
# (measured with perf: 3.4 % of a warm step).  fdlibm's (Sun, 1993): the argument reduced
# by pi/2 in three 33-bit parts (``__ieee754_rem_pio2``'s medium case, all three rounds
# always taken, which only adds bits), then ``__kernel_sin`` / ``__kernel_cos`` on
# [-pi/4, pi/4] with the reduction's tail.  For |x| < _TRIG_LIMIT, where n * pio2_1 is exact
# (at most 53 bits); beyond it the caller takes libm.  Against libm over |x| <= 1e5 and near
# multiples of pi/2: at most 1 ulp (test_kernel_lanes).  Compiled without fastmath only: a
# reassociation would undo the reduction's compensated sums.
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_2T = 2.02226624879595063154e-21
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32
_ROUND_MAGIC = 6755399441055744.0          # 1.5 * 2^52: (v + it) - it rounds v to an integer
_QX_MAGIC = 1.5 * 2.0 ** 28                # rounds x / 4 to a multiple of 2^-24 (fdlibm's qx)
_TRIG_LIMIT = 2.0 ** 19 * _PIO2_1          # n < 2^19
_SIN_P = (-1.66666666666666324348e-01, 8.33333333332248946124e-03,
          -1.98412698298579493134e-04, 2.75573137070700676789e-06,
          -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_COS_P = (4.16666666666666019037e-02, -1.38888888888741095749e-03,
          2.48015872894767294178e-05, -2.75573143513906633035e-07,
          2.08757232129817482790e-09, -1.13596475577881948265e-11)


@_jit(exact=True, inline=True)
def sincos_poly(x):
    """(sin x, cos x) without a libm call, within 1 ulp of it for |x| < _TRIG_LIMIT."""
    fn = (x * _INV_PIO2 + _ROUND_MAGIC) - _ROUND_MAGIC
    r = x - fn * _PIO2_1
    t = r
    w = fn * _PIO2_2
    r = t - w
    w = fn * _PIO2_2T - ((t - r) - w)
    t = r
    w = fn * _PIO2_3
    r = t - w
    w = fn * _PIO2_3T - ((t - r) - w)
    y0 = r - w
    y1 = (r - y0) - w
    z = y0 * y0
    v = z * y0
    rs = _SIN_P[1] + z * (_SIN_P[2] + z * (_SIN_P[3] + z * (_SIN_P[4] + z * _SIN_P[5])))
    sn = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * _SIN_P[0])
    rc = z * (_COS_P[0] + z * (_COS_P[1] + z * (_COS_P[2] + z * (_COS_P[3] + z * (
        _COS_P[4] + z * _COS_P[5])))))
    # fdlibm's qx (x / 4 on a 2^-24 grid, so that 1 - qx is exact; 0 below 0.3), and the
    # quadrant as a swap and two signs: flat selects, which the vectoriser converts.
    ay = abs(y0)
    qx = (0.25 * ay + _QX_MAGIC) - _QX_MAGIC if ay >= 0.3 else 0.0
    cs = (1.0 - qx) - ((0.5 * z - qx) - (z * rc - y0 * y1))
    q = int(fn)
    odd = (q & 1) != 0
    s_out = (1.0 - (q & 2)) * (cs if odd else sn)
    c_out = (1.0 - ((q + 1) & 2)) * (sn if odd else cs)
    return s_out, c_out


# glibc's hypot (2.35 on; dbl-64 without FMA, the x86-64 build): a scaled sqrt plus one
# correction step.  Written out so that it vectorises; compiled without fastmath it rounds
# exactly as libm, which numpy's np.hypot calls, so the contact loads stay bit for bit the
# numpy model's (test_fast_solver; test_kernel_lanes against libm).
_HYPOT_LARGE = 2.0 ** 511
_HYPOT_TINY = 2.0 ** -511
_HYPOT_SCALE = 2.0 ** -600
_HYPOT_EPS = 2.0 ** -54


@_jit(exact=True)
def hypot_exact(x, y):
    """sqrt(x^2 + y^2) rounded as glibc's hypot (finite x, y), without a call."""
    ax = max(abs(x), abs(y))
    ay = min(abs(x), abs(y))
    tiny = ay < _HYPOT_TINY
    s = _HYPOT_SCALE if ax > _HYPOT_LARGE else (1.0 / _HYPOT_SCALE if tiny else 1.0)
    a = ax * s
    b = ay * s
    h = math.sqrt(a * a + b * b)
    if h <= 2.0 * b:
        d = h - b
        t1 = a * (2.0 * d - a)
        t2 = (d - 2.0 * (a - b)) * d
    else:
        d = h - a
        t1 = 2.0 * d * (a - 2.0 * b)
        t2 = (4.0 * d - b) * b + d * d
    h = (h - (t1 + t2) / (2.0 * h)) / s
    small = (ax >= ay / _HYPOT_EPS) if tiny else (ay <= ax * _HYPOT_EPS)
    return ax + ay if small else h


@_jit(exact=True)
def _contact_loads(xin, m, lam, ca, free, on_nut, k_load, ev):
    """Compute normals, distances and loads of balls 0..m-1 (numpy's rounding); open: q = 0."""
    for k in range(4):
        evk = ev[k * _EV_BLOCK:(k + 1) * _EV_BLOCK]
        cx = xin[(_XIN_CX + k) * _CHUNK:(_XIN_CX + k + 1) * _CHUNK]
        cz = xin[(_XIN_CZ + k) * _CHUNK:(_XIN_CZ + k + 1) * _CHUNK]
        g = on_nut[k]
        kl = k_load[k]
        for i in range(m):
            dxv = lam * xin[i] - cx[i]
            dzv = (lam * xin[_CHUNK + i] - cz[i]
                   - g * (lam * ca * xin[_XIN_U * _CHUNK + i]))
            dist = hypot_exact(dxv, dzv)
            delta = dist - free
            pos = delta > 0.0
            dpos = delta if pos else 0.0
            sq = math.sqrt(dpos)
            # An open contact keeps finite normals: every term it adds is then an exact zero.
            evk[_NX * _CHUNK + i] = dxv / dist if pos else 0.0
            evk[_NZ * _CHUNK + i] = dzv / dist if pos else 0.0
            evk[_DIST * _CHUNK + i] = dist if pos else 1.0
            evk[_Q * _CHUNK + i] = kl * dpos * sq
            evk[_SQ * _CHUNK + i] = sq
            evk[_POS * _CHUNK + i] = 1.0 if pos else 0.0


@_jit
def _contact_kinematics(xin, m, r_b, sa, ca, ell, sign, on_nut, k_load, k_axis, dtm, dhm,
                        ev, ek):
    """Contact ellipse, slip, spin and the friction map's coordinates (t, h) per contact."""
    for k in range(4):
        evk = ev[k * _EV_BLOCK:(k + 1) * _EV_BLOCK]
        ekk = ek[k * _EK_BLOCK:(k + 1) * _EK_BLOCK]
        gs = on_nut[k] * sign
        ka = k_axis[k]
        # a = k_axis q^(1/3) = k_axis k_load^(1/3) sqrt(delta): one cbrt per contact type.
        ka_kl = ka * np.cbrt(k_load[k])
        for i in range(m):
            nx = evk[_NX * _CHUNK + i]
            nz = evk[_NZ * _CHUNK + i]
            wb = xin[2 * _CHUNK + i]
            ox = xin[3 * _CHUNK + i]
            oy = xin[4 * _CHUNK + i]
            oz = xin[5 * _CHUNK + i]
            a = ka_kl * evk[_SQ * _CHUNK + i]
            a_s = max(a, ka * 1e-9)
            vx = r_b * (oy - gs * sa)
            vy = wb * ell + r_b * (oz * nx - ox * nz) - gs * (ell + r_b * ca * nx)
            w = ox * nx + oz * nz - gs * ca * nz
            rx = vx / a_s
            ry = vy / a_s
            rho = max(math.sqrt(rx * rx + ry * ry), _TINY)
            t = atan2_poly(rho, w)
            h = atan2_poly(ry, rx)
            ekk[_A * _CHUNK + i] = a
            ekk[_AS * _CHUNK + i] = a_s
            ekk[_RX * _CHUNK + i] = rx
            ekk[_RY * _CHUNK + i] = ry
            ekk[_RHO * _CHUNK + i] = rho
            ekk[_S * _CHUNK + i] = math.sqrt(rho * rho + w * w)
            ekk[_W * _CHUNK + i] = w
            # The map's cell coordinates, NaN-safe: t clamped to [0, pi]; h mod 2 pi for h in
            # (-pi, pi], as the modulo rounds it, without its fmod.
            t = t if t >= 0.0 else 0.0
            t = math.pi if t > math.pi else t
            ekk[_SX * _CHUNK + i] = t / dtm
            yy = (h + _TWO_PI if h < 0.0 else h) / dhm
            ekk[_SY * _CHUNK + i] = yy if yy >= 0.0 else 0.0


@_jit
def _contact_maps(coef_s, coef_n, m, n_pol, n_az, dtm, dhm, want_jac, ev, ek, em):
    """Bicubic patch of FrictionMapSphere at every loaded contact: values, t-, h-derivatives."""
    for k in range(4):
        evk = ev[k * _EV_BLOCK:(k + 1) * _EV_BLOCK]
        ekk = ek[k * _EK_BLOCK:(k + 1) * _EK_BLOCK]
        emk = em[k * _EM_BLOCK:(k + 1) * _EM_BLOCK]
        cf = coef_s if k < 2 else coef_n
        for i in range(m):
            if evk[_POS * _CHUNK + i] == 0.0:
                for r in range(12):
                    emk[(_VAL + r) * _CHUNK + i] = 0.0
                continue
            xx = ekk[_SX * _CHUNK + i]
            i0 = int(xx)
            if i0 > n_pol - 1:
                i0 = n_pol - 1
            sx = xx - i0
            yy = ekk[_SY * _CHUNK + i]
            j0 = int(yy)
            if j0 > n_az - 1:
                j0 = n_az - 1
            sy = yy - j0
            # cf read in place: a view of the cell per contact cost an incref and a decref
            # (atomic) each, a fifth of the step with the other views.
            if want_jac:
                bicubic_patch(cf, i0 * n_az + j0, sx, sy, dtm, dhm, emk, _VAL * _CHUNK + i,
                              _CHUNK)
            else:
                bicubic_values(cf, i0 * n_az + j0, sx, sy, emk, _VAL * _CHUNK + i, _CHUNK)


# The per-ball sums of the contact passes start from the first contact type (k = 0) instead of
# from rows zeroed before: the zeroing was about 100 memset calls a warm step.  0.0 + term
# rounds as the sum from a zeroed row did (bit for bit).  The row is read whatever k is (an
# argument here): read only for k > 0, the passes stopped vectorising (42 against 30 us a
# step: measured).
@_jit(inline=True)
def _kept(value, k):
    """``value`` from the second contact type on, 0.0 for the first (k = 0)."""
    return value if k > 0 else 0.0


@_jit
def _contact_forces(m, r_b, sa, ca, ell, mu, r_gear, on_nut, ev, ek, em, acc, pco):
    """Sum the contacts' forces, moments, loss, nut torque and axial force per ball."""
    for k in range(4):
        evk = ev[k * _EV_BLOCK:(k + 1) * _EV_BLOCK]
        ekk = ek[k * _EK_BLOCK:(k + 1) * _EK_BLOCK]
        emk = em[k * _EM_BLOCK:(k + 1) * _EM_BLOCK]
        pcok = pco[k * 2 * _CHUNK:(k + 1) * 2 * _CHUNK]
        g = on_nut[k]
        for i in range(m):
            pos = evk[_POS * _CHUNK + i] != 0.0
            nx = evk[_NX * _CHUNK + i]
            nz = evk[_NZ * _CHUNK + i]
            q = evk[_Q * _CHUNK + i]
            a = ekk[_A * _CHUNK + i]
            fx = emk[_VAL * _CHUNK + i]
            fy = emk[(_VAL + 1) * _CHUNK + i]
            mm = emk[(_VAL + 2) * _CHUNK + i]
            pp = emk[(_VAL + 3) * _CHUNK + i]
            p_ = mu * q
            am = a * mm
            f0 = -q * nx + p_ * fx * nz
            f1 = p_ * fy
            f2 = -q * nz - p_ * fx * nx
            m0 = p_ * (-r_b * fy * nz + am * nx)
            m1 = p_ * r_b * fx
            m2 = p_ * (r_b * fy * nx + am * nz)
            loss_c = p_ * a * ekk[_S * _CHUNK + i] * pp
            torque_c = g * (f0 * (r_b * sa * nz) + f1 * (ell - r_gear * sa + r_b * ca * nx)
                            + f2 * (-r_gear * ca - r_b * sa * nx) + p_ * am * nz * ca)
            axial_c = g * (f1 * sa + f2 * ca)
            pcok[i] = loss_c if pos else 0.0
            pcok[_CHUNK + i] = axial_c if pos else 0.0
            acc[i] = _kept(acc[i], k) + (f0 if pos else 0.0)
            acc[_CHUNK + i] = _kept(acc[_CHUNK + i], k) + (f1 if pos else 0.0)
            acc[2 * _CHUNK + i] = _kept(acc[2 * _CHUNK + i], k) + (f2 if pos else 0.0)
            acc[3 * _CHUNK + i] = _kept(acc[3 * _CHUNK + i], k) + (m0 if pos else 0.0)
            acc[4 * _CHUNK + i] = _kept(acc[4 * _CHUNK + i], k) + (m1 if pos else 0.0)
            acc[5 * _CHUNK + i] = _kept(acc[5 * _CHUNK + i], k) + (m2 if pos else 0.0)
            acc[6 * _CHUNK + i] = _kept(acc[6 * _CHUNK + i], k) + (loss_c if pos else 0.0)
            acc[7 * _CHUNK + i] = _kept(acc[7 * _CHUNK + i], k) + (torque_c if pos else 0.0)
            acc[8 * _CHUNK + i] = _kept(acc[8 * _CHUNK + i], k) + (axial_c if pos else 0.0)


@_jit
def _contact_jacobian(xin, m, lam, r_b, sa, ca, ell, mu, sign, on_nut, k_load, inv_s,
                      inv_rs, ev, ek, em, acc):
    """
    Sum the contacts' derivatives of the scaled residual and axial force per ball.

    The six state columns written out (a loop over them inside the loop over the balls kept
    that loop from being the innermost one, so it stayed scalar: measured), each as the
    scalar loop's expression with the terms of the rate columns that are exact zeros
    (dq = da = dn = 0) left out.
    """
    for k in range(4):
        evk = ev[k * _EV_BLOCK:(k + 1) * _EV_BLOCK]
        ekk = ek[k * _EK_BLOCK:(k + 1) * _EK_BLOCK]
        emk = em[k * _EM_BLOCK:(k + 1) * _EM_BLOCK]
        g = on_nut[k]
        gs = g * sign
        kl = k_load[k]
        cu = -g * ca
        for i in range(m):
            pos = evk[_POS * _CHUNK + i] != 0.0
            nx = evk[_NX * _CHUNK + i]
            nz = evk[_NZ * _CHUNK + i]
            q = evk[_Q * _CHUNK + i]
            sq = evk[_SQ * _CHUNK + i]
            a = ekk[_A * _CHUNK + i]
            rx = ekk[_RX * _CHUNK + i]
            ry = ekk[_RY * _CHUNK + i]
            rho = ekk[_RHO * _CHUNK + i]
            s = ekk[_S * _CHUNK + i]
            w = ekk[_W * _CHUNK + i]
            fx = emk[_VAL * _CHUNK + i]
            fy = emk[(_VAL + 1) * _CHUNK + i]
            mm = emk[(_VAL + 2) * _CHUNK + i]
            t_fx = emk[_DVT * _CHUNK + i]
            t_fy = emk[(_DVT + 1) * _CHUNK + i]
            t_mm = emk[(_DVT + 2) * _CHUNK + i]
            h_fx = emk[_DVH * _CHUNK + i]
            h_fy = emk[(_DVH + 1) * _CHUNK + i]
            h_mm = emk[(_DVH + 2) * _CHUNK + i]
            ox = xin[3 * _CHUNK + i]
            oz = xin[5 * _CHUNK + i]
            p_ = mu * q
            am = a * mm
            a_over_3q = a / (3.0 * q) if q > 0.0 else 0.0
            inv_dist = 1.0 / evk[_DIST * _CHUNK + i]
            inv_as = 1.0 / ekk[_AS * _CHUNK + i]
            inv_ss = 1.0 / (s * s)
            inv_rr = 1.0 / (rho * rho)
            # Column xi: through the normal, the load and the ellipse.
            dn_l = nx * lam
            dnx = (lam - nx * dn_l) * inv_dist
            dnz = -nz * dn_l * inv_dist
            dq = 1.5 * kl * sq * dn_l
            da = a_over_3q * dq
            dvy = r_b * (oz - gs * ca) * dnx - r_b * ox * dnz
            dw = ox * dnx + (oz - gs * ca) * dnz
            drx = -rx * da * inv_as
            dry = (dvy - ry * da) * inv_as
            dt = (w * (rx * drx + ry * dry) / rho - rho * dw) * inv_ss
            dh = (rx * dry - ry * drx) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dp_ = mu * dq
            dam = mm * da + a * dmm
            d_fx = -dq * nx - q * dnx + dp_ * fx * nz + p_ * nz * dfx + p_ * fx * dnz
            d_fy = dp_ * fy + p_ * dfy
            d_fz = -dq * nz - q * dnz - dp_ * fx * nx - p_ * nx * dfx - p_ * fx * dnx
            d_mx = (dp_ * (-r_b * fy * nz + am * nx)
                    + p_ * (-r_b * (dfy * nz + fy * dnz) + dam * nx + am * dnx))
            d_my = r_b * (dp_ * fx + p_ * dfx)
            d_mz = (dp_ * (r_b * fy * nx + am * nz)
                    + p_ * (r_b * (dfy * nx + fy * dnx) + dam * nz + am * dnz))
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[9 * _CHUNK + i] = _kept(acc[9 * _CHUNK + i], k) + d0
            acc[10 * _CHUNK + i] = _kept(acc[10 * _CHUNK + i], k) + d1
            acc[11 * _CHUNK + i] = _kept(acc[11 * _CHUNK + i], k) + d2
            acc[12 * _CHUNK + i] = _kept(acc[12 * _CHUNK + i], k) + d3
            acc[13 * _CHUNK + i] = _kept(acc[13 * _CHUNK + i], k) + d4
            acc[14 * _CHUNK + i] = _kept(acc[14 * _CHUNK + i], k) + d5
            acc[15 * _CHUNK + i] = _kept(acc[15 * _CHUNK + i], k) + d_ax
            # Column zeta (and u).
            dn_l = nz * lam
            dnx = -nx * dn_l * inv_dist
            dnz = (lam - nz * dn_l) * inv_dist
            dq = 1.5 * kl * sq * dn_l
            da = a_over_3q * dq
            dvy = r_b * (oz - gs * ca) * dnx - r_b * ox * dnz
            dw = ox * dnx + (oz - gs * ca) * dnz
            drx = -rx * da * inv_as
            dry = (dvy - ry * da) * inv_as
            dt = (w * (rx * drx + ry * dry) / rho - rho * dw) * inv_ss
            dh = (rx * dry - ry * drx) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dp_ = mu * dq
            dam = mm * da + a * dmm
            d_fx = -dq * nx - q * dnx + dp_ * fx * nz + p_ * nz * dfx + p_ * fx * dnz
            d_fy = dp_ * fy + p_ * dfy
            d_fz = -dq * nz - q * dnz - dp_ * fx * nx - p_ * nx * dfx - p_ * fx * dnx
            d_mx = (dp_ * (-r_b * fy * nz + am * nx)
                    + p_ * (-r_b * (dfy * nz + fy * dnz) + dam * nx + am * dnx))
            d_my = r_b * (dp_ * fx + p_ * dfx)
            d_mz = (dp_ * (r_b * fy * nx + am * nz)
                    + p_ * (r_b * (dfy * nx + fy * dnx) + dam * nz + am * dnz))
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[16 * _CHUNK + i] = _kept(acc[16 * _CHUNK + i], k) + d0
            acc[17 * _CHUNK + i] = _kept(acc[17 * _CHUNK + i], k) + d1
            acc[18 * _CHUNK + i] = _kept(acc[18 * _CHUNK + i], k) + d2
            acc[19 * _CHUNK + i] = _kept(acc[19 * _CHUNK + i], k) + d3
            acc[20 * _CHUNK + i] = _kept(acc[20 * _CHUNK + i], k) + d4
            acc[21 * _CHUNK + i] = _kept(acc[21 * _CHUNK + i], k) + d5
            acc[22 * _CHUNK + i] = _kept(acc[22 * _CHUNK + i], k) + d_ax
            # u enters through the nut arcs' zeta shift (module docstring).
            acc[51 * _CHUNK + i] = _kept(acc[51 * _CHUNK + i], k) + (cu * d0)
            acc[52 * _CHUNK + i] = _kept(acc[52 * _CHUNK + i], k) + (cu * d1)
            acc[53 * _CHUNK + i] = _kept(acc[53 * _CHUNK + i], k) + (cu * d2)
            acc[54 * _CHUNK + i] = _kept(acc[54 * _CHUNK + i], k) + (cu * d3)
            acc[55 * _CHUNK + i] = _kept(acc[55 * _CHUNK + i], k) + (cu * d4)
            acc[56 * _CHUNK + i] = _kept(acc[56 * _CHUNK + i], k) + (cu * d5)
            acc[57 * _CHUNK + i] = _kept(acc[57 * _CHUNK + i], k) + (cu * d_ax)
            # Columns w_B, Omega_x, Omega_y, Omega_z: the velocities only (dq = da = 0).
            dry = ell * inv_as
            dt = w * (ry * dry) / rho * inv_ss
            dh = (rx * dry) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dam = a * dmm
            d_fx = p_ * nz * dfx
            d_fy = p_ * dfy
            d_fz = -p_ * nx * dfx
            d_mx = p_ * (-r_b * dfy * nz + dam * nx)
            d_my = r_b * p_ * dfx
            d_mz = p_ * (r_b * dfy * nx + dam * nz)
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[23 * _CHUNK + i] = _kept(acc[23 * _CHUNK + i], k) + d0
            acc[24 * _CHUNK + i] = _kept(acc[24 * _CHUNK + i], k) + d1
            acc[25 * _CHUNK + i] = _kept(acc[25 * _CHUNK + i], k) + d2
            acc[26 * _CHUNK + i] = _kept(acc[26 * _CHUNK + i], k) + d3
            acc[27 * _CHUNK + i] = _kept(acc[27 * _CHUNK + i], k) + d4
            acc[28 * _CHUNK + i] = _kept(acc[28 * _CHUNK + i], k) + d5
            acc[29 * _CHUNK + i] = _kept(acc[29 * _CHUNK + i], k) + d_ax
            dry = -r_b * nz * inv_as
            dt = (w * (ry * dry) / rho - rho * nx) * inv_ss
            dh = (rx * dry) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dam = a * dmm
            d_fx = p_ * nz * dfx
            d_fy = p_ * dfy
            d_fz = -p_ * nx * dfx
            d_mx = p_ * (-r_b * dfy * nz + dam * nx)
            d_my = r_b * p_ * dfx
            d_mz = p_ * (r_b * dfy * nx + dam * nz)
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[30 * _CHUNK + i] = _kept(acc[30 * _CHUNK + i], k) + d0
            acc[31 * _CHUNK + i] = _kept(acc[31 * _CHUNK + i], k) + d1
            acc[32 * _CHUNK + i] = _kept(acc[32 * _CHUNK + i], k) + d2
            acc[33 * _CHUNK + i] = _kept(acc[33 * _CHUNK + i], k) + d3
            acc[34 * _CHUNK + i] = _kept(acc[34 * _CHUNK + i], k) + d4
            acc[35 * _CHUNK + i] = _kept(acc[35 * _CHUNK + i], k) + d5
            acc[36 * _CHUNK + i] = _kept(acc[36 * _CHUNK + i], k) + d_ax
            drx = r_b * inv_as
            dt = w * (rx * drx) / rho * inv_ss
            dh = (-ry * drx) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dam = a * dmm
            d_fx = p_ * nz * dfx
            d_fy = p_ * dfy
            d_fz = -p_ * nx * dfx
            d_mx = p_ * (-r_b * dfy * nz + dam * nx)
            d_my = r_b * p_ * dfx
            d_mz = p_ * (r_b * dfy * nx + dam * nz)
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[37 * _CHUNK + i] = _kept(acc[37 * _CHUNK + i], k) + d0
            acc[38 * _CHUNK + i] = _kept(acc[38 * _CHUNK + i], k) + d1
            acc[39 * _CHUNK + i] = _kept(acc[39 * _CHUNK + i], k) + d2
            acc[40 * _CHUNK + i] = _kept(acc[40 * _CHUNK + i], k) + d3
            acc[41 * _CHUNK + i] = _kept(acc[41 * _CHUNK + i], k) + d4
            acc[42 * _CHUNK + i] = _kept(acc[42 * _CHUNK + i], k) + d5
            acc[43 * _CHUNK + i] = _kept(acc[43 * _CHUNK + i], k) + d_ax
            dry = r_b * nx * inv_as
            dt = (w * (ry * dry) / rho - rho * nz) * inv_ss
            dh = (rx * dry) * inv_rr
            dfx = t_fx * dt + h_fx * dh
            dfy = t_fy * dt + h_fy * dh
            dmm = t_mm * dt + h_mm * dh
            dam = a * dmm
            d_fx = p_ * nz * dfx
            d_fy = p_ * dfy
            d_fz = -p_ * nx * dfx
            d_mx = p_ * (-r_b * dfy * nz + dam * nx)
            d_my = r_b * p_ * dfx
            d_mz = p_ * (r_b * dfy * nx + dam * nz)
            d0 = d_fx * inv_s if pos else 0.0
            d1 = d_fy * inv_s if pos else 0.0
            d2 = d_fz * inv_s if pos else 0.0
            d3 = d_mx * inv_rs if pos else 0.0
            d4 = d_my * inv_rs if pos else 0.0
            d5 = d_mz * inv_rs if pos else 0.0
            d_ax = g * (d_fy * sa + d_fz * ca) * inv_s if pos else 0.0
            acc[44 * _CHUNK + i] = _kept(acc[44 * _CHUNK + i], k) + d0
            acc[45 * _CHUNK + i] = _kept(acc[45 * _CHUNK + i], k) + d1
            acc[46 * _CHUNK + i] = _kept(acc[46 * _CHUNK + i], k) + d2
            acc[47 * _CHUNK + i] = _kept(acc[47 * _CHUNK + i], k) + d3
            acc[48 * _CHUNK + i] = _kept(acc[48 * _CHUNK + i], k) + d4
            acc[49 * _CHUNK + i] = _kept(acc[49 * _CHUNK + i], k) + d5
            acc[50 * _CHUNK + i] = _kept(acc[50 * _CHUNK + i], k) + d_ax


@_jit
def evaluate_balls(x, u, u_ball, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                   grid, scale, want_jac, res, jac, dax, terms, per_contact):
    """
    Ball-groove residuals of all balls (``single_ball.BallGrooveModel.evaluate``).

    ``evaluate_lanes`` with work arrays of its own (``newton`` passes its preallocated ones).
    Returns the summed axial force [N].
    """
    return evaluate_lanes(x, u, u_ball, centres, sign, cst, k_load, k_axis, on_nut, coef_s,
                          coef_n, grid, scale, want_jac, res, jac, dax, terms, per_contact,
                          np.empty(WORK_SIZE))


@_jit
def evaluate_lanes(x, u, u_ball, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                   grid, scale, want_jac, res, jac, dax, terms, per_contact, work):
    """
    Ball-groove residuals of all balls, the balls across the vector lanes.

    The nut displacement at ball i is u + u_ball[i] (u_ball = 0 for a rigid nut and shaft;
    the elastic load distribution gives each ball its own).
    cst = (lambda, R_B, cos a, sin a, l, mu, free distance, r_gear); grid = (n_polar,
    n_azimuth, dt, dh).  Writes res (N, 6) = [force, moment / R_B] / scale, jac (N, 6, 7),
    dax (N, 7) = d(axial) / scale (only with ``want_jac``; jac and dax of length 0 leave
    them in work's acc rows instead, N <= _CHUNK: ``newton_direction``); terms (N, 10) =
    force (3), moment (3), loss, nut torque, axial force, 0; per_contact (N, 4, 3) = load,
    loss and the contact angle, which only ``contact_angles`` writes, on demand (no output
    of the model reads it: 148 atan2 per solve at N = 37).  work (WORK_SIZE,): the passes'
    work arrays (see above).  Returns the summed axial force [N].
    """
    lam, r_b, ca, sa, ell, mu, free, r_gear = (cst[0], cst[1], cst[2], cst[3], cst[4],
                                               cst[5], cst[6], cst[7])
    n_pol, n_az = int(grid[0]), int(grid[1])
    dtm, dhm = grid[2], grid[3]
    inv_s = 1.0 / scale
    inv_rs = 1.0 / (r_b * scale)
    axial_sum = 0.0
    n = x.shape[0]
    ev = work[:_EK_OFF]
    ek = work[_EK_OFF:_EM_OFF]
    em = work[_EM_OFF:_ACC_OFF]
    acc = work[_ACC_OFF:_PCO_OFF]
    pco = work[_PCO_OFF:_XIN_OFF]
    xin = work[_XIN_OFF:]
    for c0 in range(0, n, _CHUNK):
        m = min(_CHUNK, n - c0)
        # The passes run over the lanes up to a multiple of the vector width: a loop of 37
        # lanes ran 32 vectorised and the last 5 as scalar code, which cost as much as 16
        # more lanes (measured: an evaluation with the Jacobian took 10.5 us at 37 balls,
        # 8.9 us at 40).  The extra lanes hold a ball at the origin with its arc centres
        # there too: every contact open, so they add nothing and nothing reads them.
        mp = min(_CHUNK, (m + _LANE_PAD - 1) // _LANE_PAD * _LANE_PAD)
        for i in range(mp):
            b = c0 + i
            real = i < m
            bb = b if real else 0
            for j in range(6):
                xin[j * _CHUNK + i] = x[bb, j] if real else 0.0
            xin[_XIN_U * _CHUNK + i] = u + u_ball[bb] if real else 0.0
            for k in range(4):
                xin[(_XIN_CX + k) * _CHUNK + i] = centres[bb, k, 0] if real else 0.0
                xin[(_XIN_CZ + k) * _CHUNK + i] = centres[bb, k, 1] if real else 0.0
        _contact_loads(xin, mp, lam, ca, free, on_nut, k_load, ev)
        _contact_kinematics(xin, mp, r_b, sa, ca, ell, sign, on_nut, k_load, k_axis, dtm,
                            dhm, ev, ek)
        _contact_maps(coef_s, coef_n, mp, n_pol, n_az, dtm, dhm, want_jac, ev, ek, em)
        _contact_forces(mp, r_b, sa, ca, ell, mu, r_gear, on_nut, ev, ek, em, acc, pco)
        if want_jac:
            _contact_jacobian(xin, mp, lam, r_b, sa, ca, ell, mu, sign, on_nut, k_load,
                              inv_s, inv_rs, ev, ek, em, acc)
        for i in range(m):
            b = c0 + i
            for k in range(4):
                axial_sum += pco[(2 * k + 1) * _CHUNK + i]
                per_contact[b, k, 0] = ev[(6 * k + _Q) * _CHUNK + i]
                per_contact[b, k, 1] = pco[2 * k * _CHUNK + i]
            for r in range(9):
                terms[b, r] = acc[r * _CHUNK + i]
            terms[b, 9] = 0.0
            for r in range(3):
                res[b, r] = acc[r * _CHUNK + i] * inv_s
                res[b, 3 + r] = acc[(3 + r) * _CHUNK + i] * inv_rs
            if want_jac and jac.shape[0] > 0:
                for j in range(7):
                    for r in range(6):
                        jac[b, r, j] = acc[(_ACC_JAC + 7 * j + r) * _CHUNK + i]
                    dax[b, j] = acc[(_ACC_JAC + 7 * j + 6) * _CHUNK + i]
    return axial_sum


@_jit
def contact_angles(x, u, u_ball, centres, cst, on_nut, per_contact):
    """
    Contact angle of every contact into per_contact[..., 2] (``evaluate``'s "angle").

    The normal of ``evaluate_balls`` at the states x and nut displacements u + u_ball[i].
    """
    lam, ca = cst[0], cst[2]
    for i in range(x.shape[0]):
        ui = u + u_ball[i]
        for k in range(4):
            g = on_nut[k]
            dxv = lam * x[i, 0] - centres[i, k, 0]
            dzv = lam * x[i, 1] - centres[i, k, 1] - g * (lam * ca * ui)
            dist = math.hypot(dxv, dzv)
            per_contact[i, k, 2] = math.atan2(_ANGLE_SIGN[k] * (dzv / dist), abs(dxv / dist))


@_jit
def b2b_terms(x, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, want_jac, g_r, g_f, speed,
              dgr_r, dgr_f, dgf_r, dgf_f):
    """
    Unit-force B2B terms g_rear, g_front (K, 6), slip speed (K,) and their state derivatives.

    dg{r,f}_{r,f}[c] (6, 6): derivative of g_rear / g_front with respect to the rear / front
    ball's six states.
    """
    b2b_terms_into(x, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, want_jac, g_r, g_f, speed,
                   dgr_r, dgr_f, dgf_r, dgf_f, np.empty(B2B_WORK_SIZE))


# Work of b2b_terms_into: the slip (3), its direction (3), the projector (3 x 3) and its
# products with B_r and B_f (3 x 6 each).
B2B_WORK_SIZE = 51


@_jit
def b2b_terms_into(x, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, want_jac, g_r, g_f, speed,
                   dgr_r, dgr_f, dgf_r, dgf_f, bw):
    """``b2b_terms`` with its work arrays carved from bw (B2B_WORK_SIZE,): no allocation."""
    st = bw[0:3]
    un = bw[3:6]
    pn = carved(bw, 6, (3, 3))
    dr = carved(bw, 15, (3, 6))
    df = carved(bw, 33, (3, 6))
    for c in range(rear.shape[0]):
        r = rear[c]
        f = front[c]
        for a in range(3):
            acc = 0.0
            for j in range(6):
                acc += b_r[a, j] * x[r, j] + b_f[a, j] * x[f, j]
            st[a] = acc
        sp = math.sqrt(st[0] * st[0] + st[1] * st[1] + st[2] * st[2])
        speed[c] = sp
        inv = 1.0 / max(sp, _TINY)
        for a in range(3):
            un[a] = st[a] * inv
        for r6 in range(6):
            gr = c_r[r6]
            gf = c_f[r6]
            for a in range(3):
                gr += k_r[r6, a] * un[a]
                gf += k_f[r6, a] * un[a]
            g_r[c, r6] = gr
            g_f[c, r6] = gf
        if not want_jac:
            continue
        for a in range(3):
            for b in range(3):
                pn[a, b] = ((1.0 if a == b else 0.0) - un[a] * un[b]) * inv
        for a in range(3):
            for j in range(6):
                acc_r = 0.0
                acc_f = 0.0
                for b in range(3):
                    acc_r += pn[a, b] * b_r[b, j]
                    acc_f += pn[a, b] * b_f[b, j]
                dr[a, j] = acc_r
                df[a, j] = acc_f
        for r6 in range(6):
            for j in range(6):
                s1 = s2 = s3 = s4 = 0.0
                for a in range(3):
                    s1 += k_r[r6, a] * dr[a, j]
                    s2 += k_r[r6, a] * df[a, j]
                    s3 += k_f[r6, a] * dr[a, j]
                    s4 += k_f[r6, a] * df[a, j]
                dgr_r[c, r6, j] = s1
                dgr_f[c, r6, j] = s2
                dgf_r[c, r6, j] = s3
                dgf_f[c, r6, j] = s4


@_jit
def chains(n, rear, front):
    """Order balls chain by chain, rear first: (rear_of, front_of, seq, starts, ok)."""
    rear_of = np.empty(n, dtype=np.int64)
    front_of = np.empty(n, dtype=np.int64)
    seq = np.empty(n, dtype=np.int64)
    starts = np.empty(n + 1, dtype=np.int64)
    nc, ok = chains_into(n, rear, front, rear_of, front_of, seq, starts)
    return rear_of, front_of, seq, starts[:nc + 1], ok


@_jit
def chains_into(n, rear, front, rear_of, front_of, seq, starts):
    """``chains`` into the given arrays; returns (number of chains, ok)."""
    for b in range(n):
        rear_of[b] = -1
        front_of[b] = -1
    for c in range(rear.shape[0]):
        rear_of[rear[c]] = c
        front_of[front[c]] = c
    nc = 0
    pos = 0
    for b in range(n):
        if front_of[b] != -1:
            continue
        starts[nc] = pos
        nc += 1
        cur = b
        while pos < n:
            seq[pos] = cur
            pos += 1
            c = rear_of[cur]
            if c < 0:
                break
            cur = front[c]
    starts[nc] = pos
    return nc, pos == n


# --- The free balls' Newton blocks, solved across the vector lanes ---------------------------
#
# A ball in no B2B chain has a 6 x 6 block of its own (``newton_direction``): at N = 37 most
# balls are free.  ``solve_free_blocks`` solves them _CHUNK at a time, one ball per lane,
# by the elimination of ``compiled.gauss_solve`` with the same partial pivoting in each lane
# (the pivot row chosen per lane, the swaps as selects).  A lane whose pivot is zero or not
# finite is solved again by ``gauss_solve`` itself (its Levenberg-Marquardt retry).
# fw (FB_ROWS * _CHUNK,), flat, rows _CHUNK apart: row 8 r + j of a lane's matrix row r: the
# block (j < 6), then the two right-hand sides (the residual, the derivative in u); then
# the two solutions per row r (rows _FB_OUT + 2 r, + 1) and the singular flag.

_FB_OUT = 48
_FB_BAD = _FB_OUT + 12
FB_ROWS = _FB_BAD + 1


# --- generated by tools/gen_block_solves.py: edit the generator, not this function ---


@_jit
def _lanes_gauss6(fw, m):
    """
    Solve the lanes' 6 x 6 systems with two right-hand sides each.

    fw: flat, rows _CHUNK apart.  Row 8 r + j of lane i holds its matrix row r
    (j < 6) and right-hand sides (j = 6, 7); the solutions are written to rows
    _FB_OUT + 2 r + (j - 6), and 1.0 to row _FB_BAD where a pivot was zero or not
    finite.  Generated by tools/gen_block_solves.py (why: there).
    """
    for i in range(m):
        a00, a01, a02, a03, a04, a05, a06, a07 = (
            fw[0 * _CHUNK + i], fw[1 * _CHUNK + i], fw[2 * _CHUNK + i], fw[3 * _CHUNK + i],
            fw[4 * _CHUNK + i], fw[5 * _CHUNK + i], fw[6 * _CHUNK + i], fw[7 * _CHUNK + i])
        a10, a11, a12, a13, a14, a15, a16, a17 = (
            fw[8 * _CHUNK + i], fw[9 * _CHUNK + i], fw[10 * _CHUNK + i], fw[11 * _CHUNK + i],
            fw[12 * _CHUNK + i], fw[13 * _CHUNK + i], fw[14 * _CHUNK + i], fw[15 * _CHUNK + i])
        a20, a21, a22, a23, a24, a25, a26, a27 = (
            fw[16 * _CHUNK + i], fw[17 * _CHUNK + i], fw[18 * _CHUNK + i], fw[19 * _CHUNK + i],
            fw[20 * _CHUNK + i], fw[21 * _CHUNK + i], fw[22 * _CHUNK + i], fw[23 * _CHUNK + i])
        a30, a31, a32, a33, a34, a35, a36, a37 = (
            fw[24 * _CHUNK + i], fw[25 * _CHUNK + i], fw[26 * _CHUNK + i], fw[27 * _CHUNK + i],
            fw[28 * _CHUNK + i], fw[29 * _CHUNK + i], fw[30 * _CHUNK + i], fw[31 * _CHUNK + i])
        a40, a41, a42, a43, a44, a45, a46, a47 = (
            fw[32 * _CHUNK + i], fw[33 * _CHUNK + i], fw[34 * _CHUNK + i], fw[35 * _CHUNK + i],
            fw[36 * _CHUNK + i], fw[37 * _CHUNK + i], fw[38 * _CHUNK + i], fw[39 * _CHUNK + i])
        a50, a51, a52, a53, a54, a55, a56, a57 = (
            fw[40 * _CHUNK + i], fw[41 * _CHUNK + i], fw[42 * _CHUNK + i], fw[43 * _CHUNK + i],
            fw[44 * _CHUNK + i], fw[45 * _CHUNK + i], fw[46 * _CHUNK + i], fw[47 * _CHUNK + i])
        bad = 0.0
        # column 0: pivot, row exchange, elimination
        big = abs(a00)
        piv = 0
        v = abs(a10)
        take = v > big
        big = v if take else big
        piv = 1 if take else piv
        v = abs(a20)
        take = v > big
        big = v if take else big
        piv = 2 if take else piv
        v = abs(a30)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a40)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a50)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 1
        t0, t1 = a00, a10
        a00, a10 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a11
        a01, a11 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a12
        a02, a12 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a13
        a03, a13 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a14
        a04, a14 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a15
        a05, a15 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a16
        a06, a16 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a17
        a07, a17 = (t1, t0) if sw else (t0, t1)
        sw = piv == 2
        t0, t1 = a00, a20
        a00, a20 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a21
        a01, a21 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a22
        a02, a22 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a23
        a03, a23 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a24
        a04, a24 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a25
        a05, a25 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a26
        a06, a26 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a27
        a07, a27 = (t1, t0) if sw else (t0, t1)
        sw = piv == 3
        t0, t1 = a00, a30
        a00, a30 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a31
        a01, a31 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a32
        a02, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a33
        a03, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a34
        a04, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a35
        a05, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a36
        a06, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a37
        a07, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a00, a40
        a00, a40 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a41
        a01, a41 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a42
        a02, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a43
        a03, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a44
        a04, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a45
        a05, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a46
        a06, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a47
        a07, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a00, a50
        a00, a50 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a51
        a01, a51 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a52
        a02, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a53
        a03, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a54
        a04, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a55
        a05, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a56
        a06, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a57
        a07, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a00
        fac = a10 * inv
        a11 -= fac * a01
        a12 -= fac * a02
        a13 -= fac * a03
        a14 -= fac * a04
        a15 -= fac * a05
        a16 -= fac * a06
        a17 -= fac * a07
        fac = a20 * inv
        a21 -= fac * a01
        a22 -= fac * a02
        a23 -= fac * a03
        a24 -= fac * a04
        a25 -= fac * a05
        a26 -= fac * a06
        a27 -= fac * a07
        fac = a30 * inv
        a31 -= fac * a01
        a32 -= fac * a02
        a33 -= fac * a03
        a34 -= fac * a04
        a35 -= fac * a05
        a36 -= fac * a06
        a37 -= fac * a07
        fac = a40 * inv
        a41 -= fac * a01
        a42 -= fac * a02
        a43 -= fac * a03
        a44 -= fac * a04
        a45 -= fac * a05
        a46 -= fac * a06
        a47 -= fac * a07
        fac = a50 * inv
        a51 -= fac * a01
        a52 -= fac * a02
        a53 -= fac * a03
        a54 -= fac * a04
        a55 -= fac * a05
        a56 -= fac * a06
        a57 -= fac * a07
        # column 1: pivot, row exchange, elimination
        big = abs(a11)
        piv = 1
        v = abs(a21)
        take = v > big
        big = v if take else big
        piv = 2 if take else piv
        v = abs(a31)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a41)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a51)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 2
        t0, t1 = a11, a21
        a11, a21 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a22
        a12, a22 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a23
        a13, a23 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a24
        a14, a24 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a25
        a15, a25 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a26
        a16, a26 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a27
        a17, a27 = (t1, t0) if sw else (t0, t1)
        sw = piv == 3
        t0, t1 = a11, a31
        a11, a31 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a32
        a12, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a33
        a13, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a34
        a14, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a35
        a15, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a36
        a16, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a37
        a17, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a11, a41
        a11, a41 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a42
        a12, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a43
        a13, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a44
        a14, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a45
        a15, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a46
        a16, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a47
        a17, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a11, a51
        a11, a51 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a52
        a12, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a53
        a13, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a54
        a14, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a55
        a15, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a56
        a16, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a57
        a17, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a11
        fac = a21 * inv
        a22 -= fac * a12
        a23 -= fac * a13
        a24 -= fac * a14
        a25 -= fac * a15
        a26 -= fac * a16
        a27 -= fac * a17
        fac = a31 * inv
        a32 -= fac * a12
        a33 -= fac * a13
        a34 -= fac * a14
        a35 -= fac * a15
        a36 -= fac * a16
        a37 -= fac * a17
        fac = a41 * inv
        a42 -= fac * a12
        a43 -= fac * a13
        a44 -= fac * a14
        a45 -= fac * a15
        a46 -= fac * a16
        a47 -= fac * a17
        fac = a51 * inv
        a52 -= fac * a12
        a53 -= fac * a13
        a54 -= fac * a14
        a55 -= fac * a15
        a56 -= fac * a16
        a57 -= fac * a17
        # column 2: pivot, row exchange, elimination
        big = abs(a22)
        piv = 2
        v = abs(a32)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a42)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a52)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 3
        t0, t1 = a22, a32
        a22, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a33
        a23, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a34
        a24, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a35
        a25, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a36
        a26, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a37
        a27, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a22, a42
        a22, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a43
        a23, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a44
        a24, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a45
        a25, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a46
        a26, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a47
        a27, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a22, a52
        a22, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a53
        a23, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a54
        a24, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a55
        a25, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a56
        a26, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a57
        a27, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a22
        fac = a32 * inv
        a33 -= fac * a23
        a34 -= fac * a24
        a35 -= fac * a25
        a36 -= fac * a26
        a37 -= fac * a27
        fac = a42 * inv
        a43 -= fac * a23
        a44 -= fac * a24
        a45 -= fac * a25
        a46 -= fac * a26
        a47 -= fac * a27
        fac = a52 * inv
        a53 -= fac * a23
        a54 -= fac * a24
        a55 -= fac * a25
        a56 -= fac * a26
        a57 -= fac * a27
        # column 3: pivot, row exchange, elimination
        big = abs(a33)
        piv = 3
        v = abs(a43)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a53)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 4
        t0, t1 = a33, a43
        a33, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a34, a44
        a34, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a35, a45
        a35, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a36, a46
        a36, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a37, a47
        a37, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a33, a53
        a33, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a34, a54
        a34, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a35, a55
        a35, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a36, a56
        a36, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a37, a57
        a37, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a33
        fac = a43 * inv
        a44 -= fac * a34
        a45 -= fac * a35
        a46 -= fac * a36
        a47 -= fac * a37
        fac = a53 * inv
        a54 -= fac * a34
        a55 -= fac * a35
        a56 -= fac * a36
        a57 -= fac * a37
        # column 4: pivot, row exchange, elimination
        big = abs(a44)
        piv = 4
        v = abs(a54)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 5
        t0, t1 = a44, a54
        a44, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a45, a55
        a45, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a46, a56
        a46, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a47, a57
        a47, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a44
        fac = a54 * inv
        a55 -= fac * a45
        a56 -= fac * a46
        a57 -= fac * a47
        # column 5: pivot, row exchange, elimination
        big = abs(a55)
        piv = 5
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        inv = 1.0 / a55
        # back-substitution
        inv = 1.0 / a55
        a56 = a56 * inv
        a57 = a57 * inv
        inv = 1.0 / a44
        acc = a46
        acc -= a45 * a56
        a46 = acc * inv
        acc = a47
        acc -= a45 * a57
        a47 = acc * inv
        inv = 1.0 / a33
        acc = a36
        acc -= a34 * a46
        acc -= a35 * a56
        a36 = acc * inv
        acc = a37
        acc -= a34 * a47
        acc -= a35 * a57
        a37 = acc * inv
        inv = 1.0 / a22
        acc = a26
        acc -= a23 * a36
        acc -= a24 * a46
        acc -= a25 * a56
        a26 = acc * inv
        acc = a27
        acc -= a23 * a37
        acc -= a24 * a47
        acc -= a25 * a57
        a27 = acc * inv
        inv = 1.0 / a11
        acc = a16
        acc -= a12 * a26
        acc -= a13 * a36
        acc -= a14 * a46
        acc -= a15 * a56
        a16 = acc * inv
        acc = a17
        acc -= a12 * a27
        acc -= a13 * a37
        acc -= a14 * a47
        acc -= a15 * a57
        a17 = acc * inv
        inv = 1.0 / a00
        acc = a06
        acc -= a01 * a16
        acc -= a02 * a26
        acc -= a03 * a36
        acc -= a04 * a46
        acc -= a05 * a56
        a06 = acc * inv
        acc = a07
        acc -= a01 * a17
        acc -= a02 * a27
        acc -= a03 * a37
        acc -= a04 * a47
        acc -= a05 * a57
        a07 = acc * inv
        fw[(_FB_OUT + 0) * _CHUNK + i] = a06
        fw[(_FB_OUT + 1) * _CHUNK + i] = a07
        fw[(_FB_OUT + 2) * _CHUNK + i] = a16
        fw[(_FB_OUT + 3) * _CHUNK + i] = a17
        fw[(_FB_OUT + 4) * _CHUNK + i] = a26
        fw[(_FB_OUT + 5) * _CHUNK + i] = a27
        fw[(_FB_OUT + 6) * _CHUNK + i] = a36
        fw[(_FB_OUT + 7) * _CHUNK + i] = a37
        fw[(_FB_OUT + 8) * _CHUNK + i] = a46
        fw[(_FB_OUT + 9) * _CHUNK + i] = a47
        fw[(_FB_OUT + 10) * _CHUNK + i] = a56
        fw[(_FB_OUT + 11) * _CHUNK + i] = a57
        fw[_FB_BAD * _CHUNK + i] = bad


@_jit
def _lanes_gauss6_acc(rows, inv_s, inv_rs, fw, m):
    """
    ``_lanes_gauss6`` of the blocks as ``evaluate_lanes`` left them in its acc rows.

    Lane i is ball i: the Jacobian's rows and the residual (scaled by inv_s, inv_rs as
    there) read in place, the solutions written to fw as by ``_lanes_gauss6``.
    Generated by tools/gen_block_solves.py.
    """
    for i in range(m):
        a00, a01, a02, a03, a04, a05, a06, a07 = (
            rows[(_ACC_JAC + 0) * _CHUNK + i], rows[(_ACC_JAC + 7) * _CHUNK + i],
            rows[(_ACC_JAC + 14) * _CHUNK + i], rows[(_ACC_JAC + 21) * _CHUNK + i],
            rows[(_ACC_JAC + 28) * _CHUNK + i], rows[(_ACC_JAC + 35) * _CHUNK + i],
            rows[0 * _CHUNK + i] * inv_s, rows[(_ACC_JAC + 42) * _CHUNK + i])
        a10, a11, a12, a13, a14, a15, a16, a17 = (
            rows[(_ACC_JAC + 1) * _CHUNK + i], rows[(_ACC_JAC + 8) * _CHUNK + i],
            rows[(_ACC_JAC + 15) * _CHUNK + i], rows[(_ACC_JAC + 22) * _CHUNK + i],
            rows[(_ACC_JAC + 29) * _CHUNK + i], rows[(_ACC_JAC + 36) * _CHUNK + i],
            rows[1 * _CHUNK + i] * inv_s, rows[(_ACC_JAC + 43) * _CHUNK + i])
        a20, a21, a22, a23, a24, a25, a26, a27 = (
            rows[(_ACC_JAC + 2) * _CHUNK + i], rows[(_ACC_JAC + 9) * _CHUNK + i],
            rows[(_ACC_JAC + 16) * _CHUNK + i], rows[(_ACC_JAC + 23) * _CHUNK + i],
            rows[(_ACC_JAC + 30) * _CHUNK + i], rows[(_ACC_JAC + 37) * _CHUNK + i],
            rows[2 * _CHUNK + i] * inv_s, rows[(_ACC_JAC + 44) * _CHUNK + i])
        a30, a31, a32, a33, a34, a35, a36, a37 = (
            rows[(_ACC_JAC + 3) * _CHUNK + i], rows[(_ACC_JAC + 10) * _CHUNK + i],
            rows[(_ACC_JAC + 17) * _CHUNK + i], rows[(_ACC_JAC + 24) * _CHUNK + i],
            rows[(_ACC_JAC + 31) * _CHUNK + i], rows[(_ACC_JAC + 38) * _CHUNK + i],
            rows[3 * _CHUNK + i] * inv_rs, rows[(_ACC_JAC + 45) * _CHUNK + i])
        a40, a41, a42, a43, a44, a45, a46, a47 = (
            rows[(_ACC_JAC + 4) * _CHUNK + i], rows[(_ACC_JAC + 11) * _CHUNK + i],
            rows[(_ACC_JAC + 18) * _CHUNK + i], rows[(_ACC_JAC + 25) * _CHUNK + i],
            rows[(_ACC_JAC + 32) * _CHUNK + i], rows[(_ACC_JAC + 39) * _CHUNK + i],
            rows[4 * _CHUNK + i] * inv_rs, rows[(_ACC_JAC + 46) * _CHUNK + i])
        a50, a51, a52, a53, a54, a55, a56, a57 = (
            rows[(_ACC_JAC + 5) * _CHUNK + i], rows[(_ACC_JAC + 12) * _CHUNK + i],
            rows[(_ACC_JAC + 19) * _CHUNK + i], rows[(_ACC_JAC + 26) * _CHUNK + i],
            rows[(_ACC_JAC + 33) * _CHUNK + i], rows[(_ACC_JAC + 40) * _CHUNK + i],
            rows[5 * _CHUNK + i] * inv_rs, rows[(_ACC_JAC + 47) * _CHUNK + i])
        bad = 0.0
        # column 0: pivot, row exchange, elimination
        big = abs(a00)
        piv = 0
        v = abs(a10)
        take = v > big
        big = v if take else big
        piv = 1 if take else piv
        v = abs(a20)
        take = v > big
        big = v if take else big
        piv = 2 if take else piv
        v = abs(a30)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a40)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a50)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 1
        t0, t1 = a00, a10
        a00, a10 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a11
        a01, a11 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a12
        a02, a12 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a13
        a03, a13 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a14
        a04, a14 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a15
        a05, a15 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a16
        a06, a16 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a17
        a07, a17 = (t1, t0) if sw else (t0, t1)
        sw = piv == 2
        t0, t1 = a00, a20
        a00, a20 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a21
        a01, a21 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a22
        a02, a22 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a23
        a03, a23 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a24
        a04, a24 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a25
        a05, a25 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a26
        a06, a26 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a27
        a07, a27 = (t1, t0) if sw else (t0, t1)
        sw = piv == 3
        t0, t1 = a00, a30
        a00, a30 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a31
        a01, a31 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a32
        a02, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a33
        a03, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a34
        a04, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a35
        a05, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a36
        a06, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a37
        a07, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a00, a40
        a00, a40 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a41
        a01, a41 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a42
        a02, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a43
        a03, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a44
        a04, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a45
        a05, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a46
        a06, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a47
        a07, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a00, a50
        a00, a50 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a01, a51
        a01, a51 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a02, a52
        a02, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a03, a53
        a03, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a04, a54
        a04, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a05, a55
        a05, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a06, a56
        a06, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a07, a57
        a07, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a00
        fac = a10 * inv
        a11 -= fac * a01
        a12 -= fac * a02
        a13 -= fac * a03
        a14 -= fac * a04
        a15 -= fac * a05
        a16 -= fac * a06
        a17 -= fac * a07
        fac = a20 * inv
        a21 -= fac * a01
        a22 -= fac * a02
        a23 -= fac * a03
        a24 -= fac * a04
        a25 -= fac * a05
        a26 -= fac * a06
        a27 -= fac * a07
        fac = a30 * inv
        a31 -= fac * a01
        a32 -= fac * a02
        a33 -= fac * a03
        a34 -= fac * a04
        a35 -= fac * a05
        a36 -= fac * a06
        a37 -= fac * a07
        fac = a40 * inv
        a41 -= fac * a01
        a42 -= fac * a02
        a43 -= fac * a03
        a44 -= fac * a04
        a45 -= fac * a05
        a46 -= fac * a06
        a47 -= fac * a07
        fac = a50 * inv
        a51 -= fac * a01
        a52 -= fac * a02
        a53 -= fac * a03
        a54 -= fac * a04
        a55 -= fac * a05
        a56 -= fac * a06
        a57 -= fac * a07
        # column 1: pivot, row exchange, elimination
        big = abs(a11)
        piv = 1
        v = abs(a21)
        take = v > big
        big = v if take else big
        piv = 2 if take else piv
        v = abs(a31)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a41)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a51)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 2
        t0, t1 = a11, a21
        a11, a21 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a22
        a12, a22 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a23
        a13, a23 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a24
        a14, a24 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a25
        a15, a25 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a26
        a16, a26 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a27
        a17, a27 = (t1, t0) if sw else (t0, t1)
        sw = piv == 3
        t0, t1 = a11, a31
        a11, a31 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a32
        a12, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a33
        a13, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a34
        a14, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a35
        a15, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a36
        a16, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a37
        a17, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a11, a41
        a11, a41 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a42
        a12, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a43
        a13, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a44
        a14, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a45
        a15, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a46
        a16, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a47
        a17, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a11, a51
        a11, a51 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a12, a52
        a12, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a13, a53
        a13, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a14, a54
        a14, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a15, a55
        a15, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a16, a56
        a16, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a17, a57
        a17, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a11
        fac = a21 * inv
        a22 -= fac * a12
        a23 -= fac * a13
        a24 -= fac * a14
        a25 -= fac * a15
        a26 -= fac * a16
        a27 -= fac * a17
        fac = a31 * inv
        a32 -= fac * a12
        a33 -= fac * a13
        a34 -= fac * a14
        a35 -= fac * a15
        a36 -= fac * a16
        a37 -= fac * a17
        fac = a41 * inv
        a42 -= fac * a12
        a43 -= fac * a13
        a44 -= fac * a14
        a45 -= fac * a15
        a46 -= fac * a16
        a47 -= fac * a17
        fac = a51 * inv
        a52 -= fac * a12
        a53 -= fac * a13
        a54 -= fac * a14
        a55 -= fac * a15
        a56 -= fac * a16
        a57 -= fac * a17
        # column 2: pivot, row exchange, elimination
        big = abs(a22)
        piv = 2
        v = abs(a32)
        take = v > big
        big = v if take else big
        piv = 3 if take else piv
        v = abs(a42)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a52)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 3
        t0, t1 = a22, a32
        a22, a32 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a33
        a23, a33 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a34
        a24, a34 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a35
        a25, a35 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a36
        a26, a36 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a37
        a27, a37 = (t1, t0) if sw else (t0, t1)
        sw = piv == 4
        t0, t1 = a22, a42
        a22, a42 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a43
        a23, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a44
        a24, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a45
        a25, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a46
        a26, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a47
        a27, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a22, a52
        a22, a52 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a23, a53
        a23, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a24, a54
        a24, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a25, a55
        a25, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a26, a56
        a26, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a27, a57
        a27, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a22
        fac = a32 * inv
        a33 -= fac * a23
        a34 -= fac * a24
        a35 -= fac * a25
        a36 -= fac * a26
        a37 -= fac * a27
        fac = a42 * inv
        a43 -= fac * a23
        a44 -= fac * a24
        a45 -= fac * a25
        a46 -= fac * a26
        a47 -= fac * a27
        fac = a52 * inv
        a53 -= fac * a23
        a54 -= fac * a24
        a55 -= fac * a25
        a56 -= fac * a26
        a57 -= fac * a27
        # column 3: pivot, row exchange, elimination
        big = abs(a33)
        piv = 3
        v = abs(a43)
        take = v > big
        big = v if take else big
        piv = 4 if take else piv
        v = abs(a53)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 4
        t0, t1 = a33, a43
        a33, a43 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a34, a44
        a34, a44 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a35, a45
        a35, a45 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a36, a46
        a36, a46 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a37, a47
        a37, a47 = (t1, t0) if sw else (t0, t1)
        sw = piv == 5
        t0, t1 = a33, a53
        a33, a53 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a34, a54
        a34, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a35, a55
        a35, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a36, a56
        a36, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a37, a57
        a37, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a33
        fac = a43 * inv
        a44 -= fac * a34
        a45 -= fac * a35
        a46 -= fac * a36
        a47 -= fac * a37
        fac = a53 * inv
        a54 -= fac * a34
        a55 -= fac * a35
        a56 -= fac * a36
        a57 -= fac * a37
        # column 4: pivot, row exchange, elimination
        big = abs(a44)
        piv = 4
        v = abs(a54)
        take = v > big
        big = v if take else big
        piv = 5 if take else piv
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        sw = piv == 5
        t0, t1 = a44, a54
        a44, a54 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a45, a55
        a45, a55 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a46, a56
        a46, a56 = (t1, t0) if sw else (t0, t1)
        t0, t1 = a47, a57
        a47, a57 = (t1, t0) if sw else (t0, t1)
        inv = 1.0 / a44
        fac = a54 * inv
        a55 -= fac * a45
        a56 -= fac * a46
        a57 -= fac * a47
        # column 5: pivot, row exchange, elimination
        big = abs(a55)
        piv = 5
        bad = 1.0 if (big == 0.0 or not (big < np.inf)) else bad
        inv = 1.0 / a55
        # back-substitution
        inv = 1.0 / a55
        a56 = a56 * inv
        a57 = a57 * inv
        inv = 1.0 / a44
        acc = a46
        acc -= a45 * a56
        a46 = acc * inv
        acc = a47
        acc -= a45 * a57
        a47 = acc * inv
        inv = 1.0 / a33
        acc = a36
        acc -= a34 * a46
        acc -= a35 * a56
        a36 = acc * inv
        acc = a37
        acc -= a34 * a47
        acc -= a35 * a57
        a37 = acc * inv
        inv = 1.0 / a22
        acc = a26
        acc -= a23 * a36
        acc -= a24 * a46
        acc -= a25 * a56
        a26 = acc * inv
        acc = a27
        acc -= a23 * a37
        acc -= a24 * a47
        acc -= a25 * a57
        a27 = acc * inv
        inv = 1.0 / a11
        acc = a16
        acc -= a12 * a26
        acc -= a13 * a36
        acc -= a14 * a46
        acc -= a15 * a56
        a16 = acc * inv
        acc = a17
        acc -= a12 * a27
        acc -= a13 * a37
        acc -= a14 * a47
        acc -= a15 * a57
        a17 = acc * inv
        inv = 1.0 / a00
        acc = a06
        acc -= a01 * a16
        acc -= a02 * a26
        acc -= a03 * a36
        acc -= a04 * a46
        acc -= a05 * a56
        a06 = acc * inv
        acc = a07
        acc -= a01 * a17
        acc -= a02 * a27
        acc -= a03 * a37
        acc -= a04 * a47
        acc -= a05 * a57
        a07 = acc * inv
        fw[(_FB_OUT + 0) * _CHUNK + i] = a06
        fw[(_FB_OUT + 1) * _CHUNK + i] = a07
        fw[(_FB_OUT + 2) * _CHUNK + i] = a16
        fw[(_FB_OUT + 3) * _CHUNK + i] = a17
        fw[(_FB_OUT + 4) * _CHUNK + i] = a26
        fw[(_FB_OUT + 5) * _CHUNK + i] = a27
        fw[(_FB_OUT + 6) * _CHUNK + i] = a36
        fw[(_FB_OUT + 7) * _CHUNK + i] = a37
        fw[(_FB_OUT + 8) * _CHUNK + i] = a46
        fw[(_FB_OUT + 9) * _CHUNK + i] = a47
        fw[(_FB_OUT + 10) * _CHUNK + i] = a56
        fw[(_FB_OUT + 11) * _CHUNK + i] = a57
        fw[_FB_BAD * _CHUNK + i] = bad


@_jit
def _block_solve7(d, w):
    """
    Solve d[:7, :7] X = w[:7, 0:9] into w; False if it is singular.

    d and w are left untouched when False (a pivot zero or not finite).
    Generated by tools/gen_block_solves.py (why: there).
    """
    a00, a01, a02, a03, a04, a05, a06 = (
        d[0, 0], d[0, 1], d[0, 2], d[0, 3], d[0, 4], d[0, 5], d[0, 6])
    b00, b01, b02, b03, b04, b05, b06, b07, b08 = (
        w[0, 0], w[0, 1], w[0, 2], w[0, 3], w[0, 4], w[0, 5], w[0, 6], w[0, 7], w[0, 8])
    a10, a11, a12, a13, a14, a15, a16 = (
        d[1, 0], d[1, 1], d[1, 2], d[1, 3], d[1, 4], d[1, 5], d[1, 6])
    b10, b11, b12, b13, b14, b15, b16, b17, b18 = (
        w[1, 0], w[1, 1], w[1, 2], w[1, 3], w[1, 4], w[1, 5], w[1, 6], w[1, 7], w[1, 8])
    a20, a21, a22, a23, a24, a25, a26 = (
        d[2, 0], d[2, 1], d[2, 2], d[2, 3], d[2, 4], d[2, 5], d[2, 6])
    b20, b21, b22, b23, b24, b25, b26, b27, b28 = (
        w[2, 0], w[2, 1], w[2, 2], w[2, 3], w[2, 4], w[2, 5], w[2, 6], w[2, 7], w[2, 8])
    a30, a31, a32, a33, a34, a35, a36 = (
        d[3, 0], d[3, 1], d[3, 2], d[3, 3], d[3, 4], d[3, 5], d[3, 6])
    b30, b31, b32, b33, b34, b35, b36, b37, b38 = (
        w[3, 0], w[3, 1], w[3, 2], w[3, 3], w[3, 4], w[3, 5], w[3, 6], w[3, 7], w[3, 8])
    a40, a41, a42, a43, a44, a45, a46 = (
        d[4, 0], d[4, 1], d[4, 2], d[4, 3], d[4, 4], d[4, 5], d[4, 6])
    b40, b41, b42, b43, b44, b45, b46, b47, b48 = (
        w[4, 0], w[4, 1], w[4, 2], w[4, 3], w[4, 4], w[4, 5], w[4, 6], w[4, 7], w[4, 8])
    a50, a51, a52, a53, a54, a55, a56 = (
        d[5, 0], d[5, 1], d[5, 2], d[5, 3], d[5, 4], d[5, 5], d[5, 6])
    b50, b51, b52, b53, b54, b55, b56, b57, b58 = (
        w[5, 0], w[5, 1], w[5, 2], w[5, 3], w[5, 4], w[5, 5], w[5, 6], w[5, 7], w[5, 8])
    a60, a61, a62, a63, a64, a65, a66 = (
        d[6, 0], d[6, 1], d[6, 2], d[6, 3], d[6, 4], d[6, 5], d[6, 6])
    b60, b61, b62, b63, b64, b65, b66, b67, b68 = (
        w[6, 0], w[6, 1], w[6, 2], w[6, 3], w[6, 4], w[6, 5], w[6, 6], w[6, 7], w[6, 8])
    # column 0
    big = abs(a00)
    piv = 0
    if abs(a10) > big:
        big = abs(a10)
        piv = 1
    if abs(a20) > big:
        big = abs(a20)
        piv = 2
    if abs(a30) > big:
        big = abs(a30)
        piv = 3
    if abs(a40) > big:
        big = abs(a40)
        piv = 4
    if abs(a50) > big:
        big = abs(a50)
        piv = 5
    if abs(a60) > big:
        big = abs(a60)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 1:
        a00, a10 = a10, a00
        a01, a11 = a11, a01
        a02, a12 = a12, a02
        a03, a13 = a13, a03
        a04, a14 = a14, a04
        a05, a15 = a15, a05
        a06, a16 = a16, a06
        b00, b10 = b10, b00
        b01, b11 = b11, b01
        b02, b12 = b12, b02
        b03, b13 = b13, b03
        b04, b14 = b14, b04
        b05, b15 = b15, b05
        b06, b16 = b16, b06
        b07, b17 = b17, b07
        b08, b18 = b18, b08
    if piv == 2:
        a00, a20 = a20, a00
        a01, a21 = a21, a01
        a02, a22 = a22, a02
        a03, a23 = a23, a03
        a04, a24 = a24, a04
        a05, a25 = a25, a05
        a06, a26 = a26, a06
        b00, b20 = b20, b00
        b01, b21 = b21, b01
        b02, b22 = b22, b02
        b03, b23 = b23, b03
        b04, b24 = b24, b04
        b05, b25 = b25, b05
        b06, b26 = b26, b06
        b07, b27 = b27, b07
        b08, b28 = b28, b08
    if piv == 3:
        a00, a30 = a30, a00
        a01, a31 = a31, a01
        a02, a32 = a32, a02
        a03, a33 = a33, a03
        a04, a34 = a34, a04
        a05, a35 = a35, a05
        a06, a36 = a36, a06
        b00, b30 = b30, b00
        b01, b31 = b31, b01
        b02, b32 = b32, b02
        b03, b33 = b33, b03
        b04, b34 = b34, b04
        b05, b35 = b35, b05
        b06, b36 = b36, b06
        b07, b37 = b37, b07
        b08, b38 = b38, b08
    if piv == 4:
        a00, a40 = a40, a00
        a01, a41 = a41, a01
        a02, a42 = a42, a02
        a03, a43 = a43, a03
        a04, a44 = a44, a04
        a05, a45 = a45, a05
        a06, a46 = a46, a06
        b00, b40 = b40, b00
        b01, b41 = b41, b01
        b02, b42 = b42, b02
        b03, b43 = b43, b03
        b04, b44 = b44, b04
        b05, b45 = b45, b05
        b06, b46 = b46, b06
        b07, b47 = b47, b07
        b08, b48 = b48, b08
    if piv == 5:
        a00, a50 = a50, a00
        a01, a51 = a51, a01
        a02, a52 = a52, a02
        a03, a53 = a53, a03
        a04, a54 = a54, a04
        a05, a55 = a55, a05
        a06, a56 = a56, a06
        b00, b50 = b50, b00
        b01, b51 = b51, b01
        b02, b52 = b52, b02
        b03, b53 = b53, b03
        b04, b54 = b54, b04
        b05, b55 = b55, b05
        b06, b56 = b56, b06
        b07, b57 = b57, b07
        b08, b58 = b58, b08
    if piv == 6:
        a00, a60 = a60, a00
        a01, a61 = a61, a01
        a02, a62 = a62, a02
        a03, a63 = a63, a03
        a04, a64 = a64, a04
        a05, a65 = a65, a05
        a06, a66 = a66, a06
        b00, b60 = b60, b00
        b01, b61 = b61, b01
        b02, b62 = b62, b02
        b03, b63 = b63, b03
        b04, b64 = b64, b04
        b05, b65 = b65, b05
        b06, b66 = b66, b06
        b07, b67 = b67, b07
        b08, b68 = b68, b08
    inv = 1.0 / a00
    fac = a10 * inv
    if fac != 0.0:
        a11 -= fac * a01
        a12 -= fac * a02
        a13 -= fac * a03
        a14 -= fac * a04
        a15 -= fac * a05
        a16 -= fac * a06
        b10 -= fac * b00
        b11 -= fac * b01
        b12 -= fac * b02
        b13 -= fac * b03
        b14 -= fac * b04
        b15 -= fac * b05
        b16 -= fac * b06
        b17 -= fac * b07
        b18 -= fac * b08
    fac = a20 * inv
    if fac != 0.0:
        a21 -= fac * a01
        a22 -= fac * a02
        a23 -= fac * a03
        a24 -= fac * a04
        a25 -= fac * a05
        a26 -= fac * a06
        b20 -= fac * b00
        b21 -= fac * b01
        b22 -= fac * b02
        b23 -= fac * b03
        b24 -= fac * b04
        b25 -= fac * b05
        b26 -= fac * b06
        b27 -= fac * b07
        b28 -= fac * b08
    fac = a30 * inv
    if fac != 0.0:
        a31 -= fac * a01
        a32 -= fac * a02
        a33 -= fac * a03
        a34 -= fac * a04
        a35 -= fac * a05
        a36 -= fac * a06
        b30 -= fac * b00
        b31 -= fac * b01
        b32 -= fac * b02
        b33 -= fac * b03
        b34 -= fac * b04
        b35 -= fac * b05
        b36 -= fac * b06
        b37 -= fac * b07
        b38 -= fac * b08
    fac = a40 * inv
    if fac != 0.0:
        a41 -= fac * a01
        a42 -= fac * a02
        a43 -= fac * a03
        a44 -= fac * a04
        a45 -= fac * a05
        a46 -= fac * a06
        b40 -= fac * b00
        b41 -= fac * b01
        b42 -= fac * b02
        b43 -= fac * b03
        b44 -= fac * b04
        b45 -= fac * b05
        b46 -= fac * b06
        b47 -= fac * b07
        b48 -= fac * b08
    fac = a50 * inv
    if fac != 0.0:
        a51 -= fac * a01
        a52 -= fac * a02
        a53 -= fac * a03
        a54 -= fac * a04
        a55 -= fac * a05
        a56 -= fac * a06
        b50 -= fac * b00
        b51 -= fac * b01
        b52 -= fac * b02
        b53 -= fac * b03
        b54 -= fac * b04
        b55 -= fac * b05
        b56 -= fac * b06
        b57 -= fac * b07
        b58 -= fac * b08
    fac = a60 * inv
    if fac != 0.0:
        a61 -= fac * a01
        a62 -= fac * a02
        a63 -= fac * a03
        a64 -= fac * a04
        a65 -= fac * a05
        a66 -= fac * a06
        b60 -= fac * b00
        b61 -= fac * b01
        b62 -= fac * b02
        b63 -= fac * b03
        b64 -= fac * b04
        b65 -= fac * b05
        b66 -= fac * b06
        b67 -= fac * b07
        b68 -= fac * b08
    # column 1
    big = abs(a11)
    piv = 1
    if abs(a21) > big:
        big = abs(a21)
        piv = 2
    if abs(a31) > big:
        big = abs(a31)
        piv = 3
    if abs(a41) > big:
        big = abs(a41)
        piv = 4
    if abs(a51) > big:
        big = abs(a51)
        piv = 5
    if abs(a61) > big:
        big = abs(a61)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 2:
        a11, a21 = a21, a11
        a12, a22 = a22, a12
        a13, a23 = a23, a13
        a14, a24 = a24, a14
        a15, a25 = a25, a15
        a16, a26 = a26, a16
        b10, b20 = b20, b10
        b11, b21 = b21, b11
        b12, b22 = b22, b12
        b13, b23 = b23, b13
        b14, b24 = b24, b14
        b15, b25 = b25, b15
        b16, b26 = b26, b16
        b17, b27 = b27, b17
        b18, b28 = b28, b18
    if piv == 3:
        a11, a31 = a31, a11
        a12, a32 = a32, a12
        a13, a33 = a33, a13
        a14, a34 = a34, a14
        a15, a35 = a35, a15
        a16, a36 = a36, a16
        b10, b30 = b30, b10
        b11, b31 = b31, b11
        b12, b32 = b32, b12
        b13, b33 = b33, b13
        b14, b34 = b34, b14
        b15, b35 = b35, b15
        b16, b36 = b36, b16
        b17, b37 = b37, b17
        b18, b38 = b38, b18
    if piv == 4:
        a11, a41 = a41, a11
        a12, a42 = a42, a12
        a13, a43 = a43, a13
        a14, a44 = a44, a14
        a15, a45 = a45, a15
        a16, a46 = a46, a16
        b10, b40 = b40, b10
        b11, b41 = b41, b11
        b12, b42 = b42, b12
        b13, b43 = b43, b13
        b14, b44 = b44, b14
        b15, b45 = b45, b15
        b16, b46 = b46, b16
        b17, b47 = b47, b17
        b18, b48 = b48, b18
    if piv == 5:
        a11, a51 = a51, a11
        a12, a52 = a52, a12
        a13, a53 = a53, a13
        a14, a54 = a54, a14
        a15, a55 = a55, a15
        a16, a56 = a56, a16
        b10, b50 = b50, b10
        b11, b51 = b51, b11
        b12, b52 = b52, b12
        b13, b53 = b53, b13
        b14, b54 = b54, b14
        b15, b55 = b55, b15
        b16, b56 = b56, b16
        b17, b57 = b57, b17
        b18, b58 = b58, b18
    if piv == 6:
        a11, a61 = a61, a11
        a12, a62 = a62, a12
        a13, a63 = a63, a13
        a14, a64 = a64, a14
        a15, a65 = a65, a15
        a16, a66 = a66, a16
        b10, b60 = b60, b10
        b11, b61 = b61, b11
        b12, b62 = b62, b12
        b13, b63 = b63, b13
        b14, b64 = b64, b14
        b15, b65 = b65, b15
        b16, b66 = b66, b16
        b17, b67 = b67, b17
        b18, b68 = b68, b18
    inv = 1.0 / a11
    fac = a21 * inv
    if fac != 0.0:
        a22 -= fac * a12
        a23 -= fac * a13
        a24 -= fac * a14
        a25 -= fac * a15
        a26 -= fac * a16
        b20 -= fac * b10
        b21 -= fac * b11
        b22 -= fac * b12
        b23 -= fac * b13
        b24 -= fac * b14
        b25 -= fac * b15
        b26 -= fac * b16
        b27 -= fac * b17
        b28 -= fac * b18
    fac = a31 * inv
    if fac != 0.0:
        a32 -= fac * a12
        a33 -= fac * a13
        a34 -= fac * a14
        a35 -= fac * a15
        a36 -= fac * a16
        b30 -= fac * b10
        b31 -= fac * b11
        b32 -= fac * b12
        b33 -= fac * b13
        b34 -= fac * b14
        b35 -= fac * b15
        b36 -= fac * b16
        b37 -= fac * b17
        b38 -= fac * b18
    fac = a41 * inv
    if fac != 0.0:
        a42 -= fac * a12
        a43 -= fac * a13
        a44 -= fac * a14
        a45 -= fac * a15
        a46 -= fac * a16
        b40 -= fac * b10
        b41 -= fac * b11
        b42 -= fac * b12
        b43 -= fac * b13
        b44 -= fac * b14
        b45 -= fac * b15
        b46 -= fac * b16
        b47 -= fac * b17
        b48 -= fac * b18
    fac = a51 * inv
    if fac != 0.0:
        a52 -= fac * a12
        a53 -= fac * a13
        a54 -= fac * a14
        a55 -= fac * a15
        a56 -= fac * a16
        b50 -= fac * b10
        b51 -= fac * b11
        b52 -= fac * b12
        b53 -= fac * b13
        b54 -= fac * b14
        b55 -= fac * b15
        b56 -= fac * b16
        b57 -= fac * b17
        b58 -= fac * b18
    fac = a61 * inv
    if fac != 0.0:
        a62 -= fac * a12
        a63 -= fac * a13
        a64 -= fac * a14
        a65 -= fac * a15
        a66 -= fac * a16
        b60 -= fac * b10
        b61 -= fac * b11
        b62 -= fac * b12
        b63 -= fac * b13
        b64 -= fac * b14
        b65 -= fac * b15
        b66 -= fac * b16
        b67 -= fac * b17
        b68 -= fac * b18
    # column 2
    big = abs(a22)
    piv = 2
    if abs(a32) > big:
        big = abs(a32)
        piv = 3
    if abs(a42) > big:
        big = abs(a42)
        piv = 4
    if abs(a52) > big:
        big = abs(a52)
        piv = 5
    if abs(a62) > big:
        big = abs(a62)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 3:
        a22, a32 = a32, a22
        a23, a33 = a33, a23
        a24, a34 = a34, a24
        a25, a35 = a35, a25
        a26, a36 = a36, a26
        b20, b30 = b30, b20
        b21, b31 = b31, b21
        b22, b32 = b32, b22
        b23, b33 = b33, b23
        b24, b34 = b34, b24
        b25, b35 = b35, b25
        b26, b36 = b36, b26
        b27, b37 = b37, b27
        b28, b38 = b38, b28
    if piv == 4:
        a22, a42 = a42, a22
        a23, a43 = a43, a23
        a24, a44 = a44, a24
        a25, a45 = a45, a25
        a26, a46 = a46, a26
        b20, b40 = b40, b20
        b21, b41 = b41, b21
        b22, b42 = b42, b22
        b23, b43 = b43, b23
        b24, b44 = b44, b24
        b25, b45 = b45, b25
        b26, b46 = b46, b26
        b27, b47 = b47, b27
        b28, b48 = b48, b28
    if piv == 5:
        a22, a52 = a52, a22
        a23, a53 = a53, a23
        a24, a54 = a54, a24
        a25, a55 = a55, a25
        a26, a56 = a56, a26
        b20, b50 = b50, b20
        b21, b51 = b51, b21
        b22, b52 = b52, b22
        b23, b53 = b53, b23
        b24, b54 = b54, b24
        b25, b55 = b55, b25
        b26, b56 = b56, b26
        b27, b57 = b57, b27
        b28, b58 = b58, b28
    if piv == 6:
        a22, a62 = a62, a22
        a23, a63 = a63, a23
        a24, a64 = a64, a24
        a25, a65 = a65, a25
        a26, a66 = a66, a26
        b20, b60 = b60, b20
        b21, b61 = b61, b21
        b22, b62 = b62, b22
        b23, b63 = b63, b23
        b24, b64 = b64, b24
        b25, b65 = b65, b25
        b26, b66 = b66, b26
        b27, b67 = b67, b27
        b28, b68 = b68, b28
    inv = 1.0 / a22
    fac = a32 * inv
    if fac != 0.0:
        a33 -= fac * a23
        a34 -= fac * a24
        a35 -= fac * a25
        a36 -= fac * a26
        b30 -= fac * b20
        b31 -= fac * b21
        b32 -= fac * b22
        b33 -= fac * b23
        b34 -= fac * b24
        b35 -= fac * b25
        b36 -= fac * b26
        b37 -= fac * b27
        b38 -= fac * b28
    fac = a42 * inv
    if fac != 0.0:
        a43 -= fac * a23
        a44 -= fac * a24
        a45 -= fac * a25
        a46 -= fac * a26
        b40 -= fac * b20
        b41 -= fac * b21
        b42 -= fac * b22
        b43 -= fac * b23
        b44 -= fac * b24
        b45 -= fac * b25
        b46 -= fac * b26
        b47 -= fac * b27
        b48 -= fac * b28
    fac = a52 * inv
    if fac != 0.0:
        a53 -= fac * a23
        a54 -= fac * a24
        a55 -= fac * a25
        a56 -= fac * a26
        b50 -= fac * b20
        b51 -= fac * b21
        b52 -= fac * b22
        b53 -= fac * b23
        b54 -= fac * b24
        b55 -= fac * b25
        b56 -= fac * b26
        b57 -= fac * b27
        b58 -= fac * b28
    fac = a62 * inv
    if fac != 0.0:
        a63 -= fac * a23
        a64 -= fac * a24
        a65 -= fac * a25
        a66 -= fac * a26
        b60 -= fac * b20
        b61 -= fac * b21
        b62 -= fac * b22
        b63 -= fac * b23
        b64 -= fac * b24
        b65 -= fac * b25
        b66 -= fac * b26
        b67 -= fac * b27
        b68 -= fac * b28
    # column 3
    big = abs(a33)
    piv = 3
    if abs(a43) > big:
        big = abs(a43)
        piv = 4
    if abs(a53) > big:
        big = abs(a53)
        piv = 5
    if abs(a63) > big:
        big = abs(a63)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 4:
        a33, a43 = a43, a33
        a34, a44 = a44, a34
        a35, a45 = a45, a35
        a36, a46 = a46, a36
        b30, b40 = b40, b30
        b31, b41 = b41, b31
        b32, b42 = b42, b32
        b33, b43 = b43, b33
        b34, b44 = b44, b34
        b35, b45 = b45, b35
        b36, b46 = b46, b36
        b37, b47 = b47, b37
        b38, b48 = b48, b38
    if piv == 5:
        a33, a53 = a53, a33
        a34, a54 = a54, a34
        a35, a55 = a55, a35
        a36, a56 = a56, a36
        b30, b50 = b50, b30
        b31, b51 = b51, b31
        b32, b52 = b52, b32
        b33, b53 = b53, b33
        b34, b54 = b54, b34
        b35, b55 = b55, b35
        b36, b56 = b56, b36
        b37, b57 = b57, b37
        b38, b58 = b58, b38
    if piv == 6:
        a33, a63 = a63, a33
        a34, a64 = a64, a34
        a35, a65 = a65, a35
        a36, a66 = a66, a36
        b30, b60 = b60, b30
        b31, b61 = b61, b31
        b32, b62 = b62, b32
        b33, b63 = b63, b33
        b34, b64 = b64, b34
        b35, b65 = b65, b35
        b36, b66 = b66, b36
        b37, b67 = b67, b37
        b38, b68 = b68, b38
    inv = 1.0 / a33
    fac = a43 * inv
    if fac != 0.0:
        a44 -= fac * a34
        a45 -= fac * a35
        a46 -= fac * a36
        b40 -= fac * b30
        b41 -= fac * b31
        b42 -= fac * b32
        b43 -= fac * b33
        b44 -= fac * b34
        b45 -= fac * b35
        b46 -= fac * b36
        b47 -= fac * b37
        b48 -= fac * b38
    fac = a53 * inv
    if fac != 0.0:
        a54 -= fac * a34
        a55 -= fac * a35
        a56 -= fac * a36
        b50 -= fac * b30
        b51 -= fac * b31
        b52 -= fac * b32
        b53 -= fac * b33
        b54 -= fac * b34
        b55 -= fac * b35
        b56 -= fac * b36
        b57 -= fac * b37
        b58 -= fac * b38
    fac = a63 * inv
    if fac != 0.0:
        a64 -= fac * a34
        a65 -= fac * a35
        a66 -= fac * a36
        b60 -= fac * b30
        b61 -= fac * b31
        b62 -= fac * b32
        b63 -= fac * b33
        b64 -= fac * b34
        b65 -= fac * b35
        b66 -= fac * b36
        b67 -= fac * b37
        b68 -= fac * b38
    # column 4
    big = abs(a44)
    piv = 4
    if abs(a54) > big:
        big = abs(a54)
        piv = 5
    if abs(a64) > big:
        big = abs(a64)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 5:
        a44, a54 = a54, a44
        a45, a55 = a55, a45
        a46, a56 = a56, a46
        b40, b50 = b50, b40
        b41, b51 = b51, b41
        b42, b52 = b52, b42
        b43, b53 = b53, b43
        b44, b54 = b54, b44
        b45, b55 = b55, b45
        b46, b56 = b56, b46
        b47, b57 = b57, b47
        b48, b58 = b58, b48
    if piv == 6:
        a44, a64 = a64, a44
        a45, a65 = a65, a45
        a46, a66 = a66, a46
        b40, b60 = b60, b40
        b41, b61 = b61, b41
        b42, b62 = b62, b42
        b43, b63 = b63, b43
        b44, b64 = b64, b44
        b45, b65 = b65, b45
        b46, b66 = b66, b46
        b47, b67 = b67, b47
        b48, b68 = b68, b48
    inv = 1.0 / a44
    fac = a54 * inv
    if fac != 0.0:
        a55 -= fac * a45
        a56 -= fac * a46
        b50 -= fac * b40
        b51 -= fac * b41
        b52 -= fac * b42
        b53 -= fac * b43
        b54 -= fac * b44
        b55 -= fac * b45
        b56 -= fac * b46
        b57 -= fac * b47
        b58 -= fac * b48
    fac = a64 * inv
    if fac != 0.0:
        a65 -= fac * a45
        a66 -= fac * a46
        b60 -= fac * b40
        b61 -= fac * b41
        b62 -= fac * b42
        b63 -= fac * b43
        b64 -= fac * b44
        b65 -= fac * b45
        b66 -= fac * b46
        b67 -= fac * b47
        b68 -= fac * b48
    # column 5
    big = abs(a55)
    piv = 5
    if abs(a65) > big:
        big = abs(a65)
        piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 6:
        a55, a65 = a65, a55
        a56, a66 = a66, a56
        b50, b60 = b60, b50
        b51, b61 = b61, b51
        b52, b62 = b62, b52
        b53, b63 = b63, b53
        b54, b64 = b64, b54
        b55, b65 = b65, b55
        b56, b66 = b66, b56
        b57, b67 = b67, b57
        b58, b68 = b68, b58
    inv = 1.0 / a55
    fac = a65 * inv
    if fac != 0.0:
        a66 -= fac * a56
        b60 -= fac * b50
        b61 -= fac * b51
        b62 -= fac * b52
        b63 -= fac * b53
        b64 -= fac * b54
        b65 -= fac * b55
        b66 -= fac * b56
        b67 -= fac * b57
        b68 -= fac * b58
    # column 6
    big = abs(a66)
    piv = 6
    if big == 0.0 or not math.isfinite(big):
        return False
    inv = 1.0 / a66
    # back-substitution
    inv = 1.0 / a66
    b60 = b60 * inv
    b61 = b61 * inv
    b62 = b62 * inv
    b63 = b63 * inv
    b64 = b64 * inv
    b65 = b65 * inv
    b66 = b66 * inv
    b67 = b67 * inv
    b68 = b68 * inv
    inv = 1.0 / a55
    acc = b50
    acc -= a56 * b60
    b50 = acc * inv
    acc = b51
    acc -= a56 * b61
    b51 = acc * inv
    acc = b52
    acc -= a56 * b62
    b52 = acc * inv
    acc = b53
    acc -= a56 * b63
    b53 = acc * inv
    acc = b54
    acc -= a56 * b64
    b54 = acc * inv
    acc = b55
    acc -= a56 * b65
    b55 = acc * inv
    acc = b56
    acc -= a56 * b66
    b56 = acc * inv
    acc = b57
    acc -= a56 * b67
    b57 = acc * inv
    acc = b58
    acc -= a56 * b68
    b58 = acc * inv
    inv = 1.0 / a44
    acc = b40
    acc -= a45 * b50
    acc -= a46 * b60
    b40 = acc * inv
    acc = b41
    acc -= a45 * b51
    acc -= a46 * b61
    b41 = acc * inv
    acc = b42
    acc -= a45 * b52
    acc -= a46 * b62
    b42 = acc * inv
    acc = b43
    acc -= a45 * b53
    acc -= a46 * b63
    b43 = acc * inv
    acc = b44
    acc -= a45 * b54
    acc -= a46 * b64
    b44 = acc * inv
    acc = b45
    acc -= a45 * b55
    acc -= a46 * b65
    b45 = acc * inv
    acc = b46
    acc -= a45 * b56
    acc -= a46 * b66
    b46 = acc * inv
    acc = b47
    acc -= a45 * b57
    acc -= a46 * b67
    b47 = acc * inv
    acc = b48
    acc -= a45 * b58
    acc -= a46 * b68
    b48 = acc * inv
    inv = 1.0 / a33
    acc = b30
    acc -= a34 * b40
    acc -= a35 * b50
    acc -= a36 * b60
    b30 = acc * inv
    acc = b31
    acc -= a34 * b41
    acc -= a35 * b51
    acc -= a36 * b61
    b31 = acc * inv
    acc = b32
    acc -= a34 * b42
    acc -= a35 * b52
    acc -= a36 * b62
    b32 = acc * inv
    acc = b33
    acc -= a34 * b43
    acc -= a35 * b53
    acc -= a36 * b63
    b33 = acc * inv
    acc = b34
    acc -= a34 * b44
    acc -= a35 * b54
    acc -= a36 * b64
    b34 = acc * inv
    acc = b35
    acc -= a34 * b45
    acc -= a35 * b55
    acc -= a36 * b65
    b35 = acc * inv
    acc = b36
    acc -= a34 * b46
    acc -= a35 * b56
    acc -= a36 * b66
    b36 = acc * inv
    acc = b37
    acc -= a34 * b47
    acc -= a35 * b57
    acc -= a36 * b67
    b37 = acc * inv
    acc = b38
    acc -= a34 * b48
    acc -= a35 * b58
    acc -= a36 * b68
    b38 = acc * inv
    inv = 1.0 / a22
    acc = b20
    acc -= a23 * b30
    acc -= a24 * b40
    acc -= a25 * b50
    acc -= a26 * b60
    b20 = acc * inv
    acc = b21
    acc -= a23 * b31
    acc -= a24 * b41
    acc -= a25 * b51
    acc -= a26 * b61
    b21 = acc * inv
    acc = b22
    acc -= a23 * b32
    acc -= a24 * b42
    acc -= a25 * b52
    acc -= a26 * b62
    b22 = acc * inv
    acc = b23
    acc -= a23 * b33
    acc -= a24 * b43
    acc -= a25 * b53
    acc -= a26 * b63
    b23 = acc * inv
    acc = b24
    acc -= a23 * b34
    acc -= a24 * b44
    acc -= a25 * b54
    acc -= a26 * b64
    b24 = acc * inv
    acc = b25
    acc -= a23 * b35
    acc -= a24 * b45
    acc -= a25 * b55
    acc -= a26 * b65
    b25 = acc * inv
    acc = b26
    acc -= a23 * b36
    acc -= a24 * b46
    acc -= a25 * b56
    acc -= a26 * b66
    b26 = acc * inv
    acc = b27
    acc -= a23 * b37
    acc -= a24 * b47
    acc -= a25 * b57
    acc -= a26 * b67
    b27 = acc * inv
    acc = b28
    acc -= a23 * b38
    acc -= a24 * b48
    acc -= a25 * b58
    acc -= a26 * b68
    b28 = acc * inv
    inv = 1.0 / a11
    acc = b10
    acc -= a12 * b20
    acc -= a13 * b30
    acc -= a14 * b40
    acc -= a15 * b50
    acc -= a16 * b60
    b10 = acc * inv
    acc = b11
    acc -= a12 * b21
    acc -= a13 * b31
    acc -= a14 * b41
    acc -= a15 * b51
    acc -= a16 * b61
    b11 = acc * inv
    acc = b12
    acc -= a12 * b22
    acc -= a13 * b32
    acc -= a14 * b42
    acc -= a15 * b52
    acc -= a16 * b62
    b12 = acc * inv
    acc = b13
    acc -= a12 * b23
    acc -= a13 * b33
    acc -= a14 * b43
    acc -= a15 * b53
    acc -= a16 * b63
    b13 = acc * inv
    acc = b14
    acc -= a12 * b24
    acc -= a13 * b34
    acc -= a14 * b44
    acc -= a15 * b54
    acc -= a16 * b64
    b14 = acc * inv
    acc = b15
    acc -= a12 * b25
    acc -= a13 * b35
    acc -= a14 * b45
    acc -= a15 * b55
    acc -= a16 * b65
    b15 = acc * inv
    acc = b16
    acc -= a12 * b26
    acc -= a13 * b36
    acc -= a14 * b46
    acc -= a15 * b56
    acc -= a16 * b66
    b16 = acc * inv
    acc = b17
    acc -= a12 * b27
    acc -= a13 * b37
    acc -= a14 * b47
    acc -= a15 * b57
    acc -= a16 * b67
    b17 = acc * inv
    acc = b18
    acc -= a12 * b28
    acc -= a13 * b38
    acc -= a14 * b48
    acc -= a15 * b58
    acc -= a16 * b68
    b18 = acc * inv
    inv = 1.0 / a00
    acc = b00
    acc -= a01 * b10
    acc -= a02 * b20
    acc -= a03 * b30
    acc -= a04 * b40
    acc -= a05 * b50
    acc -= a06 * b60
    b00 = acc * inv
    acc = b01
    acc -= a01 * b11
    acc -= a02 * b21
    acc -= a03 * b31
    acc -= a04 * b41
    acc -= a05 * b51
    acc -= a06 * b61
    b01 = acc * inv
    acc = b02
    acc -= a01 * b12
    acc -= a02 * b22
    acc -= a03 * b32
    acc -= a04 * b42
    acc -= a05 * b52
    acc -= a06 * b62
    b02 = acc * inv
    acc = b03
    acc -= a01 * b13
    acc -= a02 * b23
    acc -= a03 * b33
    acc -= a04 * b43
    acc -= a05 * b53
    acc -= a06 * b63
    b03 = acc * inv
    acc = b04
    acc -= a01 * b14
    acc -= a02 * b24
    acc -= a03 * b34
    acc -= a04 * b44
    acc -= a05 * b54
    acc -= a06 * b64
    b04 = acc * inv
    acc = b05
    acc -= a01 * b15
    acc -= a02 * b25
    acc -= a03 * b35
    acc -= a04 * b45
    acc -= a05 * b55
    acc -= a06 * b65
    b05 = acc * inv
    acc = b06
    acc -= a01 * b16
    acc -= a02 * b26
    acc -= a03 * b36
    acc -= a04 * b46
    acc -= a05 * b56
    acc -= a06 * b66
    b06 = acc * inv
    acc = b07
    acc -= a01 * b17
    acc -= a02 * b27
    acc -= a03 * b37
    acc -= a04 * b47
    acc -= a05 * b57
    acc -= a06 * b67
    b07 = acc * inv
    acc = b08
    acc -= a01 * b18
    acc -= a02 * b28
    acc -= a03 * b38
    acc -= a04 * b48
    acc -= a05 * b58
    acc -= a06 * b68
    b08 = acc * inv
    w[0, 0] = b00
    w[0, 1] = b01
    w[0, 2] = b02
    w[0, 3] = b03
    w[0, 4] = b04
    w[0, 5] = b05
    w[0, 6] = b06
    w[0, 7] = b07
    w[0, 8] = b08
    w[1, 0] = b10
    w[1, 1] = b11
    w[1, 2] = b12
    w[1, 3] = b13
    w[1, 4] = b14
    w[1, 5] = b15
    w[1, 6] = b16
    w[1, 7] = b17
    w[1, 8] = b18
    w[2, 0] = b20
    w[2, 1] = b21
    w[2, 2] = b22
    w[2, 3] = b23
    w[2, 4] = b24
    w[2, 5] = b25
    w[2, 6] = b26
    w[2, 7] = b27
    w[2, 8] = b28
    w[3, 0] = b30
    w[3, 1] = b31
    w[3, 2] = b32
    w[3, 3] = b33
    w[3, 4] = b34
    w[3, 5] = b35
    w[3, 6] = b36
    w[3, 7] = b37
    w[3, 8] = b38
    w[4, 0] = b40
    w[4, 1] = b41
    w[4, 2] = b42
    w[4, 3] = b43
    w[4, 4] = b44
    w[4, 5] = b45
    w[4, 6] = b46
    w[4, 7] = b47
    w[4, 8] = b48
    w[5, 0] = b50
    w[5, 1] = b51
    w[5, 2] = b52
    w[5, 3] = b53
    w[5, 4] = b54
    w[5, 5] = b55
    w[5, 6] = b56
    w[5, 7] = b57
    w[5, 8] = b58
    w[6, 0] = b60
    w[6, 1] = b61
    w[6, 2] = b62
    w[6, 3] = b63
    w[6, 4] = b64
    w[6, 5] = b65
    w[6, 6] = b66
    w[6, 7] = b67
    w[6, 8] = b68
    return True


@_jit
def _block_solve6(d, w):
    """
    Solve d[:6, :6] X = w[:6, 7:9] into w; False if it is singular.

    d and w are left untouched when False (a pivot zero or not finite).
    Generated by tools/gen_block_solves.py (why: there).
    """
    a00, a01, a02, a03, a04, a05 = (
        d[0, 0], d[0, 1], d[0, 2], d[0, 3], d[0, 4], d[0, 5])
    b07, b08 = (
        w[0, 7], w[0, 8])
    a10, a11, a12, a13, a14, a15 = (
        d[1, 0], d[1, 1], d[1, 2], d[1, 3], d[1, 4], d[1, 5])
    b17, b18 = (
        w[1, 7], w[1, 8])
    a20, a21, a22, a23, a24, a25 = (
        d[2, 0], d[2, 1], d[2, 2], d[2, 3], d[2, 4], d[2, 5])
    b27, b28 = (
        w[2, 7], w[2, 8])
    a30, a31, a32, a33, a34, a35 = (
        d[3, 0], d[3, 1], d[3, 2], d[3, 3], d[3, 4], d[3, 5])
    b37, b38 = (
        w[3, 7], w[3, 8])
    a40, a41, a42, a43, a44, a45 = (
        d[4, 0], d[4, 1], d[4, 2], d[4, 3], d[4, 4], d[4, 5])
    b47, b48 = (
        w[4, 7], w[4, 8])
    a50, a51, a52, a53, a54, a55 = (
        d[5, 0], d[5, 1], d[5, 2], d[5, 3], d[5, 4], d[5, 5])
    b57, b58 = (
        w[5, 7], w[5, 8])
    # column 0
    big = abs(a00)
    piv = 0
    if abs(a10) > big:
        big = abs(a10)
        piv = 1
    if abs(a20) > big:
        big = abs(a20)
        piv = 2
    if abs(a30) > big:
        big = abs(a30)
        piv = 3
    if abs(a40) > big:
        big = abs(a40)
        piv = 4
    if abs(a50) > big:
        big = abs(a50)
        piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 1:
        a00, a10 = a10, a00
        a01, a11 = a11, a01
        a02, a12 = a12, a02
        a03, a13 = a13, a03
        a04, a14 = a14, a04
        a05, a15 = a15, a05
        b07, b17 = b17, b07
        b08, b18 = b18, b08
    if piv == 2:
        a00, a20 = a20, a00
        a01, a21 = a21, a01
        a02, a22 = a22, a02
        a03, a23 = a23, a03
        a04, a24 = a24, a04
        a05, a25 = a25, a05
        b07, b27 = b27, b07
        b08, b28 = b28, b08
    if piv == 3:
        a00, a30 = a30, a00
        a01, a31 = a31, a01
        a02, a32 = a32, a02
        a03, a33 = a33, a03
        a04, a34 = a34, a04
        a05, a35 = a35, a05
        b07, b37 = b37, b07
        b08, b38 = b38, b08
    if piv == 4:
        a00, a40 = a40, a00
        a01, a41 = a41, a01
        a02, a42 = a42, a02
        a03, a43 = a43, a03
        a04, a44 = a44, a04
        a05, a45 = a45, a05
        b07, b47 = b47, b07
        b08, b48 = b48, b08
    if piv == 5:
        a00, a50 = a50, a00
        a01, a51 = a51, a01
        a02, a52 = a52, a02
        a03, a53 = a53, a03
        a04, a54 = a54, a04
        a05, a55 = a55, a05
        b07, b57 = b57, b07
        b08, b58 = b58, b08
    inv = 1.0 / a00
    fac = a10 * inv
    if fac != 0.0:
        a11 -= fac * a01
        a12 -= fac * a02
        a13 -= fac * a03
        a14 -= fac * a04
        a15 -= fac * a05
        b17 -= fac * b07
        b18 -= fac * b08
    fac = a20 * inv
    if fac != 0.0:
        a21 -= fac * a01
        a22 -= fac * a02
        a23 -= fac * a03
        a24 -= fac * a04
        a25 -= fac * a05
        b27 -= fac * b07
        b28 -= fac * b08
    fac = a30 * inv
    if fac != 0.0:
        a31 -= fac * a01
        a32 -= fac * a02
        a33 -= fac * a03
        a34 -= fac * a04
        a35 -= fac * a05
        b37 -= fac * b07
        b38 -= fac * b08
    fac = a40 * inv
    if fac != 0.0:
        a41 -= fac * a01
        a42 -= fac * a02
        a43 -= fac * a03
        a44 -= fac * a04
        a45 -= fac * a05
        b47 -= fac * b07
        b48 -= fac * b08
    fac = a50 * inv
    if fac != 0.0:
        a51 -= fac * a01
        a52 -= fac * a02
        a53 -= fac * a03
        a54 -= fac * a04
        a55 -= fac * a05
        b57 -= fac * b07
        b58 -= fac * b08
    # column 1
    big = abs(a11)
    piv = 1
    if abs(a21) > big:
        big = abs(a21)
        piv = 2
    if abs(a31) > big:
        big = abs(a31)
        piv = 3
    if abs(a41) > big:
        big = abs(a41)
        piv = 4
    if abs(a51) > big:
        big = abs(a51)
        piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 2:
        a11, a21 = a21, a11
        a12, a22 = a22, a12
        a13, a23 = a23, a13
        a14, a24 = a24, a14
        a15, a25 = a25, a15
        b17, b27 = b27, b17
        b18, b28 = b28, b18
    if piv == 3:
        a11, a31 = a31, a11
        a12, a32 = a32, a12
        a13, a33 = a33, a13
        a14, a34 = a34, a14
        a15, a35 = a35, a15
        b17, b37 = b37, b17
        b18, b38 = b38, b18
    if piv == 4:
        a11, a41 = a41, a11
        a12, a42 = a42, a12
        a13, a43 = a43, a13
        a14, a44 = a44, a14
        a15, a45 = a45, a15
        b17, b47 = b47, b17
        b18, b48 = b48, b18
    if piv == 5:
        a11, a51 = a51, a11
        a12, a52 = a52, a12
        a13, a53 = a53, a13
        a14, a54 = a54, a14
        a15, a55 = a55, a15
        b17, b57 = b57, b17
        b18, b58 = b58, b18
    inv = 1.0 / a11
    fac = a21 * inv
    if fac != 0.0:
        a22 -= fac * a12
        a23 -= fac * a13
        a24 -= fac * a14
        a25 -= fac * a15
        b27 -= fac * b17
        b28 -= fac * b18
    fac = a31 * inv
    if fac != 0.0:
        a32 -= fac * a12
        a33 -= fac * a13
        a34 -= fac * a14
        a35 -= fac * a15
        b37 -= fac * b17
        b38 -= fac * b18
    fac = a41 * inv
    if fac != 0.0:
        a42 -= fac * a12
        a43 -= fac * a13
        a44 -= fac * a14
        a45 -= fac * a15
        b47 -= fac * b17
        b48 -= fac * b18
    fac = a51 * inv
    if fac != 0.0:
        a52 -= fac * a12
        a53 -= fac * a13
        a54 -= fac * a14
        a55 -= fac * a15
        b57 -= fac * b17
        b58 -= fac * b18
    # column 2
    big = abs(a22)
    piv = 2
    if abs(a32) > big:
        big = abs(a32)
        piv = 3
    if abs(a42) > big:
        big = abs(a42)
        piv = 4
    if abs(a52) > big:
        big = abs(a52)
        piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 3:
        a22, a32 = a32, a22
        a23, a33 = a33, a23
        a24, a34 = a34, a24
        a25, a35 = a35, a25
        b27, b37 = b37, b27
        b28, b38 = b38, b28
    if piv == 4:
        a22, a42 = a42, a22
        a23, a43 = a43, a23
        a24, a44 = a44, a24
        a25, a45 = a45, a25
        b27, b47 = b47, b27
        b28, b48 = b48, b28
    if piv == 5:
        a22, a52 = a52, a22
        a23, a53 = a53, a23
        a24, a54 = a54, a24
        a25, a55 = a55, a25
        b27, b57 = b57, b27
        b28, b58 = b58, b28
    inv = 1.0 / a22
    fac = a32 * inv
    if fac != 0.0:
        a33 -= fac * a23
        a34 -= fac * a24
        a35 -= fac * a25
        b37 -= fac * b27
        b38 -= fac * b28
    fac = a42 * inv
    if fac != 0.0:
        a43 -= fac * a23
        a44 -= fac * a24
        a45 -= fac * a25
        b47 -= fac * b27
        b48 -= fac * b28
    fac = a52 * inv
    if fac != 0.0:
        a53 -= fac * a23
        a54 -= fac * a24
        a55 -= fac * a25
        b57 -= fac * b27
        b58 -= fac * b28
    # column 3
    big = abs(a33)
    piv = 3
    if abs(a43) > big:
        big = abs(a43)
        piv = 4
    if abs(a53) > big:
        big = abs(a53)
        piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 4:
        a33, a43 = a43, a33
        a34, a44 = a44, a34
        a35, a45 = a45, a35
        b37, b47 = b47, b37
        b38, b48 = b48, b38
    if piv == 5:
        a33, a53 = a53, a33
        a34, a54 = a54, a34
        a35, a55 = a55, a35
        b37, b57 = b57, b37
        b38, b58 = b58, b38
    inv = 1.0 / a33
    fac = a43 * inv
    if fac != 0.0:
        a44 -= fac * a34
        a45 -= fac * a35
        b47 -= fac * b37
        b48 -= fac * b38
    fac = a53 * inv
    if fac != 0.0:
        a54 -= fac * a34
        a55 -= fac * a35
        b57 -= fac * b37
        b58 -= fac * b38
    # column 4
    big = abs(a44)
    piv = 4
    if abs(a54) > big:
        big = abs(a54)
        piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    if piv == 5:
        a44, a54 = a54, a44
        a45, a55 = a55, a45
        b47, b57 = b57, b47
        b48, b58 = b58, b48
    inv = 1.0 / a44
    fac = a54 * inv
    if fac != 0.0:
        a55 -= fac * a45
        b57 -= fac * b47
        b58 -= fac * b48
    # column 5
    big = abs(a55)
    piv = 5
    if big == 0.0 or not math.isfinite(big):
        return False
    inv = 1.0 / a55
    # back-substitution
    inv = 1.0 / a55
    b57 = b57 * inv
    b58 = b58 * inv
    inv = 1.0 / a44
    acc = b47
    acc -= a45 * b57
    b47 = acc * inv
    acc = b48
    acc -= a45 * b58
    b48 = acc * inv
    inv = 1.0 / a33
    acc = b37
    acc -= a34 * b47
    acc -= a35 * b57
    b37 = acc * inv
    acc = b38
    acc -= a34 * b48
    acc -= a35 * b58
    b38 = acc * inv
    inv = 1.0 / a22
    acc = b27
    acc -= a23 * b37
    acc -= a24 * b47
    acc -= a25 * b57
    b27 = acc * inv
    acc = b28
    acc -= a23 * b38
    acc -= a24 * b48
    acc -= a25 * b58
    b28 = acc * inv
    inv = 1.0 / a11
    acc = b17
    acc -= a12 * b27
    acc -= a13 * b37
    acc -= a14 * b47
    acc -= a15 * b57
    b17 = acc * inv
    acc = b18
    acc -= a12 * b28
    acc -= a13 * b38
    acc -= a14 * b48
    acc -= a15 * b58
    b18 = acc * inv
    inv = 1.0 / a00
    acc = b07
    acc -= a01 * b17
    acc -= a02 * b27
    acc -= a03 * b37
    acc -= a04 * b47
    acc -= a05 * b57
    b07 = acc * inv
    acc = b08
    acc -= a01 * b18
    acc -= a02 * b28
    acc -= a03 * b38
    acc -= a04 * b48
    acc -= a05 * b58
    b08 = acc * inv
    w[0, 7] = b07
    w[0, 8] = b08
    w[1, 7] = b17
    w[1, 8] = b18
    w[2, 7] = b27
    w[2, 8] = b28
    w[3, 7] = b37
    w[3, 8] = b38
    w[4, 7] = b47
    w[4, 8] = b48
    w[5, 7] = b57
    w[5, 8] = b58
    return True


# --- end of generated code ---


@_jit
def solve_free_blocks(jac, res, free, nf, xs, fw, d, w, d0, w0, rows, direct, inv_s,
                      inv_rs):
    """
    Solve the blocks of the free balls free[:nf] into xs[k, :6, 7:9] (``newton_direction``).

    free holds (ball, block index k) pairs; fw (FB_ROWS * _CHUNK,) and the scalar solve's d,
    w, d0, w0 are work arrays.  ``direct``: the blocks are read in place from the
    evaluation's acc rows (``newton_direction``; the residual scaled by inv_s, inv_rs as
    there), every ball in its own lane, the chained ones solved too and not used.
    """
    n = res.shape[0]
    for c0 in range(0, nf, _CHUNK):
        m = n if direct else min(_CHUNK, nf - c0)
        # Lanes up to a multiple of 8 (the vector width) hold identity blocks: no remainder.
        mp = min(_CHUNK, (m + 7) // 8 * 8)
        if direct:
            # The padded lanes hold open contacts' zeros: singular blocks nobody reads.
            _lanes_gauss6_acc(rows, inv_s, inv_rs, fw, mp)
        else:
            for i in range(mp):
                if i < m:
                    b = free[c0 + i, 0]
                    for r in range(6):
                        for j in range(6):
                            fw[(8 * r + j) * _CHUNK + i] = jac[b, r, j]
                        fw[(8 * r + 6) * _CHUNK + i] = res[b, r]
                        fw[(8 * r + 7) * _CHUNK + i] = jac[b, r, 6]
                else:
                    for r in range(6):
                        for j in range(8):
                            fw[(8 * r + j) * _CHUNK + i] = 1.0 if j == r else 0.0
            _lanes_gauss6(fw, mp)
        for q in range(nf if direct else m):
            b = free[q if direct else c0 + q, 0]
            k = free[q if direct else c0 + q, 1]
            lane = b if direct else q
            if fw[_FB_BAD * _CHUNK + lane] == 0.0:
                for r in range(6):
                    xs[k, r, 7] = fw[(_FB_OUT + 2 * r) * _CHUNK + lane]
                    xs[k, r, 8] = fw[(_FB_OUT + 2 * r + 1) * _CHUNK + lane]
                continue
            for r in range(6):
                for j in range(7):
                    v = rows[(_ACC_JAC + 7 * j + r) * _CHUNK + b] if direct else jac[b, r, j]
                    if j < 6:
                        d[r, j] = v
                    else:
                        w[r, 8] = v
                w[r, 7] = res[b, r]
            gauss_solve(d, w, 6, 7, d0, w0)
            for r in range(6):
                xs[k, r, 7] = w[r, 7]
                xs[k, r, 8] = w[r, 8]
        if direct:
            break


@_jit
def newton_direction(seq, starts, rear_of, front_of, jac, dax, res, axial, cons, fhat, g_r,
                     g_f, dgr_r, dgr_f, dgf_r, dgf_f, xs, ys, dx, df, d, w, d0, w0, lm, free,
                     fbw, rows, direct, inv_s, inv_rs):
    """
    Newton step (dx, du, df) of the bordered block-tridiagonal system (module docstring).

    xs (N, 7, 9), ys (N, 7, 2), d, d0, lm (7, 7), w, w0 (7, 9), free (N, 2) (int),
    fbw (FB_ROWS * _CHUNK,): work arrays.  ``direct``: the balls' Jacobian is still in the
    evaluation's acc rows (``rows``, N <= _CHUNK; ``evaluate_lanes`` with jac empty): the
    free balls' blocks are read from there as they are, lanes and all, and only dax and the
    chained balls' blocks are copied into dax and jac (measured: copying 49 values of every
    ball out of the lanes, and the free balls' blocks back in, cost ~3 us of a 36 us warm
    step at N = 37).  Returns du; writes dx (N, 6), df (K,).
    """
    acc_y = 0.0
    acc_w = 0.0
    c_u = 0.0
    if direct:
        for j in range(7):
            src = (_ACC_JAC + 7 * j + 6) * _CHUNK
            for b in range(res.shape[0]):
                dax[b, j] = rows[src + b]
        for b in range(res.shape[0]):
            if rear_of[b] >= 0 or front_of[b] >= 0:
                for j in range(7):
                    for r in range(6):
                        jac[b, r, j] = rows[(_ACC_JAC + 7 * j + r) * _CHUNK + b]
    for b in range(res.shape[0]):
        c_u += dax[b, 6]
    # The free balls' blocks first, all at once (solve_free_blocks); the chains below.
    nf = 0
    for k in range(seq.shape[0]):
        b = seq[k]
        if rear_of[b] < 0 and front_of[b] < 0:
            free[nf, 0] = b
            free[nf, 1] = k
            nf += 1
    solve_free_blocks(jac, res, free, nf, xs, fbw, d, w, d0, w0, rows, direct, inv_s, inv_rs)
    for ch in range(starts.shape[0] - 1):
        k0, k1 = starts[ch], starts[ch + 1]
        for k in range(k0, k1):
            b = seq[k]
            c = rear_of[b]
            cp = front_of[b]
            if c < 0 and cp < 0:
                xs[k, 6, 7] = 0.0
                xs[k, 6, 8] = 0.0
                continue
            # Block k: rows = ball b's six equations and (if b is the rear of contact c)
            # equal orbit rates across c; columns = b's states and the force of c.  Without c
            # (a chain's end or a free ball) U = 0 and the block is the 6 x 6 ball alone.
            nd = 7 if c >= 0 else 6
            for r in range(6):
                for j in range(6):
                    d[r, j] = jac[b, r, j]
                w[r, 7] = res[b, r]
                w[r, 8] = jac[b, r, 6]
            if c >= 0:
                fc = fhat[c]
                for r in range(6):
                    for j in range(6):
                        d[r, j] += fc * dgr_r[c, r, j]
                        w[r, j] = fc * dgr_f[c, r, j]
                    d[r, 6] = g_r[c, r]
                    w[r, 6] = 0.0
                for j in range(7):
                    d[6, j] = 0.0
                    w[6, j] = 0.0
                d[6, 2] = 1.0
                w[6, 2] = -1.0
                w[6, 7] = cons[c]
                w[6, 8] = 0.0
            if cp >= 0:
                fp = fhat[cp]
                for r in range(6):
                    for j in range(6):
                        d[r, j] += fp * dgf_f[cp, r, j]
            if k > k0:
                # L block: this ball's rows on the previous block (its x and the force cp).
                fp = fhat[cp]
                for r in range(6):
                    for j in range(6):
                        lm[r, j] = fp * dgf_r[cp, r, j]
                    lm[r, 6] = g_f[cp, r]
                for r in range(6):
                    for j in range(9):
                        if j >= nd and j < 7:
                            continue
                        acc = 0.0
                        for m in range(7):
                            acc += lm[r, m] * xs[k - 1, m, j]
                        if j < 7:
                            d[r, j] -= acc
                        else:
                            w[r, j] -= acc
            ok = _block_solve7(d, w) if c >= 0 else _block_solve6(d, w)
            if not ok:      # a zero or non-finite pivot: gauss_solve's shifted retry
                gauss_solve(d, w, nd, 0 if c >= 0 else 7, d0, w0)
            if c >= 0:
                for r in range(7):
                    for j in range(9):
                        xs[k, r, j] = w[r, j]
            else:
                for r in range(6):
                    xs[k, r, 7] = w[r, 7]
                    xs[k, r, 8] = w[r, 8]
                xs[k, 6, 7] = 0.0
                xs[k, 6, 8] = 0.0
        for k in range(k1 - 1, k0 - 1, -1):
            back_substitute_block(xs, ys, k, k == k1 - 1)
            b = seq[k]
            for r in range(6):
                acc_y += dax[b, r] * ys[k, r, 0]
                acc_w += dax[b, r] * ys[k, r, 1]
    du = (axial - acc_y) / (c_u - acc_w)
    for k in range(seq.shape[0]):
        b = seq[k]
        for r in range(6):
            dx[b, r] = -(ys[k, r, 0] - ys[k, r, 1] * du)
        c = rear_of[b]
        if c >= 0:
            df[c] = -(ys[k, 6, 0] - ys[k, 6, 1] * du)
    return -du


@_jit
def add_b2b_forces(x, rear, front, g_r, g_f, fhat, res, cons):
    """
    Add each B2B pair's force (``fhat`` along ``g_r``/``g_f``) to its two balls' residuals.

    Also writes the pair's constraint residual into ``cons``.  One loop for the rigid and
    the elastic residual.
    """
    for c in range(rear.shape[0]):
        r = rear[c]
        f = front[c]
        for j in range(6):
            res[r, j] += g_r[c, j] * fhat[c]
            res[f, j] += g_f[c, j] * fhat[c]
        cons[c] = x[r, 2] - x[f, 2]


@_jit
def _residual(x, u, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid,
              scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, res, jac, dax, terms,
              per_contact, g_r, g_f, speed, dgr_r, dgr_f, dgf_r, dgf_f, cons, want_jac, u_ball,
              ew, bw):
    """
    Full residual (balls + B2B + axial + equal rates) and Jacobian; returns (axial, norm).

    u_ball (N,): zeros; ew (WORK_SIZE,), bw (B2B_WORK_SIZE,): the evaluation's work arrays.
    """
    ax = evaluate_lanes(x, u, u_ball, centres, sign, cst, k_load, k_axis, on_nut, coef_s,
                        coef_n, grid, scale, want_jac, res, jac, dax, terms, per_contact, ew)
    b2b_terms_into(x, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, want_jac, g_r, g_f, speed,
                   dgr_r, dgr_f, dgf_r, dgf_f, bw)
    add_b2b_forces(x, rear, front, g_r, g_f, fhat, res, cons)
    axial = (ax + axial_load_n) / scale
    norm = abs(axial)
    for i in range(res.shape[0]):
        for j in range(6):
            v = abs(res[i, j])
            if v > norm or v != v:
                norm = v
    for c in range(rear.shape[0]):
        v = abs(cons[c])
        if v > norm or v != v:
            norm = v
    return axial, norm


@_jit
def solve_active(x, u, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                 grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, tol,
                 max_it, max_rate, disp_limit):
    """
    ``newton`` for a rigid nut and shaft (one nut displacement u, a float).

    Same iteration as ``EquilibriumSolver.solve_active`` (numpy path) with the exact
    Jacobian.  Returns (x, u, fhat, ok, iterations, norm, terms, per_contact, speed).
    """
    ua = np.empty(1)
    ua[0] = u
    x, ua, fhat, ok, it, norm, terms, per_contact, speed = newton(
        x, ua, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale,
        axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, np.zeros(0, dtype=np.int64),
        np.zeros(0), np.zeros(0), tol, max_it, max_rate, disp_limit, np.empty(0),
        np.empty(0, dtype=np.int64))
    return x, ua[0], fhat, ok, it, norm, terms, per_contact, speed


@_jit
def ring_projection(azimuth, separation, loop_length):
    """``whole_screw.isotonic_ring_projection``: PAV on the ring cut at its largest gap."""
    n = azimuth.shape[0]
    out = np.empty(n)
    _ring_projection_into(azimuth, separation, loop_length, out, np.empty((3, n)),
                          np.empty(n, dtype=np.int64))
    return out


@_jit
def _ring_projection_into(azimuth, separation, loop_length, out, work, counts):
    """``ring_projection`` into out (N, not azimuth); work (3, N), counts (N,): work."""
    n = azimuth.shape[0]
    worst = np.inf
    best = -np.inf
    cut = 0
    for i in range(n):
        nxt = azimuth[i + 1] if i + 1 < n else azimuth[0] + loop_length
        gap = nxt - azimuth[i] - separation
        worst = min(worst, gap)
        if gap > best:
            best = gap
            cut = i + 1
    if worst >= 0.0:
        for i in range(n):
            out[i] = azimuth[i]
        return
    y = work[0]
    fitted = work[2]
    for k in range(n):
        j = (k + cut) % n
        y[k] = azimuth[j] + (loop_length if j < cut else 0.0) - k * separation
    _pav_into(y, work[1], counts, fitted)
    for k in range(n):
        j = (k + cut) % n
        out[j] = fitted[k] + k * separation - (loop_length if j < cut else 0.0)


@_jit
def pool_adjacent_violators(y):
    """L2 projection of y onto non-decreasing sequences (pool-adjacent-violators)."""
    n = y.shape[0]
    out = np.empty(n)
    _pav_into(y, np.empty(n), np.empty(n, dtype=np.int64), out)
    return out


@_jit
def _pav_into(y, means, counts, out):
    """``pool_adjacent_violators`` into out (N, not y); means, counts (N,): work."""
    n = y.shape[0]
    nb = 0
    for i in range(n):
        means[nb] = y[i]
        counts[nb] = 1
        nb += 1
        while nb > 1 and means[nb - 2] > means[nb - 1]:
            c = counts[nb - 2] + counts[nb - 1]
            means[nb - 2] = (means[nb - 2] * counts[nb - 2]
                             + means[nb - 1] * counts[nb - 1]) / c
            counts[nb - 2] = c
            nb -= 1
    k = 0
    for b in range(nb):
        for _ in range(counts[b]):
            out[k] = means[b]
            k += 1


@_jit
def ring_pairs(azimuth, separation, loop_length, gap_tolerance, sign):
    """
    ``WholeScrew._pairs``: touching ring pairs (index, rear, front) in chain order.

    Pair j is (ball j, ball j+1); the order starts after the largest gap (chains never cross
    it) and runs against the loop for sign < 0.
    """
    n = azimuth.shape[0]
    idx = np.empty(n, dtype=np.int64)
    rear = np.empty(n, dtype=np.int64)
    front = np.empty(n, dtype=np.int64)
    k = _ring_pairs_into(azimuth, separation, loop_length, gap_tolerance, sign,
                         np.empty(n, dtype=np.bool_), idx, rear, front)
    return idx[:k], rear[:k], front[:k]


@_jit
def _ring_pairs_into(azimuth, separation, loop_length, gap_tolerance, sign, touching, idx, rear,
                     front):
    """``ring_pairs`` into the caller's arrays (N,) (touching: work); returns the pair count."""
    n = azimuth.shape[0]
    best = -np.inf
    start = 0
    for i in range(n):
        nxt = azimuth[i + 1] if i + 1 < n else azimuth[0] + loop_length
        gap = nxt - azimuth[i] - separation
        touching[i] = gap <= gap_tolerance
        if gap > best:
            best = gap
            start = i + 1
    k = 0
    for m in range(n):
        j = (start + (m if sign > 0 else n - 1 - m)) % n
        if touching[j]:
            idx[k] = j
            k += 1
    for c in range(k):
        nxt = (idx[c] + 1) % n
        rear[c] = idx[c] if sign > 0 else nxt
        front[c] = nxt if sign > 0 else idx[c]
    return k


@_jit
def pair_speed(x, rear, front, b_r, b_f):
    """|B_r x_rear + B_f x_front| per pair: the B2B slip speed (``b2b.linear_terms``)."""
    out = np.empty(rear.shape[0])
    _pair_speed_into(x, rear, front, b_r, b_f, out)
    return out


@_jit
def _pair_speed_into(x, rear, front, b_r, b_f, out):
    """``pair_speed`` into out (K,)."""
    for c in range(rear.shape[0]):
        acc = 0.0
        for a in range(3):
            v = 0.0
            for j in range(6):
                v += b_r[a, j] * x[rear[c], j] + b_f[a, j] * x[front[c], j]
            acc += v * v
        out[c] = math.sqrt(acc)


@_jit
def step_totals(loss, nut_torque, load, forces, speed, active, pair_idx, x, sign):
    """
    Sum and scatter what ``WholeScrew._finish`` needs, in one call.

    Measured need: the eight numpy calls it replaces cost about 10 us of a step at
    N = 37.  Returns (sum of the ball-groove losses, sum of the nut torques, sum of the B2B
    force times slip speed, largest contact load, orbit ratio x[:, 2] sign per ball, active
    and force per ring pair, indices of the active candidate pairs).
    """
    n = x.shape[0]
    ratio = np.empty(n)
    ring_active = np.empty(n, dtype=np.bool_)
    ring_forces = np.empty(n)
    act = np.empty(pair_idx.shape[0], dtype=np.int64)
    loss_sum, torque_sum, b2b, load_max, count = _step_totals_into(
        loss, nut_torque, load, forces, speed, active, pair_idx, x, sign, ratio, ring_active,
        ring_forces, act)
    return loss_sum, torque_sum, b2b, load_max, ratio, ring_active, ring_forces, act[:count]


@_jit
def _step_totals_into(loss, nut_torque, load, forces, speed, active, pair_idx, x, sign, ratio,
                      ring_active, ring_forces, act):
    """
    ``step_totals`` into the caller's arrays: ratio, ring_active, ring_forces (N,), act (K,).

    Returns (its four sums, the number of active pairs: act's length in use).
    """
    n = x.shape[0]
    loss_sum = 0.0
    torque_sum = 0.0
    load_max = -np.inf
    for i in range(n):
        loss_sum += loss[i]
        torque_sum += nut_torque[i]
        for k in range(load.shape[1]):
            load_max = max(load_max, load[i, k])
    b2b = 0.0
    for c in range(forces.shape[0]):
        b2b += forces[c] * speed[c]
    for i in range(n):
        ratio[i] = x[i, 2] * sign
    for i in range(n):
        ring_active[i] = False
        ring_forces[i] = 0.0
    for c in range(pair_idx.shape[0]):
        ring_active[pair_idx[c]] = active[c]
        ring_forces[pair_idx[c]] = forces[c]
    count = 0
    for c in range(pair_idx.shape[0]):
        if active[c]:
            act[count] = c
            count += 1
    return loss_sum, torque_sum, b2b, load_max, count


@_jit
def theta_centres(phi, amplitude, cycles, phase, offset, eccentricity, beta0):
    """
    theta(phi) and the arc centres (N, 4, 2) without lead errors, in one pass.

    Same as ``geometry.theta_deviation`` then ``geometry.arc_centres`` with zero shifts;
    eccentricity = R_G - R_B.
    """
    n = phi.shape[0]
    theta = np.empty(n)
    out = np.empty((n, 4, 2))
    _theta_centres_into(phi, amplitude, cycles, phase, offset, eccentricity, beta0, theta, out,
                        np.empty(4 * n))
    return theta, out


@_jit(exact=True)
def _theta_centres_into(phi, amplitude, cycles, phase, offset, eccentricity, beta0, theta, out,
                        tmp):
    """
    ``theta_centres`` into theta (N,) and out (N, 4, 2); tmp (4 N,): work.

    sin and cos by ``sincos_poly``, in loops that vectorise (theta, then the sines and
    cosines of beta0 -/+ theta into tmp, then the centres: one loop of it all, or stores
    into out's (N, 4, 2) layout, stayed scalar: measured); libm beyond its range.
    """
    n = phi.shape[0]
    cb = eccentricity * math.cos(beta0)
    sb = eccentricity * math.sin(beta0)
    big = abs(beta0) + abs(offset) + abs(amplitude) >= _TRIG_LIMIT
    for i in range(n):
        big = big or not abs(cycles * phi[i] + phase) < _TRIG_LIMIT
    if big:
        for i in range(n):
            th = offset + amplitude * math.sin(cycles * phi[i] + phase)
            theta[i] = th
            tmp[i] = math.sin(beta0 - th)
            tmp[n + i] = math.cos(beta0 - th)
            tmp[2 * n + i] = math.sin(beta0 + th)
            tmp[3 * n + i] = math.cos(beta0 + th)
    else:
        for i in range(n):
            theta[i] = offset + amplitude * sincos_poly(cycles * phi[i] + phase)[0]
        for i in range(n):
            th = theta[i]
            sm, cm = sincos_poly(beta0 - th)
            sp, cp = sincos_poly(beta0 + th)
            tmp[i] = sm
            tmp[n + i] = cm
            tmp[2 * n + i] = sp
            tmp[3 * n + i] = cp
    for i in range(n):
        out[i, 0, 0] = eccentricity * tmp[n + i]
        out[i, 0, 1] = eccentricity * tmp[i]
        out[i, 1, 0] = eccentricity * tmp[3 * n + i]
        out[i, 1, 1] = -eccentricity * tmp[2 * n + i]
        out[i, 2, 0] = -cb
        out[i, 2, 1] = -sb
        out[i, 3, 0] = -cb
        out[i, 3, 1] = sb


@_jit(exact=True)
def advance(azimuth, ratio, d_psi, separation, loop_length, track_start, gap_tolerance, sign,
            amplitude, cycles, phase, offset, eccentricity, beta0):
    """
    Advance the balls and return the step's geometry (no lead errors; ``WholeScrew.step``).

    Balls advanced by ratio * d_psi and projected (``ring_projection``; rounded as the numpy
    expression it replaces, hence exact); their azimuth in the
    loaded track, which starts at ``track_start`` (nut angle + track start [rad]);
    ``theta_centres`` there; the touching pairs (``ring_pairs``).  Returns (azimuth, phi,
    theta, centres, pair index, rear, front).  Measured need: four calls and
    the numpy between them cost about 15 us of a 230 us step at N = 37.
    """
    n = azimuth.shape[0]
    az = np.empty(n)
    phi = np.empty(n)
    theta = np.empty(n)
    centres = np.empty((n, 4, 2))
    idx = np.empty(n, dtype=np.int64)
    rear = np.empty(n, dtype=np.int64)
    front = np.empty(n, dtype=np.int64)
    k = _advance_into(azimuth, ratio, d_psi, separation, loop_length, track_start,
                      gap_tolerance, sign, amplitude, cycles, phase, offset, eccentricity,
                      beta0, np.empty((4, n)), az, phi, theta, centres,
                      np.empty(n, dtype=np.bool_), np.empty(n, dtype=np.int64), idx, rear,
                      front)
    return az, phi, theta, centres, idx[:k], rear[:k], front[:k]


@_jit(exact=True)
def _track_azimuth_into(az, track_start, loop_length, phi):
    """
    Write phi = track_start + np.mod(az - track_start, loop_length), rounded as numpy does.

    np.mod is fmod (exact) then + L when negative: the exact d - floor(d / L) L rounded
    once, which one fused multiply-add gives, in a loop that vectorises (numba's np.mod is a
    call per ball: 0.7 % of a warm step, measured).  Where floor(d / L) was rounded to the
    next integer (the result outside [0, L)), and for a NaN, np.mod itself.
    """
    n = az.shape[0]
    outside = False
    for i in range(n):
        d = az[i] - track_start
        r = fused_multiply_add(-np.floor(d / loop_length), loop_length, d)
        outside |= not ((r >= 0.0) & (r < loop_length))
        phi[i] = track_start + r
    if outside:
        for i in range(n):
            phi[i] = track_start + np.mod(az[i] - track_start, loop_length)


@_jit(exact=True)
def _advance_into(azimuth, ratio, d_psi, separation, loop_length, track_start, gap_tolerance,
                  sign, amplitude, cycles, phase, offset, eccentricity, beta0, work, az, phi,
                  theta, centres, touching, counts, idx, rear, front):
    """
    ``advance`` into the caller's arrays (N,) and centres (N, 4, 2); returns the pair count.

    work (4, N), touching and counts (N,): work.
    """
    n = azimuth.shape[0]
    moved = work[0]
    for i in range(n):
        moved[i] = azimuth[i] + ratio[i] * d_psi
    _ring_projection_into(moved, separation, loop_length, az, work[1:], counts)
    _track_azimuth_into(az, track_start, loop_length, phi)
    # work is free again: the projection is done with it.
    _theta_centres_into(phi, amplitude, cycles, phase, offset, eccentricity, beta0, theta,
                        centres, work.reshape(4 * n))
    return _ring_pairs_into(az, separation, loop_length, gap_tolerance, sign, touching, idx,
                            rear, front)

# --- Elastic load distribution (shaft and nut deform axially between balls; ref. [19]) ---
#
# Unknowns per ball b_k, in axial order k = 0..N-1 along the nut (``order``): its six states,
# its own nut displacement v_k (u of the rigid model, now per ball) and the cumulative load
# C_k = P_0 + ... + P_k carried into the nut by balls 0..k (P = -axial, scaled by ``scale``).
# Equations per ball: its six equilibrium equations; load transfer C_k - C_{k-1} - P_k = 0;
# compatibility of the two bars between balls k and k+1,
#     v_{k+1} - v_k = comp_a[k] - comp_b[k] C_k              (k < N-1)
# (``whole_screw.ElasticLoadPath`` derives comp_a, comp_b), and C_{N-1} = W at the last ball.
# Every row involves only blocks k-1, k, k+1: the Newton system is block tridiagonal in axial
# order (9 x 9 blocks: six states, v, C and the force of the B2B contact behind ball k).  A
# B2B contact across the return tube (between the last and the first ball) is the one
# border unknown.  The cost per iteration stays linear in N.


# elastic_direction's block work: d, w, d0, w0, L (9 x 9 or 9 x 11), the role's terms (6)
# and its two 6 x 6 derivatives.
ELASTIC_WORK_SIZE = 3 * 81 + 2 * 99 + 6 + 72


@_jit
def _elastic_blocks(order, pos, rear, front, n):
    """Active pair behind / ahead of each axial position, and the return-tube pair (or -1)."""
    behind = np.full(n, -1, dtype=np.int64)
    ahead = np.full(n, -1, dtype=np.int64)
    wrap = -1
    for c in range(rear.shape[0]):
        r = rear[c]
        f = front[c]
        if (r + 1) % n == f:
            lo, hi = r, f
        else:
            lo, hi = f, r
        if pos[hi] == 0:
            wrap = c
        else:
            behind[pos[hi]] = c
            ahead[pos[lo]] = c
    return behind, ahead, wrap


@_jit
def _elastic_residual(x, v, cum, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s,
                      coef_n, grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f,
                      order, comp_a, comp_b, res, jac, dax, terms, per_contact, g_r, g_f,
                      speed, dgr_r, dgr_f, dgf_r, dgf_f, cons, tr, cp, want_jac, ew, bw):
    """Residuals of the elastic system (see above) and the Jacobian pieces; returns the norm."""
    evaluate_lanes(x, 0.0, v, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid,
                   scale, want_jac, res, jac, dax, terms, per_contact, ew)
    b2b_terms_into(x, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, want_jac, g_r, g_f, speed,
                   dgr_r, dgr_f, dgf_r, dgf_f, bw)
    add_b2b_forces(x, rear, front, g_r, g_f, fhat, res, cons)
    n = x.shape[0]
    inv_s = 1.0 / scale
    for k in range(n):
        b = order[k]
        tr[k] = cum[k] - (cum[k - 1] if k > 0 else 0.0) + terms[b, 8] * inv_s
        if k < n - 1:
            cp[k] = v[order[k + 1]] - v[b] - comp_a[k] + comp_b[k] * cum[k]
        else:
            cp[k] = cum[k] - axial_load_n * inv_s
    norm = 0.0
    for i in range(n):
        for j in range(6):
            val = abs(res[i, j])
            if val > norm or val != val:
                norm = val
        for val in (abs(tr[i]), abs(cp[i])):
            if val > norm or val != val:
                norm = val
    for c in range(rear.shape[0]):
        val = abs(cons[c])
        if val > norm or val != val:
            norm = val
    return norm


@_jit
def _role(c, b, rear, g_r, g_f, dgr_r, dgr_f, dgf_r, dgf_f, gv, d_own, d_other):
    """Unit-force terms of contact c on ball b (rear or front) and their state derivatives."""
    if rear[c] == b:
        for r in range(6):
            gv[r] = g_r[c, r]
            for j in range(6):
                d_own[r, j] = dgr_r[c, r, j]
                d_other[r, j] = dgr_f[c, r, j]
        return 1.0
    for r in range(6):
        gv[r] = g_f[c, r]
        for j in range(6):
            d_own[r, j] = dgf_f[c, r, j]
            d_other[r, j] = dgf_r[c, r, j]
    return -1.0


@_jit
def elastic_direction(order, behind, ahead, wrap, rear, jac, dax, res, tr, cp, cons, fhat,
                      comp_b, g_r, g_f, dgr_r, dgr_f, dgf_r, dgf_f, xs, ys, dx, dv, dcum, df,
                      bw):
    """
    Newton step of the elastic system.

    A block Thomas sweep in axial order with the return-tube contact as a border.  The
    derivatives of that one contact's friction
    direction with respect to the other ball are left out of the Jacobian (its residual
    stays exact; only that contact converges linearly).  Returns the border force step.

    xs (N, 9, 11) and ys (N, 9, 2): work arrays, and bw (ELASTIC_WORK_SIZE,) for the
    blocks (``newton``'s, not allocated per call).  Writes dx (N, 6), dv (N,), dcum (N,),
    df (K,).
    """
    n = order.shape[0]
    d = carved(bw, 0, (9, 9))
    w = carved(bw, 81, (9, 11))
    d0 = carved(bw, 180, (9, 9))
    w0 = carved(bw, 261, (9, 11))
    # Of L only the entries written below for a contact behind are ever read: not cleared.
    lm = carved(bw, 360, (9, 9))
    gv = bw[441:447]
    d_own = carved(bw, 447, (6, 6))
    d_other = carved(bw, 483, (6, 6))
    for k in range(n):
        b = order[k]
        for r in range(9):
            for j in range(9):
                d[r, j] = 0.0
            for j in range(11):
                w[r, j] = 0.0
        for r in range(6):
            for j in range(7):
                d[r, j] = jac[b, r, j]
            w[r, 9] = res[b, r]
        for j in range(7):
            d[6, j] = dax[b, j]
        d[6, 7] = 1.0
        w[6, 9] = tr[k]
        if k < n - 1:
            d[7, 6] = -1.0
            d[7, 7] = comp_b[k]
            w[7, 6] = 1.0          # U block: v of the next ball
        else:
            d[7, 7] = 1.0
        w[7, 9] = cp[k]
        c = behind[k]
        if c >= 0:
            fc = fhat[c]
            s_rear = _role(c, b, rear, g_r, g_f, dgr_r, dgr_f, dgf_r, dgf_f, gv, d_own,
                           d_other)
            for r in range(6):
                d[r, 8] = gv[r]
                for j in range(6):
                    d[r, j] += fc * d_own[r, j]
                    lm[r, j] = fc * d_other[r, j]
            # equal orbit rates: x_rear[2] - x_front[2] = 0
            d[8, 2] = s_rear
            lm[8, 2] = -s_rear
            w[8, 9] = cons[c]
        else:
            d[8, 8] = 1.0
        c = ahead[k]
        if c >= 0:
            fc = fhat[c]
            _role(c, b, rear, g_r, g_f, dgr_r, dgr_f, dgf_r, dgf_f, gv, d_own, d_other)
            for r in range(6):
                w[r, 8] = gv[r]    # U block: force of the contact ahead (next block)
                for j in range(6):
                    d[r, j] += fc * d_own[r, j]
                    w[r, j] = fc * d_other[r, j]
        if wrap >= 0 and (k == 0 or k == n - 1):
            fc = fhat[wrap]
            _role(wrap, b, rear, g_r, g_f, dgr_r, dgr_f, dgf_r, dgf_f, gv, d_own, d_other)
            for r in range(6):
                w[r, 10] = gv[r]
                for j in range(6):
                    d[r, j] += fc * d_own[r, j]
        if k > 0:
            # L is sparse: the load-transfer row on C_{k-1} always; with a B2B contact
            # behind, the ball rows on the previous ball's states and the equal-rate row.
            for j in range(11):
                if j < 9:
                    d[6, j] += xs[k - 1, 7, j]
                else:
                    w[6, j] += xs[k - 1, 7, j]
            if behind[k] >= 0:
                for r in range(6):
                    for j in range(11):
                        acc = 0.0
                        for m in range(6):
                            acc += lm[r, m] * xs[k - 1, m, j]
                        if j < 9:
                            d[r, j] -= acc
                        else:
                            w[r, j] -= acc
                for j in range(11):
                    acc = lm[8, 2] * xs[k - 1, 2, j]
                    if j < 9:
                        d[8, j] -= acc
                    else:
                        w[8, j] -= acc
        # Nothing ahead: the columns of the next ball's states and force (0..5, 8) are zero,
        # and so is their solution; solved from column 6 (the same arithmetic elsewhere).
        gauss_solve(d, w, 9, 0 if ahead[k] >= 0 else 6, d0, w0)
        for r in range(9):
            for j in range(11):
                xs[k, r, j] = w[r, j]
    for k in range(n - 1, -1, -1):
        back_substitute_block(xs, ys, k, k == n - 1)
    dfw = 0.0
    if wrap >= 0:
        # Border row: equal orbit rates across the return tube (rear minus front).
        kr = 0 if rear[wrap] == order[0] else n - 1
        kf = n - 1 - kr
        row_y = ys[kr, 2, 0] - ys[kf, 2, 0]
        row_z = ys[kr, 2, 1] - ys[kf, 2, 1]
        dfw = (cons[wrap] - row_y) / row_z
        df[wrap] = dfw
    for k in range(n):
        b = order[k]
        for r in range(6):
            dx[b, r] = -(ys[k, r, 0] + ys[k, r, 1] * dfw)
        dv[b] = -(ys[k, 6, 0] + ys[k, 6, 1] * dfw)
        dcum[k] = -(ys[k, 7, 0] + ys[k, 7, 1] * dfw)
        c = behind[k]
        if c >= 0:
            df[c] = -(ys[k, 8, 0] + ys[k, 8, 1] * dfw)
    return dfw


@_jit
def _carve(ws, off, shape):
    """Return a view of ws[off:] of ``shape`` (C order) and the offset after it."""
    size = 1
    for d in shape:
        size *= d
    return carved(ws, off, shape), off + size


@_jit
def _eval_arrays(ws, off, n, kc):
    """
    Carve the work arrays of one evaluation from ws at off: (arrays, next offset).

    ``_residual`` uses 13 and u_ball (the 16th, zeros), ``_elastic_residual`` the first 15.
    """
    res, off = _carve(ws, off, (n, 6))
    jac, off = _carve(ws, off, (n, 6, 7))
    dax, off = _carve(ws, off, (n, 7))
    terms, off = _carve(ws, off, (n, 10))
    per_contact, off = _carve(ws, off, (n, 4, 3))
    g_r, off = _carve(ws, off, (kc, 6))
    g_f, off = _carve(ws, off, (kc, 6))
    speed, off = _carve(ws, off, (kc,))
    dgr_r, off = _carve(ws, off, (kc, 6, 6))
    dgr_f, off = _carve(ws, off, (kc, 6, 6))
    dgf_r, off = _carve(ws, off, (kc, 6, 6))
    dgf_f, off = _carve(ws, off, (kc, 6, 6))
    cons, off = _carve(ws, off, (kc,))
    tr, off = _carve(ws, off, (n,))
    cp, off = _carve(ws, off, (n,))
    u_ball, off = _carve(ws, off, (n,))
    for i in range(n):
        u_ball[i] = 0.0
    return (res, jac, dax, terms, per_contact, g_r, g_f, speed, dgr_r, dgr_f, dgf_r, dgf_f,
            cons, tr, cp, u_ball), off


@_jit
def newton_work_size(n):
    """Floats and integers of ``newton``'s work arrays for n balls (``work_arrays``)."""
    per_eval = 80 * n + 158 * n
    return (2 * per_eval + 141 * n + 3 * n + WORK_SIZE + B2B_WORK_SIZE + ELASTIC_WORK_SIZE
            + 441 + FB_ROWS * _CHUNK, 7 * n + 1)


def work_arrays(n):
    """
    Work arrays (float, int) that ``newton`` and its callers reuse for n balls.

    newton's share, then the warm step's (``step_work_size``).  Given these, ``newton``
    returns views of them (``_newton_result``): for compiled callers only.
    """
    nf, ni = newton_work_size(n)
    sf, si = step_work_size(n)
    return np.empty(nf + sf), np.empty(ni + si, dtype=np.int64)


@_jit
def solve_active_elastic(x, v, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s,
                         coef_n, grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r,
                         k_f, order, comp_a, comp_b, tol, max_it, max_rate, disp_limit):
    """
    ``newton`` for the elastic load distribution: v (N,) per-ball nut displacements.

    Returns (x, v, fhat, ok, iterations, norm, terms, per_contact, speed).
    """
    return newton(x, v, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid,
                  scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a,
                  comp_b, tol, max_it, max_rate, disp_limit, np.empty(0),
                  np.empty(0, dtype=np.int64))


@_jit
def newton(x, u, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid,
           scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b,
           tol, max_it, max_rate, disp_limit, ws, wi):
    """``_newton`` with work arrays of at least ``newton_work_size`` (allocated if smaller)."""
    nf, ni = newton_work_size(x.shape[0])
    if ws.shape[0] < nf or wi.shape[0] < ni:
        ws = np.empty(nf)
        wi = np.empty(ni, dtype=np.int64)
    # Passed on as arguments, so that _newton may borrow them (compiled.borrowed).
    return _newton(x, u, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                   grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order,
                   comp_a, comp_b, tol, max_it, max_rate, disp_limit, ws, wi)


@_jit
def _newton(x, u, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid,
            scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a,
            comp_b, tol, max_it, max_rate, disp_limit, ws, wi):
    """
    Newton with trust region and halving line search for one active set, either load path.

    The one compiled Newton iteration.  Rigid nut and shaft (``order`` empty): u (1,) is the
    shared nut displacement; the system is block tridiagonal along each chain, bordered by u
    (``newton_direction``).  Elastic
    load path (``order``: ball ids in axial order): u (N,) are the per-ball displacements and
    the cumulative loads C_k are unknowns too, starting from the balls' current axial forces;
    the system is block tridiagonal in axial order (``elastic_direction``).  Same iteration as
    ``EquilibriumSolver.solve_active`` (numpy path) with the exact Jacobian.  Returns (x, u,
    fhat, ok, iterations, norm, terms, per_contact, speed).
    """
    x = borrowed(x)
    u = borrowed(u)
    fhat = borrowed(fhat)
    centres = borrowed(centres)
    cst = borrowed(cst)
    k_load = borrowed(k_load)
    k_axis = borrowed(k_axis)
    on_nut = borrowed(on_nut)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    grid = borrowed(grid)
    rear = borrowed(rear)
    front = borrowed(front)
    b_r = borrowed(b_r)
    b_f = borrowed(b_f)
    c_r = borrowed(c_r)
    c_f = borrowed(c_f)
    k_r = borrowed(k_r)
    k_f = borrowed(k_f)
    order = borrowed(order)
    comp_a = borrowed(comp_a)
    comp_b = borrowed(comp_b)
    ws = borrowed(ws)
    wi = borrowed(wi)
    n = x.shape[0]
    kc = rear.shape[0]
    elastic = order.shape[0] > 0
    # Every work array is a view of ws / wi (measured: 45 allocations were a fifth of a warm
    # step); what is returned is copied.
    cur, off = _eval_arrays(ws, 0, n, kc)
    trial, off = _eval_arrays(ws, off, n, kc)
    nb = 9 if elastic else 7
    xs, off = _carve(ws, off, (n, nb, nb + 2))
    ys, off = _carve(ws, off, (n, nb, 2))
    dx, off = _carve(ws, off, (n, 6))
    xn, off = _carve(ws, off, (n, 6))
    xw, off = _carve(ws, off, (n, 6))
    du, off = _carve(ws, off, (u.shape[0],))
    un, off = _carve(ws, off, (u.shape[0],))
    uw, off = _carve(ws, off, (u.shape[0],))
    ne = n if elastic else 0
    dcum, off = _carve(ws, off, (ne,))
    cn, off = _carve(ws, off, (ne,))
    cum, off = _carve(ws, off, (ne,))
    df, off = _carve(ws, off, (kc,))
    fn, off = _carve(ws, off, (kc,))
    fw_, off = _carve(ws, off, (kc,))
    ew, off = _carve(ws, off, (WORK_SIZE,))
    bw, off = _carve(ws, off, (B2B_WORK_SIZE,))
    edw, off = _carve(ws, off, (ELASTIC_WORK_SIZE,))
    dd, off = _carve(ws, off, (7, 7))
    dw, off = _carve(ws, off, (7, 9))
    dd0, off = _carve(ws, off, (7, 7))
    dw0, off = _carve(ws, off, (7, 9))
    dlm, off = _carve(ws, off, (7, 7))
    fbw, off = _carve(ws, off, (FB_ROWS * _CHUNK,))
    pos, io = _carve(wi, 0, (order.shape[0],))
    rear_of, io = _carve(wi, io, (n,))
    front_of, io = _carve(wi, io, (n,))
    seq, io = _carve(wi, io, (n,))
    starts, io = _carve(wi, io, (n + 1,))
    free, io = _carve(wi, io, (n, 2))
    for i in range(n):
        for j in range(6):
            xw[i, j] = x[i, j]
    for i in range(u.shape[0]):
        uw[i] = u[i]
    for c in range(kc):
        fw_[c] = fhat[c]
        df[c] = 0.0
    x = xw
    u = uw
    fhat = fw_
    if elastic:
        evaluate_lanes(x, 0.0, u, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                       grid, scale, False, cur[0], cur[1], cur[2], cur[3], cur[4], ew)
        acc = 0.0
        for k in range(n):
            acc -= cur[3][order[k], 8] / scale
            cum[k] = acc
        for k in range(n):
            pos[order[k]] = k
    if elastic:
        behind, ahead, wrap = _elastic_blocks(order, pos, rear, front, n)
    else:
        behind = order      # empty: the rigid path has no axial order (no allocation)
        ahead = order
        wrap = -1
    nc, ok_chain = chains_into(n, rear, front, rear_of, front_of, seq, starts)
    starts = starts[:nc + 1]
    # The rigid path's Jacobian stays in the evaluation's acc rows: the direction
    # reads it after the evaluation of the current iterate, always the last one made.
    rows = ew[_ACC_OFF:_PCO_OFF]
    jn = n if elastic or n > _CHUNK else 0
    # The evaluation written out here (and below): a call with 30 arguments per evaluation
    # cost more than its body's share of a warm step.
    if elastic:
        norm = _elastic_residual(
            x, u, cum, fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
            grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order,
            comp_a, comp_b, cur[0], cur[1], cur[2], cur[3], cur[4], cur[5], cur[6],
            cur[7], cur[8], cur[9], cur[10], cur[11], cur[12], cur[13], cur[14], True, ew,
            bw)
        axial = 0.0
    else:
        axial, norm = _residual(
            x, u[0], fhat, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
            grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, cur[0],
            cur[1][:jn], cur[2][:jn], cur[3], cur[4], cur[5], cur[6], cur[7], cur[8], cur[9],
            cur[10], cur[11], cur[12], True, cur[15], ew, bw)
    if not (elastic or ok_chain):
        return _newton_result(x, u, fhat, False, 0, norm, cur[3], cur[4], cur[7], ws)
    it = 0
    while norm > tol and it < max_it:
        it += 1
        if elastic:
            elastic_direction(order, behind, ahead, wrap, rear, cur[1], cur[2], cur[0], cur[13],
                              cur[14], cur[12], fhat, comp_b, cur[5], cur[6], cur[8], cur[9],
                              cur[10], cur[11], xs, ys, dx, du, dcum, df, edw)
        else:
            du[0] = newton_direction(seq, starts, rear_of, front_of, cur[1], cur[2], cur[0],
                                     axial, cur[12], fhat, cur[5], cur[6], cur[8], cur[9],
                                     cur[10], cur[11], xs, ys, dx, df, dd, dw, dd0, dw0, dlm,
                                     free, fbw, rows, jn == 0, 1.0 / scale,
                                     1.0 / (cst[1] * scale))
        # Trust region: near two-point contact the spin about the loaded diagonal is weakly
        # determined and a full step can run away.
        big_r = 0.0
        big_d = 0.0
        for i in range(u.shape[0]):
            big_d = max(big_d, abs(du[i]))
        for i in range(n):
            for j in range(2):
                big_d = max(big_d, abs(dx[i, j]))
            for j in range(2, 6):
                big_r = max(big_r, abs(dx[i, j]))
        big = max(big_r / max_rate, big_d / disp_limit)
        if not math.isfinite(big):
            return _newton_result(x, u, fhat, False, it, norm, cur[3], cur[4], cur[7], ws)
        step = 1.0 / big if big > 1.0 else 1.0
        nn = norm
        ax_n = axial
        # Near the solution (quadratic convergence, _LAST_FACTOR) the next iterate
        # almost surely meets the tolerance: evaluate it without the Jacobian, and add the
        # Jacobian only if it did not.
        last = norm * norm * (_FIRST_FACTOR if it == 1 else _LAST_FACTOR) <= tol
        for _ in range(_N_TRIAL):
            for i in range(n):
                for j in range(6):
                    xn[i, j] = x[i, j] + step * dx[i, j]
            for i in range(u.shape[0]):
                un[i] = u[i] + step * du[i]
            for i in range(cum.shape[0]):
                cn[i] = cum[i] + step * dcum[i]
            for c in range(kc):
                fn[c] = fhat[c] + step * df[c]
            if elastic:
                nn = _elastic_residual(
                    xn, un, cn, fn, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                    grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order,
                    comp_a, comp_b, trial[0], trial[1], trial[2], trial[3], trial[4], trial[5],
                    trial[6], trial[7], trial[8], trial[9], trial[10], trial[11], trial[12],
                    trial[13], trial[14], not last, ew, bw)
                ax_n = 0.0
            else:
                ax_n, nn = _residual(
                    xn, un[0], fn, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                    grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, trial[0],
                    trial[1][:jn], trial[2][:jn], trial[3], trial[4], trial[5], trial[6], trial[7],
                    trial[8], trial[9], trial[10], trial[11], trial[12], not last, trial[15], ew,
                    bw)
            if math.isfinite(nn) and (nn < norm or nn <= tol):
                break
            step *= 0.5
        if last and not nn <= tol:
            if elastic:
                nn = _elastic_residual(
                    xn, un, cn, fn, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                    grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order,
                    comp_a, comp_b, trial[0], trial[1], trial[2], trial[3], trial[4], trial[5],
                    trial[6], trial[7], trial[8], trial[9], trial[10], trial[11], trial[12],
                    trial[13], trial[14], True, ew, bw)
                ax_n = 0.0
            else:
                ax_n, nn = _residual(
                    xn, un[0], fn, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n,
                    grid, scale, axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, trial[0],
                    trial[1][:jn], trial[2][:jn], trial[3], trial[4], trial[5], trial[6], trial[7],
                    trial[8], trial[9], trial[10], trial[11], trial[12], True, trial[15], ew, bw)
        x, xn = xn, x
        u, un = un, u
        cum, cn = cn, cum
        fhat, fn = fn, fhat
        axial = ax_n
        norm = nn
        cur, trial = trial, cur
    return _newton_result(x, u, fhat, norm <= tol, it, norm, cur[3], cur[4], cur[7], ws)


@_jit
def _newton_result(x, u, fhat, ok, it, norm, terms, per_contact, speed, ws):
    """
    ``_newton``'s result: its arrays themselves (views of ws) if ws is a caller's, else copies.

    A ws longer than newton's own share is a caller's ``work_arrays``, alive for its
    caller's whole call; those callers read the views before they use ws again (measured:
    the nine copies were 9 of the 47 allocations of a warm step).  Else ws may be the one
    ``newton`` allocated for this call alone: the arrays are copied out of it.
    """
    if ws.shape[0] > newton_work_size(x.shape[0])[0]:
        return x, u, fhat, ok, it, norm, terms, per_contact, speed
    return (x.copy(), u.copy(), fhat.copy(), ok, it, norm, terms.copy(), per_contact.copy(),
            speed.copy())


# The warm step's own work arrays (``step_work_size``), after newton's share of ws and wi,
# in blocks of N values: floats of advance (its work: 4, azimuth, phi, theta: 3, centres: 8),
# warm_solve (the guesses' x, u, forces: 2 x 8), _solve_guess (its forces: 1),
# solve_active_set (f0, forces: 2, terms: 10, per contact: 12, x: 6, u: 1),
# _warm_step_core (speed, forces, ratio, ring forces: 4); integers of advance (pair index,
# rear, front, touching, counts: 5), _solve_guess (active: 1), solve_active_set (active,
# index, rear, front: 4) and _warm_step_core (ring active, active pairs: 2).  A bool array
# takes one integer per entry.
_SW_ADVANCE = 0
_SW_GUESS = 15
_SW_SOLVE_GUESS = 31
_SW_SET = 32
_SW_CORE = 63
_SW_BLOCKS = 67
_SI_ADVANCE = 0
_SI_SOLVE_GUESS = 5
_SI_SET = 6
_SI_CORE = 10
_SI_BLOCKS = 12


@_jit
def step_work_size(n):
    """Floats and integers of the warm step's work arrays for n balls, after newton's."""
    return _SW_BLOCKS * n, _SI_BLOCKS * n


@_jit
def _step_offsets(n, fblock, iblock):
    """Offsets in ws and wi of the warm step's work blocks fblock and iblock (_SW_*, _SI_*)."""
    nf, ni = newton_work_size(n)
    return nf + fblock * n, ni + iblock * n


@_jit
def _carve_bools(wi, off, k):
    """Return a bool view of k entries of wi at off (one integer each) and the offset after."""
    v, nxt = _carve(wi, off, (k,))
    return v.view(np.bool_)[:k], nxt


@_jit(exact=True)
def solve_active_set(x, u, f_all, active, centres, sign, cst, k_load, k_axis, on_nut, coef_s,
                     coef_n, grid, scale, axial_load_n, pair_rear, pair_front, b_r, b_f, c_r, c_f,
                     k_r, k_f, order, comp_a, comp_b, tol, max_it, max_rate, disp_limit,
                     max_changes, budget, ws, wi):
    """
    ``EquilibriumSolver.solve`` compiled: Newton per active set, exact complementarity.

    The same loop as the numpy reference (``solver.EquilibriumSolver.solve``), step for step,
    its own arithmetic compiled without fastmath: release the contacts with a negative force,
    else close the open pairs whose rear ball orbits faster, until neither happens.
    f_all: B2B forces per candidate pair in units of ``scale``; budget < 0: no iteration cap.
    Returns (x, u, f_all, active, converged, budget_exhausted, iterations, norm, terms,
    per_contact); u as in ``newton``.  Its arrays are views of ws and wi (``work_arrays``,
    which it needs), valid until the caller uses them again: for compiled callers only.
    """
    pair_rear = borrowed(pair_rear)
    pair_front = borrowed(pair_front)
    centres = borrowed(centres)
    cst = borrowed(cst)
    k_load = borrowed(k_load)
    k_axis = borrowed(k_axis)
    on_nut = borrowed(on_nut)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    grid = borrowed(grid)
    b_r = borrowed(b_r)
    b_f = borrowed(b_f)
    c_r = borrowed(c_r)
    c_f = borrowed(c_f)
    k_r = borrowed(k_r)
    k_f = borrowed(k_f)
    order = borrowed(order)
    comp_a = borrowed(comp_a)
    comp_b = borrowed(comp_b)
    ws = borrowed(ws)
    wi = borrowed(wi)
    n = x.shape[0]
    p = pair_rear.shape[0]
    # Every array of the loop is a view of the step's share of ws / wi (step_work_size).
    off, io = _step_offsets(n, _SW_SET, _SI_SET)
    f0_w, off = _carve(ws, off, (n,))
    f_w, off = _carve(ws, off, (n,))
    terms, off = _carve(ws, off, (n, 10))
    per_contact, off = _carve(ws, off, (n, 4, 3))
    x_w, off = _carve(ws, off, (n, 6))
    u_w, off = _carve(ws, off, (u.shape[0],))
    active_w, io = _carve_bools(wi, io, p)
    idx_w, io = _carve(wi, io, (n,))
    rear_w, io = _carve(wi, io, (n,))
    front_w, io = _carve(wi, io, (n,))
    for i in range(p):
        active_w[i] = active[i]
    active = active_w
    total_it = 0
    ok = False
    exhausted = False
    norm = np.inf
    if max_changes < 1:
        # Returned as they are: the loop below does not run.
        terms[:] = 0.0
        per_contact[:] = 0.0
    settled = False
    solved = False
    for _ in range(max_changes):
        if solved:
            # newton's x and u are views of its work arrays, laid out by the active set:
            # copied out before the next call lays them out again.
            for i in range(n):
                for j in range(6):
                    x_w[i, j] = x[i, j]
            for i in range(u.shape[0]):
                u_w[i] = u[i]
            x = x_w
            u = u_w
        k = 0
        for i in range(p):
            if active[i]:
                idx_w[k] = i
                k += 1
        idx = idx_w[:k]
        rear = rear_w[:k]
        front = front_w[:k]
        f0 = f0_w[:k]
        for j in range(k):
            rear[j] = pair_rear[idx[j]]
            front[j] = pair_front[idx[j]]
            # np.maximum(f, 0.0) as numba computes it: f itself if NaN.
            f = f_all[idx[j]]
            f0[j] = 0.0 if f < 0.0 else f
        left = max(budget - total_it, 0) if budget >= 0 else max_it
        x, u, f_hat, ok, it, norm, terms, per_contact, _ = newton(
            x, u, f0, centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale,
            axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol,
            min(max_it, left), max_rate, disp_limit, ws, wi)
        solved = True
        total_it += it
        for i in range(p):
            f_w[i] = 0.0
        for j in range(k):
            f_w[idx[j]] = f_hat[j]
        f_all = f_w[:p]
        if not ok:
            exhausted = budget >= 0 and it >= left and math.isfinite(norm)
            settled = True
            break
        if p == 0:
            settled = True
            break
        released = False
        for j in range(idx.shape[0]):
            if f_hat[j] < -tol:
                active[idx[j]] = False
                released = True
        closed = False
        if not released:
            for i in range(p):
                if not active[i] and (x[pair_rear[i], 2] * sign
                                      > x[pair_front[i], 2] * sign + tol):
                    active[i] = True
                    closed = True
        if not (released or closed):
            settled = True
            break
    if not settled:
        ok = False
    return x, u, f_all, active, ok, exhausted, total_it, norm, terms, per_contact


@_jit(exact=True)
def _solve_guess(x, u, forces, ring_active, pair_idx, centres, sign, cst, k_load, k_axis,
                 on_nut, coef_s, coef_n, grid, scale, axial_load_n, rear, front, b_r, b_f, c_r,
                 c_f, k_r, k_f, order, comp_a, comp_b, tol, max_it, max_rate, disp_limit,
                 max_changes, budget, ws, wi):
    """``solve_active_set`` from one guess (x, u, forces per ring pair [N]) of ``warm_solve``."""
    x = borrowed(x)
    u = borrowed(u)
    forces = borrowed(forces)
    ring_active = borrowed(ring_active)
    pair_idx = borrowed(pair_idx)
    rear = borrowed(rear)
    front = borrowed(front)
    centres = borrowed(centres)
    cst = borrowed(cst)
    k_load = borrowed(k_load)
    k_axis = borrowed(k_axis)
    on_nut = borrowed(on_nut)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    grid = borrowed(grid)
    b_r = borrowed(b_r)
    b_f = borrowed(b_f)
    c_r = borrowed(c_r)
    c_f = borrowed(c_f)
    k_r = borrowed(k_r)
    k_f = borrowed(k_f)
    order = borrowed(order)
    comp_a = borrowed(comp_a)
    comp_b = borrowed(comp_b)
    ws = borrowed(ws)
    wi = borrowed(wi)
    p = pair_idx.shape[0]
    off, io = _step_offsets(x.shape[0], _SW_SOLVE_GUESS, _SI_SOLVE_GUESS)
    fs, _ = _carve(ws, off, (p,))
    active, _ = _carve_bools(wi, io, p)
    for i in range(p):
        fg = forces[pair_idx[i]]
        faster = x[rear[i], 2] * sign > x[front[i], 2] * sign
        active[i] = (ring_active[pair_idx[i]] and fg > 0.0) or faster
        fs[i] = fg / scale
    # x and u as they are: solve_active_set and newton only read them.
    return solve_active_set(x, u, fs, active, centres, sign, cst, k_load, k_axis, on_nut,
                            coef_s, coef_n, grid, scale, axial_load_n, rear, front, b_r, b_f,
                            c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol, max_it, max_rate,
                            disp_limit, max_changes, budget, ws, wi)


@_jit(exact=True)
def warm_solve(x, u, x_prev, u_prev, f_prev, d_psi_prev, forces, ring_active, d_psi, pair_idx,
               centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale,
               axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b,
               tol, max_it, max_rate, disp_limit, max_changes, budget, ws, wi):
    """
    Solve a warm step (``whole_screw.WholeScrew._warm_solve_numpy``, its reference).

    Guesses in turn (only the first with an iteration budget): the secant prediction in
    nut angle from the previous (x_prev, u_prev, f_prev over d_psi_prev; d_psi_prev = 0:
    none), then the previous solution (x, u, forces per ring pair [N]).  Each starts with the
    closed pairs whose predicted force stays positive plus the open pairs whose rear ball is
    predicted faster.  Returns ``solve_active_set``'s tuple for the first guess that
    converged or used up the budget (else the last), the summed iterations, and the B2B slip
    speed of every candidate pair, all arrays of their own.  ws, wi: ``work_arrays``.
    """
    _check_work(x.shape[0], ws, wi)
    out, iterations, speed = _warm_solve(
        x, u, x_prev, u_prev, f_prev, d_psi_prev, forces, ring_active, d_psi, pair_idx,
        centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale,
        axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol,
        max_it, max_rate, disp_limit, max_changes, budget, ws, wi)
    xs, us, f_all, active, ok, exhausted, it, norm, terms, per_contact = out
    return ((xs.copy(), us.copy(), f_all.copy(), active.copy(), ok, exhausted, it, norm,
             terms.copy(), per_contact.copy()), iterations, speed.copy())


@_jit
def _check_work(n, ws, wi):
    """Raise unless ws and wi hold newton's and the warm step's work arrays for n balls."""
    nf, ni = newton_work_size(n)
    sf, si = step_work_size(n)
    if ws.shape[0] < nf + sf or wi.shape[0] < ni + si:
        raise ValueError("warm step: work arrays too small (kernel.work_arrays)")


@_jit(exact=True)
def _warm_solve(x, u, x_prev, u_prev, f_prev, d_psi_prev, forces, ring_active, d_psi, pair_idx,
                centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale,
                axial_load_n, rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b,
                tol, max_it, max_rate, disp_limit, max_changes, budget, ws, wi):
    """
    ``warm_solve`` in the caller's work arrays (ws, wi, at least ``_check_work``'s).

    Its arrays are views of ws and wi: valid until the caller uses them again.
    """
    x = borrowed(x)
    u = borrowed(u)
    x_prev = borrowed(x_prev)
    u_prev = borrowed(u_prev)
    f_prev = borrowed(f_prev)
    forces = borrowed(forces)
    ring_active = borrowed(ring_active)
    pair_idx = borrowed(pair_idx)
    rear = borrowed(rear)
    front = borrowed(front)
    centres = borrowed(centres)
    cst = borrowed(cst)
    k_load = borrowed(k_load)
    k_axis = borrowed(k_axis)
    on_nut = borrowed(on_nut)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    grid = borrowed(grid)
    b_r = borrowed(b_r)
    b_f = borrowed(b_f)
    c_r = borrowed(c_r)
    c_f = borrowed(c_f)
    k_r = borrowed(k_r)
    k_f = borrowed(k_f)
    order = borrowed(order)
    comp_a = borrowed(comp_a)
    comp_b = borrowed(comp_b)
    ws = borrowed(ws)
    wi = borrowed(wi)
    n_guess = 1
    off, _ = _step_offsets(x.shape[0], _SW_GUESS, 0)
    gx, off = _carve(ws, off, (2,) + x.shape)
    gu, off = _carve(ws, off, (2,) + u.shape)
    gf, off = _carve(ws, off, (2,) + forces.shape)
    if d_psi_prev != 0.0:
        r = d_psi / d_psi_prev
        if 0.0 < r <= 4.0:
            # Element by element (the same rounding as the array expression, no temporaries).
            for i in range(x.shape[0]):
                for j in range(x.shape[1]):
                    gx[0, i, j] = x[i, j] + r * (x[i, j] - x_prev[i, j])
            for i in range(u.shape[0]):
                gu[0, i] = u[i] + r * (u[i] - u_prev[i])
            for i in range(forces.shape[0]):
                gf[0, i] = forces[i] + r * (forces[i] - f_prev[i])
            n_guess = 2
    g = n_guess - 1
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            gx[g, i, j] = x[i, j]
    for i in range(u.shape[0]):
        gu[g, i] = u[i]
    for i in range(forces.shape[0]):
        gf[g, i] = forces[i]
    if budget >= 0:
        n_guess = 1
    out = _solve_guess(gx[0], gu[0], gf[0], ring_active, pair_idx, centres, sign, cst, k_load,
                       k_axis, on_nut, coef_s, coef_n, grid, scale, axial_load_n, rear, front,
                       b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol, max_it,
                       max_rate, disp_limit, max_changes, budget, ws, wi)
    iterations = out[6]
    if n_guess == 2 and not (out[4] or out[5]):
        out = _solve_guess(gx[1], gu[1], gf[1], ring_active, pair_idx, centres, sign, cst,
                           k_load, k_axis, on_nut, coef_s, coef_n, grid, scale, axial_load_n,
                           rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol,
                           max_it, max_rate, disp_limit, max_changes, budget, ws, wi)
        iterations += out[6]
    off, _ = _step_offsets(x.shape[0], _SW_CORE, 0)
    speed, _ = _carve(ws, off, (rear.shape[0],))
    _pair_speed_into(out[0], rear, front, b_r, b_f, speed)
    return out, iterations, speed


# Rows of warm_step's output block (rows, N): azimuth, phi, theta, orbit ratio, omega_B,
# axial force on the nut, B2B force per ring pair, the forces of the active pairs in chain
# order (first ones), contact loads (4 rows).
STEP_ROWS = 12
# Constants of the elastic load path (``elastic_path``, ``pack_elastic_constants``).
ELASTIC_CONSTANTS = 6


@_jit(exact=True)
def elastic_path(phi, epar, axial_load_n, scale):
    """
    ``load_distribution.elastic_load_path`` compiled, with the same rounding.

    phi: the balls' track azimuths [rad]; epar: ``pack_elastic_constants``.  Returns (order,
    comp_a, comp_b).  A stable sort, so the order of two balls at one azimuth is numpy's.
    """
    n = phi.shape[0]
    order = np.argsort(phi, kind="mergesort")
    comp_a = np.empty(max(n - 1, 0))
    comp_b = np.empty(max(n - 1, 0))
    per_rad = epar[0] / (2.0 * math.pi)
    for k in range(n - 1):
        dz = per_rad * (phi[order[k + 1]] - phi[order[k]])
        c_shaft = dz / epar[1]
        c_nut = 0.0 if epar[3] != 0.0 else dz / epar[2]
        comp_a[k] = axial_load_n * (epar[4] * c_nut + epar[5] * c_shaft) / LENGTH_SCALE_M
        comp_b[k] = (c_nut + c_shaft) * scale / LENGTH_SCALE_M
    return order, comp_a, comp_b


@_jit(exact=True)
def _warm_step_core(azimuth, ratio, x, x_prev, f_prev, forces, ring_active, par, epar,
                    coef_s, coef_n, ws, wi, d_psi, track_start, sign, u, u_prev, d_psi_prev,
                    scale, axial_load_n, tol, max_it, max_rate, disp_limit, max_changes,
                    budget):
    """
    ``advance``, the load path, ``warm_solve`` and ``step_totals`` of one warm step.

    u, u_prev: the nut displacement(s), (1,) rigid, (N,) elastic (epar not empty).
    Returns (ok, exhausted, iterations, norm, u, x, forces of the candidate pairs [N],
    step_totals' tuple, azimuth, phi, theta, terms, per_contact, rear, front).
    """
    azimuth = borrowed(azimuth)
    ratio = borrowed(ratio)
    x = borrowed(x)
    x_prev = borrowed(x_prev)
    f_prev = borrowed(f_prev)
    forces = borrowed(forces)
    ring_active = borrowed(ring_active)
    par = borrowed(par)
    epar = borrowed(epar)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    ws = borrowed(ws)
    wi = borrowed(wi)
    u = borrowed(u)
    u_prev = borrowed(u_prev)
    geo = par[0:9]
    cst = par[9:17]
    k_load = par[17:21]
    k_axis = par[21:25]
    on_nut = par[25:29]
    grid = par[29:33]
    b_r = par[33:51].reshape((3, 6))
    b_f = par[51:69].reshape((3, 6))
    c_r = par[69:75]
    c_f = par[75:81]
    k_r = par[81:99].reshape((6, 3))
    k_f = par[99:117].reshape((6, 3))
    n = azimuth.shape[0]
    _check_work(n, ws, wi)
    off, io = _step_offsets(n, _SW_ADVANCE, _SI_ADVANCE)
    work, off = _carve(ws, off, (4, n))
    az, off = _carve(ws, off, (n,))
    phi, off = _carve(ws, off, (n,))
    theta, off = _carve(ws, off, (n,))
    centres, off = _carve(ws, off, (n, 4, 2))
    idx_w, io = _carve(wi, io, (n,))
    rear_w, io = _carve(wi, io, (n,))
    front_w, io = _carve(wi, io, (n,))
    touching, io = _carve_bools(wi, io, n)
    counts, io = _carve(wi, io, (n,))
    k = _advance_into(azimuth, ratio, d_psi, geo[0], geo[1], track_start, geo[2], sign, geo[3],
                      geo[4], geo[5], geo[6], geo[7], geo[8], work, az, phi, theta, centres,
                      touching, counts, idx_w, rear_w, front_w)
    pair_idx = idx_w[:k]
    rear = rear_w[:k]
    front = front_w[:k]
    if epar.shape[0] > 0:
        order, comp_a, comp_b = elastic_path(phi, epar, axial_load_n, scale)
    else:
        order, _ = _carve(wi, 0, (0,))
        comp_a, _ = _carve(ws, 0, (0,))
        comp_b = comp_a
    out, iterations, speed = _warm_solve(
        x, u, x_prev, u_prev, f_prev, d_psi_prev, forces, ring_active, d_psi, pair_idx,
        centres, sign, cst, k_load, k_axis, on_nut, coef_s, coef_n, grid, scale, axial_load_n,
        rear, front, b_r, b_f, c_r, c_f, k_r, k_f, order, comp_a, comp_b, tol, max_it,
        max_rate, disp_limit, max_changes, budget, ws, wi)
    xs, us, f_all, active, ok, exhausted, _, norm, terms, per_contact = out
    # speed is the first of this function's blocks (_warm_solve's), the rest follow it.
    off, io = _step_offsets(n, _SW_CORE + 1, _SI_CORE)
    f_w, off = _carve(ws, off, (n,))
    f = f_w[:k]
    new_ratio, off = _carve(ws, off, (n,))
    ring_forces, off = _carve(ws, off, (n,))
    ring_active_new, io = _carve_bools(wi, io, n)
    act, io = _carve(wi, io, (n,))
    for c in range(k):
        f[c] = f_all[c] * scale
    loss_sum, torque_sum, b2b, load_max, count = _step_totals_into(
        terms[:, 6], terms[:, 7], per_contact[:, :, 0], f, speed, active, pair_idx, xs, sign,
        new_ratio, ring_active_new, ring_forces, act)
    totals = (loss_sum, torque_sum, b2b, load_max, new_ratio, ring_active_new, ring_forces,
              act[:count])
    return (ok, exhausted, iterations, norm, us, xs, f, totals, az, phi, theta, terms,
            per_contact, rear, front)


@_jit(exact=True)
def _step_outputs(az, phi, theta, terms, per_contact, rear, front, f, totals, omega_n):
    """Return the output block (STEP_ROWS, N) and the active pairs (2, K) of a step."""
    blk = np.empty((STEP_ROWS, az.shape[0]))
    groups = np.empty((2, totals[7].shape[0]), dtype=np.int64)
    _step_outputs_into(az, phi, theta, terms, per_contact, rear, front, f, totals, omega_n, blk,
                       groups)
    return blk, groups


@_jit(exact=True)
def _step_outputs_into(az, phi, theta, terms, per_contact, rear, front, f, totals, omega_n, blk,
                       groups):
    """``_step_outputs`` into blk (STEP_ROWS, N) and groups (2, >= K); returns K."""
    new_ratio, new_forces, act = totals[4], totals[6], totals[7]
    n = az.shape[0]
    for i in range(n):
        blk[0, i] = az[i]
        blk[1, i] = phi[i]
        blk[2, i] = theta[i]
        blk[3, i] = new_ratio[i]
        blk[4, i] = new_ratio[i] * omega_n
        blk[5, i] = -terms[i, 8]
        blk[6, i] = new_forces[i]
        for k in range(4):
            blk[8 + k, i] = per_contact[i, k, 0]
    for j in range(act.shape[0]):
        groups[0, j] = rear[act[j]]
        groups[1, j] = front[act[j]]
        blk[7, j] = f[act[j]]
    return act.shape[0]


@_jit(exact=True)
def warm_step(azimuth, ratio, x, x_prev, f_prev, forces, ring_active, par, coef_s, coef_n, ws,
              wi, d_psi, track_start, sign, u, u_prev, d_psi_prev, scale, axial_load_n, tol,
              max_it, max_rate, disp_limit, max_changes, budget, omega_n):
    """
    Take a whole warm step of a rigid nut without lead errors in one call (``WholeScrew.step``).

    ``advance``, ``warm_solve`` and ``step_totals`` in turn, with the arrays between them
    never leaving compiled code, and the step's per-ball outputs built here: the same
    arithmetic as those three calls and the numpy around them (exact, so the same rounding).
    par: the constants packed once per direction (``pack_step_constants``); ws, wi: the work
    arrays (``work_arrays``); u, u_prev: the rigid nut's displacement; omega_n: the nut
    velocity.  Measured need: a call with 37 arguments that returned 13 arrays cost 9 us of
    a 50 us step at N = 37 (the same call with 10 arguments and scalars back: 0.5 us).
    Returns (converged, budget exhausted, iterations, residual norm, u, sums of the
    ball-groove losses, of the nut torques and of the B2B force times slip speed, largest
    contact load, the output block (STEP_ROWS, N), x (N, 6), active per ring pair, rear and
    front of the active pairs in chain order (2, K)).  Of a failed solve only its flags and
    iterations mean anything: the caller redoes the geometry and cold-starts.
    """
    u_arr = np.empty(1)
    u_arr[0] = u
    up_arr = np.empty(1)
    up_arr[0] = u_prev
    ok, exhausted, iterations, norm, us, xs, f, totals, az, phi, theta, terms, per_contact, \
        rear, front = _warm_step_core(
            azimuth, ratio, x, x_prev, f_prev, forces, ring_active, par, np.zeros(0), coef_s,
            coef_n, ws, wi, d_psi, track_start, sign, u_arr, up_arr, d_psi_prev, scale,
            axial_load_n, tol, max_it, max_rate, disp_limit, max_changes, budget)
    blk, groups = _step_outputs(az, phi, theta, terms, per_contact, rear, front, f, totals,
                                omega_n)
    # xs and totals[5] are views of ws and wi (_warm_step_core): the caller keeps them.
    return (ok, exhausted, iterations, norm, us[0], totals[0], totals[1], totals[2], totals[3],
            blk, xs.copy(), totals[5].copy(), groups)


# warm_steps' settings: direction sign, load sign, max iterations, max active-set changes,
# iteration budget (-1: none), trust-region rate limit, the nut angle before the path [rad],
# the track start [rad], the force scale's floor (preload load) [N], the smallest load
# solved (-1 with preload) [N], the largest [N], tolerance, sub-step tolerance, trust-region
# displacement limit's floor and the Hertz approach per N^(2/3) [LENGTH_SCALE_M].
SETTINGS_SIZE = 15
# warm_steps' results: steps done, last step converged, budget exhausted, its iterations,
# its residual norm, its sums (loss, nut torque, B2B force x speed), largest contact load,
# sub-steps not converged, iterations of the steps done, the last step's active pairs.
# After a failed step, "its iterations" are those of the failed solve.
RESULT_SIZE = 12
# warm_step's packed constants (``pack_step_constants``) and the elastic ones
# (``pack_elastic_constants``).
PAR_SIZE = 117
EPAR_SIZE = 6
# Where each part of warm_steps' aux array starts: settings, result, packed constants,
# elastic constants (the only place the layout is written down).
_AUX_RESULT = SETTINGS_SIZE
_AUX_PAR = _AUX_RESULT + RESULT_SIZE
_AUX_EPAR = _AUX_PAR + PAR_SIZE


def aux_size(elastic):
    """Length of ``warm_steps``' aux array: settings, result, packed and elastic constants."""
    return _AUX_EPAR + (EPAR_SIZE if elastic else 0)


def aux_parts(aux):
    """Return the views (settings, result, packed constants, elastic constants) of ``aux``."""
    return (aux[:_AUX_RESULT], aux[_AUX_RESULT:_AUX_PAR], aux[_AUX_PAR:_AUX_EPAR],
            aux[_AUX_EPAR:])


@_jit(exact=True)
def warm_steps(state, ring_active, path, aux, coef_s, coef_n, ws, wi, blk, groups):
    """
    Take the warm steps to the given points in turn in one call: sub-steps, then the last.

    Each step is ``WholeScrew.step``'s warm step (``_warm_step_core``, the same arithmetic,
    its force scale and trust region computed as there), its start the state the step before
    left; all but the last point are sub-steps (the sub-step tolerance).  state
    (16 N + 2 + 2 m,): the model's state, read and written in place: azimuth, orbit ratio,
    x (6 N), the previous x (6 N), B2B force per ring pair and its previous value, the
    previous nut-angle increment, then u and the previous u (m = 1 rigid, N elastic), then
    a spare; ring_active (N,) is written in place too.  path (3 K,): the K points' angles
    [rad], velocities [rad/s] and loads [N], one after the other.  aux (``aux_size``): the
    settings (SETTINGS_SIZE), the result (RESULT_SIZE, written), the packed constants
    (PAR_SIZE) and, elastic, the elastic ones (EPAR_SIZE).  Stops before the first point
    that is not a warm step of the state's direction and load sign inside the load range,
    and at the first step that fails from every guess, the state left as that step found it
    (the caller takes it with a cold start).  When the path's last point is reached, writes
    its output block (``warm_step``'s) into blk (STEP_ROWS, N) and its active pairs into
    groups[:, :result[11]] ((2, N) int64).  Returns nothing: two arrays returned cost 0.6 us
    a call more than arrays passed in (measured: boxing them), a tenth of the Python around
    the call.
    """
    state = borrowed(state)
    ring_active = borrowed(ring_active)
    path = borrowed(path)
    aux = borrowed(aux)
    coef_s = borrowed(coef_s)
    coef_n = borrowed(coef_n)
    ws = borrowed(ws)
    wi = borrowed(wi)
    blk = borrowed(blk)
    groups = borrowed(groups)
    steps = path.shape[0] // 3
    angles = path[0:steps]
    velocities = path[steps:2 * steps]
    loads = path[2 * steps:3 * steps]
    settings = aux[:_AUX_RESULT]       # aux_parts, as views here
    result = aux[_AUX_RESULT:_AUX_PAR]
    par = aux[_AUX_PAR:_AUX_EPAR]
    epar = aux[_AUX_EPAR:]
    n = ring_active.shape[0]
    m = (state.shape[0] - 16 * n - 2) // 2
    azimuth = state[0:n]
    ratio = state[n:2 * n]
    x = state[2 * n:8 * n].reshape((n, 6))
    x_prev = state[8 * n:14 * n].reshape((n, 6))
    forces = state[14 * n:15 * n]
    f_prev = state[15 * n:16 * n]
    u = state[16 * n + 1:16 * n + 1 + m]
    u_prev = state[16 * n + 1 + m:16 * n + 1 + 2 * m]
    sign = settings[0]
    load_sign = settings[1]
    max_it = int(settings[2])
    max_changes = int(settings[3])
    budget = int(settings[4])
    max_rate = settings[5]
    angle = settings[6]
    for i in range(RESULT_SIZE):
        result[i] = 0.0
    for j in range(steps):
        w = velocities[j]
        load = loads[j]
        if not (w * sign > 0.0 and (1.0 if load >= 0.0 else -1.0) == load_sign
                and abs(load) > settings[9] and abs(load) <= settings[10]):
            return
        last = j == steps - 1
        d_psi = angles[j] - angle
        scale = max(abs(load) / n, settings[8])
        disp_limit = max(settings[13], settings[14] * max(scale, 0.0) ** (2.0 / 3.0)
                         / LENGTH_SCALE_M)
        ok, exhausted, iterations, norm, us, xs, f, totals, az, phi, theta, terms, \
            per_contact, rear, front = _warm_step_core(
                azimuth, ratio, x, x_prev, f_prev, forces, ring_active, par, epar, coef_s,
                coef_n, ws, wi, d_psi, angles[j] + settings[7], sign, u, u_prev,
                state[16 * n], scale, load, settings[11] if last else settings[12], max_it,
                max_rate, disp_limit, max_changes, budget)
        result[3] = iterations
        if not (ok or exhausted):
            return
        result[10] += iterations
        # The state the next step starts from (WholeScrew._fused_step's bookkeeping).
        for i in range(n):
            for k in range(6):
                x_prev[i, k] = x[i, k]
                x[i, k] = xs[i, k]
            f_prev[i] = forces[i]
            forces[i] = totals[6][i]
            ring_active[i] = totals[5][i]
            azimuth[i] = az[i]
            ratio[i] = totals[4][i]
        for i in range(m):
            u_prev[i] = u[i]
            u[i] = us[i]
        state[16 * n] = d_psi
        angle = angles[j]
        result[0] = j + 1
        if last:
            result[1] = 1.0 if ok else 0.0
            result[2] = 1.0 if exhausted else 0.0
            result[4] = norm
            result[5] = totals[0]
            result[6] = totals[1]
            result[7] = totals[2]
            result[8] = totals[3]
            result[11] = _step_outputs_into(az, phi, theta, terms, per_contact, rear, front, f,
                                            totals, w, blk, groups)
            return
        if not ok:
            result[9] += 1
    return


def state_size(n, elastic):
    """Length of ``warm_steps``' state for n balls."""
    m = n if elastic else 1
    return 16 * n + 2 + 2 * m


def pack_elastic_constants(lead_m, elastic):
    """
    Pack ``elastic_path``'s constants from the lead [m] and an ``ElasticBodies``.

    (lead, shaft E A, nut E A, 1 if the nut is held on its outer surface, the selectors S_n
    and L_s of ``load_distribution.compatibility_terms``).
    """
    return np.array([lead_m, elastic.shaft_axial_rigidity_n, elastic.nut_axial_rigidity_n,
                     1.0 if elastic.nut_support == "outer_surface" else 0.0,
                     1.0 if elastic.nut_support == "flange_at_track_start" else 0.0,
                     1.0 if elastic.shaft_load_end == "track_start" else 0.0])


def pack_step_constants(geo, cst, k_load, k_axis, on_nut, grid, b_r, b_f, c_r, c_f, k_r, k_f):
    """Pack ``warm_step``'s constant arrays into its one ``par`` (PAR_SIZE floats)."""
    par = np.concatenate([np.ravel(a) for a in (geo, cst, k_load, k_axis, on_nut, grid, b_r, b_f,
                                                c_r, c_f, k_r, k_f)]).astype(float)
    if par.shape != (PAR_SIZE,):
        raise ValueError(f"warm_step constants: {par.shape[0]} values, {PAR_SIZE} expected")
    return par


def pack_constants(ball, extra_oversize_m=0.0):
    """
    Pack the kernels' constant vector ``cst`` from a ``single_ball.BallGrooveModel``.

    (lambda, R_B, cos alpha, sin alpha, l = L/2pi, mu, ball-arc free distance, p/2pi); a
    temporary extra oversize (cold-start continuation) shortens the free distance.
    """
    return np.array([LENGTH_SCALE_M, ball.r_b, ball.cos_a, ball.sin_a, ball.ell, ball.mu,
                     ball.free_distance - 0.5 * extra_oversize_m, ball.r_gear])
