"""
Compiled Newton solve of a group of touching balls in the linear bearing (numba).

Why compiled (measured; the target: the whole two-ball case <= 1 ms warm): the numpy residual
of ``numerical.LinearBearingModel`` costs about 0.2 ms per evaluation for two balls, almost
all of it the overhead of ~60 small numpy calls, and the whole case needs about 14
evaluations (two free balls, then the pair).  The same arithmetic as scalar loops takes
about a microsecond.  This is the ball screw's kernel pattern (``ball_screw/kernel.py``):
the numpy model stays the reference and the fallback without numba, and the tests compare
both.

The residual and Jacobian are ``LinearBearingModel._residual_impl`` (Eqs. 1-10) written per
contact; the Newton iteration with its backtracking line search is ``solve_group``'s: one
evaluation (residual and Jacobian together) per accepted step.
"""

import math

import numpy as np

from bb_friction_ros.compiled import HAVE_NUMBA  # noqa: F401  (re-exported: numerical, tests)
from bb_friction_ros.compiled import gauss_solve
from bb_friction_ros.compiled import jit as _jit

_PI = math.pi


@_jit
def _map_line(values, slopes, step, u, val, der):
    """``FrictionMapLine.evaluate(u, derivative=True)`` for one rate angle u."""
    n = values.shape[1]
    t = (u + _PI) / step
    fl = math.floor(t)
    s = t - fl
    i0 = int(fl) % n
    i1 = (i0 + 1) % n
    s2 = s * s
    s3 = s2 * s
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = s3 - 2 * s2 + s
    h01 = -2 * s3 + 3 * s2
    h11 = s3 - s2
    g00 = 6 * s2 - 6 * s
    g10 = 3 * s2 - 4 * s + 1
    g01 = -6 * s2 + 6 * s
    g11 = 3 * s2 - 2 * s
    for k in range(3):
        y0 = values[k, i0]
        y1 = values[k, i1]
        d0 = slopes[k, i0] * step
        d1 = slopes[k, i1] * step
        val[k] = h00 * y0 + h10 * d0 + h01 * y1 + h11 * d1
        der[k] = (g00 * y0 + g10 * d0 + g01 * y1 + g11 * d1) / step


@_jit
def group_residual(z, nx, ny, q, a, vg, v, r_b, mu, q_ref, values, slopes, step, want_jac,
                   res, jac):
    """
    Scaled residuals (3 per ball) and Jacobian of a group; ``_residual_impl`` per contact.

    nx, ny, q, a: (g, 4) normals, loads [N] and semi-major axes [m] (q = 0: unloaded);
    vg (4,): groove velocity of each contact [m/s].  Returns max |res|.
    """
    g = nx.shape[0]
    m = 3 * g
    val = np.empty(3)
    der = np.empty(3)
    for r in range(m):
        res[r] = 0.0
        if want_jac:
            for c in range(m):
                jac[r, c] = 0.0
    k_w = v / r_b
    for j in range(g):
        wx = z[1 + 2 * j] * k_w
        wy = z[2 + 2 * j] * k_w
        for i in range(4):
            qi = q[j, i]
            if qi <= 0.0:
                continue
            ai = a[j, i]
            cx = nx[j, i]
            cy = ny[j, i]
            slip = z[0] * v - vg[i] + r_b * (wx * cy - wy * cx)
            spin = wx * cx + wy * cy
            y = slip / ai
            u = math.atan2(y, spin)
            _map_line(values, slopes, step, u, val, der)
            fz = qi * val[0] / q_ref
            mom = qi * ai * val[1] / (q_ref * r_b)
            res[3 * j] += fz
            res[3 * j + 1] += cy * fz + cx * mom
            res[3 * j + 2] += -cx * fz + cy * mom
            if not want_jac:
                continue
            s2 = y * y + spin * spin
            if s2 <= 0.0:
                s2 = 1.0
            du_dslip = spin / (ai * s2)
            du_dspin = -y / s2
            for col in range(3):
                if col == 0:
                    du = du_dslip * v
                    cc = 0
                elif col == 1:
                    du = du_dslip * v * cy + du_dspin * k_w * cx
                    cc = 1 + 2 * j
                else:
                    du = -du_dslip * v * cx + du_dspin * k_w * cy
                    cc = 2 + 2 * j
                dfz = qi * der[0] * du / q_ref
                dmom = qi * ai * der[1] * du / (q_ref * r_b)
                jac[3 * j, cc] += dfz
                jac[3 * j + 1, cc] += cy * dfz + cx * dmom
                jac[3 * j + 2, cc] += -cx * dfz + cy * dmom
    # B2B contacts between ball j (rear) and j + 1 (front): Eqs. (5)-(8).
    for j in range(g - 1):
        cf = 1 + 2 * g + j
        fb = z[cf]
        res[3 * j] -= fb
        res[3 * j + 3] += fb
        dvx = z[2 + 2 * j] + z[4 + 2 * j]
        dvy = -(z[1 + 2 * j] + z[3 + 2 * j])
        dvn = math.sqrt(dvx * dvx + dvy * dvy)
        if dvn <= 0.0:
            dvn = 1.0
        tx = -dvx / dvn
        ty = -dvy / dvn
        for k in (j, j + 1):
            res[3 * k + 1] += -mu * fb * ty
            res[3 * k + 2] += mu * fb * tx
        if not want_jac:
            continue
        jac[3 * j, cf] -= 1.0
        jac[3 * j + 3, cf] += 1.0
        inv = 1.0 / dvn
        dtx_ddvx = -(1 - tx * tx) * inv
        dtx_ddvy = tx * ty * inv
        dty_ddvx = tx * ty * inv
        dty_ddvy = -(1 - ty * ty) * inv
        mfb = mu * fb
        for k in (j, j + 1):
            jac[3 * k + 1, cf] += -mu * ty
            jac[3 * k + 2, cf] += mu * tx
            for mm in (j, j + 1):
                cwx = 1 + 2 * mm
                cwy = 2 + 2 * mm
                jac[3 * k + 1, cwy] += -mfb * dty_ddvx
                jac[3 * k + 1, cwx] += mfb * dty_ddvy
                jac[3 * k + 2, cwy] += mfb * dtx_ddvx
                jac[3 * k + 2, cwx] += -mfb * dtx_ddvy
    norm = 0.0
    for r in range(m):
        x = abs(res[r])
        if x > norm or x != x:
            norm = x
    return norm


@_jit
def solve_group(z0, nx, ny, q, a, vg, v, r_b, mu, q_ref, values, slopes, step, tol,
                max_iter):
    """
    Newton with backtracking (``LinearBearingModel.solve_group``): (z, norm, iterations).

    A singular Jacobian is solved again with a Levenberg-Marquardt diagonal shift (the numpy
    path uses a least-squares solve there).
    """
    m = z0.shape[0]
    z = z0.copy()
    res = np.empty(m)
    jac = np.empty((m, m))
    res_n = np.empty(m)
    jac_n = np.empty((m, m))
    rhs = np.empty((m, 1))
    d0 = np.empty((m, m))
    w0 = np.empty((m, 1))
    z_new = np.empty(m)
    norm = group_residual(z, nx, ny, q, a, vg, v, r_b, mu, q_ref, values, slopes, step, True,
                          res, jac)
    it = 0
    while norm > tol and it < max_iter:
        it += 1
        for r in range(m):
            rhs[r, 0] = -res[r]
        # jac is overwritten: the line search's evaluation replaces it.
        if not gauss_solve(jac, rhs, m, 0, d0, w0):
            break
        lam = 1.0
        while True:
            for r in range(m):
                z_new[r] = z[r] + lam * rhs[r, 0]
            norm_new = group_residual(z_new, nx, ny, q, a, vg, v, r_b, mu, q_ref, values,
                                      slopes, step, True, res_n, jac_n)
            if norm_new < (1.0 - 1e-4 * lam) * norm or lam < 1e-4:
                break
            lam *= 0.5
        z, z_new = z_new, z
        res, res_n = res_n, res
        jac, jac_n = jac_n, jac
        norm = norm_new
    return z, norm, it


@_jit
def group_outputs(z, nx, ny, q, a, vg, v, r_b, mu, values, slopes, step):
    """
    Per-contact results of a solved group (``LinearBearingModel._unpack``), in SI.

    Returns friction force along z on the ball [N], moment about the normal [N m], loss [W]
    (the map identity P = -(F V + w M)) and c/a (nan where unloaded), each (g, 4).
    """
    g = nx.shape[0]
    val = np.empty(3)
    der = np.empty(3)
    fz = np.zeros((g, 4))
    mom = np.zeros((g, 4))
    loss = np.zeros((g, 4))
    c_over_a = np.full((g, 4), np.nan)
    k_w = v / r_b
    for j in range(g):
        wx = z[1 + 2 * j] * k_w
        wy = z[2 + 2 * j] * k_w
        for i in range(4):
            qi = q[j, i]
            if qi <= 0.0:
                continue
            ai = a[j, i]
            slip = z[0] * v - vg[i] + r_b * (wx * ny[j, i] - wy * nx[j, i])
            spin = wx * nx[j, i] + wy * ny[j, i]
            _map_line(values, slopes, step, math.atan2(slip / ai, spin), val, der)
            fz[j, i] = mu * qi * val[0]
            mom[j, i] = mu * qi * ai * val[1]
            loss[j, i] = -(fz[j, i] * slip + mom[j, i] * spin)
            c_over_a[j, i] = -slip / (spin * ai) if spin != 0.0 else \
                (-math.inf if slip > 0.0 else math.inf)
    return fz, mom, loss, c_over_a
