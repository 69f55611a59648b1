"""
Coulomb friction over a Hertz ellipse, Eqs. (A4)-(A7), as tabulated maps.

Contact-plane frame: X along the major semi-axis a (across the groove), Y along the minor
semi-axis b (the rolling direction), normal Z = X x Y.  The slip of the ball relative to the
groove at a point r of the contact plane is  V + w Z x r : V is the slip at the contact centre,
w the spin about Z.  Coulomb traction -mu sigma slip/|slip| with the Hertz pressure sigma.

Why not c/a: the paper tabulates against c/a = distance of the velocity centre, which runs to
+-infinity as the spin w -> 0 (pure sliding).  We use the direction of the rate vector
(V_X/a, V_Y/a, w) on the unit sphere instead; every point of the sphere is regular, pure
sliding included, so a solver never meets a singularity.  c/a = -tan(u) on the paper's line.

Normalised outputs (``mu Q`` = friction coefficient times normal load):
    F = mu Q * f(direction)           frictional force (X, Y)            [N]
    M = mu Q a * m(direction)         frictional moment about Z at the centre  [N m]
    P = mu Q a s * p(direction)       friction loss, s = |(V/a, w)|      [W]
Identity: P = -(F.V + w M), checked in the tests.

Radial integrals are in closed form along rays from the velocity centre (the traction direction
is constant on each ray); only the angle is integrated numerically.  Tables are built once per
ellipticity and cached on disk; between nodes we interpolate with cubic Hermite polynomials
(own implementation: scipy's interpolators cost ~30 us per call, which would be most of the
1 ms budget of a two-ball solve).

References
----------
.. [1] Lin, B., Duan, M., Okwudire, C. E., 2019, "Analytical and Low-Order Numerical Modeling
   of Ball-to-Ball Contact Friction in Linear Ball Bearings and Ball Screws", ASME J. Tribol.
   141(8), DOI 10.1115/1.4043630.
   Eqs. (A4)-(A7) (force, moment, loss over the ellipse), Eqs. (11)-(12) (limits), Fig. 5
   and Sec. 2.3.1 (k_f).

"""

import hashlib
import math
import os
from pathlib import Path

import numpy as np

_TWO_PI = 2.0 * math.pi
_NORM = 3.0 / (2.0 * math.pi)   # weight (3/(2 pi k)) sqrt(1-X^2-Y^2/k^2), times dA = k dA'


def _ray_integrals_inside(p, e):
    """
    Closed-form K1 = int_0^rho2 sqrt(q) r dr and K2 = int sqrt(q) r^2 dr, start inside.

    In the unit-disc (primed) frame, q(r) = h^2 - (r - m)^2 with m = -p.e, h^2 = 1 - (p x e)^2.
    """
    pe = p[0] * e[0] + p[1] * e[1]
    px = p[0] * e[1] - p[1] * e[0]
    h2 = np.maximum(1.0 - px * px, 0.0)
    h = np.sqrt(h2)
    m = -pe
    u0 = -m                                # u = r - m runs from u0 (r = 0) to h
    s0 = np.sqrt(np.maximum(h2 - u0 * u0, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        asn = np.where(h > 0, np.arcsin(np.clip(u0 / np.where(h > 0, h, 1.0), -1, 1)), 0.0)
    half_pi = 0.5 * math.pi
    j0 = 0.5 * (h2 * half_pi) - 0.5 * (u0 * s0 + h2 * asn)
    j1 = (s0 ** 3) / 3.0
    j2 = (h2 * h2 / 8.0) * (half_pi - asn) - (u0 * (2 * u0 * u0 - h2) * s0) / 8.0
    k1 = m * j0 + j1
    k2 = m * m * j0 + 2 * m * j1 + j2
    return k1, k2


_BUILD_CHUNK = 1024     # rate directions integrated at once while a table is built
_N_INSIDE = 1024        # quadrature rays of a velocity centre inside the contact

# Memory of a table's build, estimated up front so a too-fine map is refused before it
# starts.  Peaks measured with tracemalloc (line maps of 65 536 and 262 144
# nodes: 139 and 154 MB; sphere map 640 x 512: 409 MB), rounded up: one chunk's quadrature
# temporaries (about 16 arrays of chunk x rays floats) plus a cost per node.
_CHUNK_BYTES = 16 * 8 * _BUILD_CHUNK * _N_INSIDE
_LINE_NODE_BYTES = 400      # values, slopes, the spline's coefficients and their temporaries
_SPHERE_NODE_BYTES = 1024   # 4 tables (128 B), cell coefficients (512 B), their temporaries


def line_map_bytes(n_nodes):
    """Return the peak memory [bytes] of building a FrictionMapLine of ``n_nodes``."""
    return _CHUNK_BYTES + _LINE_NODE_BYTES * int(n_nodes)


def sphere_map_bytes(n_polar, n_azimuth):
    """Return the peak memory [bytes] of building a FrictionMapSphere (per map)."""
    return _CHUNK_BYTES + _SPHERE_NODE_BYTES * (int(n_polar) + 1) * int(n_azimuth)


def _rate_direction_integrals(vx, vy, w, k, n_inside=_N_INSIDE, n_outside=96):
    """
    Normalised (fX, fY, m, p) for rate directions (vx, vy, w) with vx^2+vy^2+w^2 = 1.

    vx, vy are V/a; arrays of equal shape.  Pure sliding (w = 0) is the exact limit.
    """
    vx, vy, w = (np.asarray(t, dtype=float).ravel() for t in (vx, vy, w))
    if vx.size > _BUILD_CHUNK:
        # Every direction is integrated on its own, and the quadrature temporaries cost
        # ~64 kB per direction: a table is built in chunks, so its build needs memory for
        # the table, not for n x n_inside temporaries.  Same numbers.
        return np.concatenate([_rate_direction_integrals(vx[i:i + _BUILD_CHUNK],
                                                         vy[i:i + _BUILD_CHUNK],
                                                         w[i:i + _BUILD_CHUNK], k, n_inside,
                                                         n_outside)
                               for i in range(0, vx.size, _BUILD_CHUNK)], axis=1)
    out = np.zeros((4, vx.size))
    sgn = np.where(w < 0, -1.0, 1.0)
    # (V, w) -> -(V, w) flips the traction: compute with w >= 0, restore the sign after.
    vx, vy, w = vx * sgn, vy * sgn, w * sgn
    sliding = w < 1e-12
    vnorm = np.hypot(vx, vy)
    out[0, sliding] = -vx[sliding] / vnorm[sliding]
    out[1, sliding] = -vy[sliding] / vnorm[sliding]
    out[3, sliding] = vnorm[sliding]

    idx = np.flatnonzero(~sliding)
    if idx.size:
        xc = -vy[idx] / w[idx]              # velocity centre (units of a), physical frame
        yc = vx[idx] / w[idx]
        pxp, pyp = xc, yc / k               # same point in the unit-disc frame
        d = np.hypot(pxp, pyp)
        inside = d < 1.0
        for sel, is_inside in ((np.flatnonzero(inside), True), (np.flatnonzero(~inside), False)):
            if sel.size == 0:
                continue
            if is_inside:
                t = (np.arange(n_inside) + 0.5) * (_TWO_PI / n_inside)
                wts = np.full(n_inside, _TWO_PI / n_inside)
                phi_p = np.broadcast_to(t, (sel.size, n_inside))
                wq = np.broadcast_to(wts, (sel.size, n_inside))
            else:
                # Rays that meet the ellipse form the cone of tangents from the outside centre.
                xg, wg = np.polynomial.legendre.leggauss(n_outside)
                theta0 = np.arctan2(-pyp[sel], -pxp[sel])[:, None]
                alpha = np.arcsin(1.0 / d[sel])[:, None]
                phi_p = theta0 + alpha * xg[None, :]
                wq = alpha * wg[None, :]
            ex, ey = np.cos(phi_p), np.sin(phi_p)
            p = (pxp[sel][:, None], pyp[sel][:, None])
            if is_inside:
                k1, k2 = _ray_integrals_inside(p, (ex, ey))
            else:
                pe = p[0] * ex + p[1] * ey
                px = p[0] * ey - p[1] * ex
                h2 = np.maximum(1.0 - px * px, 0.0)
                m = -pe
                k1 = m * (0.5 * math.pi * h2)
                k2 = m * m * (0.5 * math.pi * h2) + math.pi * h2 * h2 / 8.0
            # Physical ray direction (cos phi', k sin phi') / n, length scale n.
            n = np.sqrt(ex * ex + (k * ey) ** 2)
            cph, sph = ex / n, k * ey / n
            # r_phys = n r' and dA_phys = k dA'; the weight's 1/k cancels the k.
            fx = _NORM * np.sum(wq * sph * k1, axis=1)
            fy = _NORM * np.sum(wq * (-cph) * k1, axis=1)
            lever = xc[sel][:, None] * cph + yc[sel][:, None] * sph
            mz = -_NORM * np.sum(wq * (lever * k1 + n * k2), axis=1)
            loss = _NORM * np.sum(wq * n * k2, axis=1) * w[idx][sel]
            out[0, idx[sel]] = fx
            out[1, idx[sel]] = fy
            out[2, idx[sel]] = mz
            out[3, idx[sel]] = loss
    out[0] *= sgn
    out[1] *= sgn
    out[2] *= sgn
    return out


def _cache_dir():
    """Directory for built tables: $BB_FRICTION_CACHE or ~/.cache/bb_friction_ros."""
    root = os.environ.get("BB_FRICTION_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "bb_friction_ros")
    return Path(root)


_TABLE_VERSION = "1"   # bump when the integration changes, so stale caches are rebuilt


_IN_PROCESS = {}   # tables already loaded here: models built per sample share them (sweeps)


def cached_arrays(name, key, build):
    """
    Return the arrays of a table: from this process, the disk cache, or built and stored.

    ``build()`` returns a dict of numpy arrays; ``key`` (with ``name``) identifies them by
    its repr, so floats in it must be the exact inputs.  Also used for the Hertz and B2B
    constants that need scipy (``hertz``, ``ball_screw.geometry``): a warm cache keeps
    scipy's imports (0.26 s) off the node's start-up.
    """
    where = (str(_cache_dir()), name, key)
    memo = _IN_PROCESS.get(where)
    if memo is None:
        memo = _IN_PROCESS[where] = _cached_on_disk(name, key, build)
    return memo


def _cached_on_disk(name, key, build):
    digest = hashlib.sha256(repr((_TABLE_VERSION, name, key)).encode()).hexdigest()[:16]
    path = _cache_dir() / f"{name}-{digest}.npz"
    try:
        with np.load(path) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, KeyError):
        pass
    arrays = build()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    except OSError:
        pass   # a read-only home only costs a rebuild next time
    return arrays


def _periodic_node_slopes(values, step):
    """Node derivatives of the periodic cubic spline through ``values`` (last axis)."""
    from scipy.interpolate import CubicSpline
    n = values.shape[-1]
    grid = np.arange(n + 1) * step
    closed = np.concatenate([values, values[..., :1]], axis=-1)
    spline = CubicSpline(grid, closed, axis=-1, bc_type="periodic")
    return spline(grid[:-1], 1)


class FrictionMapLine:
    """
    Friction map for slip along the rolling direction only (V_X = 0): the paper's Fig. 5.

    Rate angle u = atan2(V_Y / a, w) in (-pi, pi]; the paper's c/a = -tan(u).
    """

    def __init__(self, ellipticity, n_nodes=4096):
        """Tabulate f_Y, m, p on a uniform periodic grid of ``n_nodes`` rate angles."""
        self.ellipticity = float(ellipticity)
        self.n_nodes = int(n_nodes)
        self.step = _TWO_PI / self.n_nodes

        def build():
            u = -math.pi + np.arange(self.n_nodes) * self.step
            vals = _rate_direction_integrals(np.zeros_like(u), np.sin(u), np.cos(u),
                                             self.ellipticity)
            table = vals[[1, 2, 3]]
            return {"values": table, "slopes": _periodic_node_slopes(table, self.step)}

        arrays = cached_arrays("line", (round(self.ellipticity, 12), self.n_nodes), build)
        self._values, self._slopes = arrays["values"], arrays["slopes"]

    @property
    def hermite_tables(self):
        """(values, node slopes, step): the cubic Hermite table, for compiled evaluators."""
        return self._values, self._slopes, self.step

    def evaluate(self, u, derivative=False):
        """Normalised (f_Y, m, p) at rate angles ``u`` [rad]; with d/du if ``derivative``."""
        t = (np.asarray(u, dtype=float) + math.pi) / self.step
        fl = np.floor(t)
        s = t - fl
        i0 = fl.astype(np.int64) % self.n_nodes
        i1 = (i0 + 1) % self.n_nodes
        y0, y1 = self._values[:, i0], self._values[:, i1]
        d0, d1 = self._slopes[:, i0] * self.step, self._slopes[:, i1] * self.step
        s2, s3 = s * s, s * s * s
        val = ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * d0
               + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * d1)
        if not derivative:
            return val
        der = ((6 * s2 - 6 * s) * y0 + (3 * s2 - 4 * s + 1) * d0
               + (-6 * s2 + 6 * s) * y1 + (3 * s2 - 2 * s) * d1) / self.step
        return val, der

    def exact(self, u):
        """Direct (untabulated) evaluation, for checks."""
        u = np.asarray(u, dtype=float)
        return _rate_direction_integrals(np.zeros_like(u), np.sin(u), np.cos(u),
                                         self.ellipticity)[[1, 2, 3]].reshape((3,) + u.shape)


class FrictionMapSphere:
    """
    Friction map for a general slip (V_X, V_Y) and spin w: needed in ball screws (c and d).

    Rate direction (V_X/a, V_Y/a, w) = (sin t cos h, sin t sin h, cos t), t in [0, pi],
    h in [0, 2 pi).  Bicubic Hermite on a uniform (t, h) grid; t is extended by reflection
    through the poles so the interpolant stays smooth there.
    """

    def __init__(self, ellipticity, n_polar=160, n_azimuth=256):
        """Tabulate (f_X, f_Y, m, p) on a (n_polar + 1) x n_azimuth grid."""
        self.ellipticity = float(ellipticity)
        self.n_polar, self.n_azimuth = int(n_polar), int(n_azimuth)
        self.dt = math.pi / self.n_polar
        self.dh = _TWO_PI / self.n_azimuth

        def build():
            t = np.arange(self.n_polar + 1) * self.dt
            h = np.arange(self.n_azimuth) * self.dh
            tt, hh = np.meshgrid(t, h, indexing="ij")
            vals = _rate_direction_integrals(np.sin(tt) * np.cos(hh), np.sin(tt) * np.sin(hh),
                                             np.cos(tt), self.ellipticity)
            vals = vals.reshape(4, t.size, h.size)
            # Extend over the poles (t -> -t is the same point at h + pi) for smooth slopes.
            half = self.n_azimuth // 2
            ext = np.concatenate([np.roll(vals[:, 1:4][:, ::-1], half, axis=2), vals,
                                  np.roll(vals[:, -4:-1][:, ::-1], half, axis=2)], axis=1)
            from scipy.interpolate import CubicSpline
            dt_ = CubicSpline(np.arange(ext.shape[1]) * self.dt, ext, axis=1)(
                np.arange(3, 3 + t.size) * self.dt, 1)
            dh_ = _periodic_node_slopes(vals, self.dh)
            dth = _periodic_node_slopes(dt_, self.dh)
            return {"values": vals, "dt": dt_, "dh": dh_, "dth": dth}

        key = (round(self.ellipticity, 12), self.n_polar, self.n_azimuth)
        arrays = cached_arrays("sphere", key, build)
        names = ("values", "dt", "dh", "dth")
        self._v, self._dt, self._dh, self._dth = (arrays[k] for k in names)
        self._coef = cached_arrays("sphere-cells", key,
                                   lambda: {"coef": self._cell_coefficients()})["coef"]

    def _cell_coefficients(self):
        """
        Power-basis coefficients of the bicubic Hermite patch of every cell.

        Shape (n_polar * n_azimuth, 4, 16): per cell, power j of s_h, then output o and
        power i of s_t at index 4 o + i (contiguous slices for the Horner steps).  Built from
        the node tables once per map so an evaluation is a single gather and a polynomial
        (no Python loop over corners).
        """
        n_t, n_h = self.n_polar, self.n_azimuth
        i0 = np.arange(n_t)[:, None]
        i1 = i0 + 1
        j0 = np.arange(n_h)[None, :]
        j1 = (j0 + 1) % n_h
        v, ft = self._v, self._dt * self.dt
        fh, fth = self._dh * self.dh, self._dth * (self.dt * self.dh)
        # G[o, cell, a, b]: a = (value at i0, at i1, t-slope at i0, at i1), b likewise in h.
        g = np.stack([
            np.stack([v[:, i0, j0], v[:, i0, j1], fh[:, i0, j0], fh[:, i0, j1]], axis=-1),
            np.stack([v[:, i1, j0], v[:, i1, j1], fh[:, i1, j0], fh[:, i1, j1]], axis=-1),
            np.stack([ft[:, i0, j0], ft[:, i0, j1], fth[:, i0, j0], fth[:, i0, j1]], axis=-1),
            np.stack([ft[:, i1, j0], ft[:, i1, j1], fth[:, i1, j0], fth[:, i1, j1]], axis=-1),
        ], axis=-2)
        hermite = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                            [-3.0, 3.0, -2.0, -1.0], [2.0, -2.0, 1.0, 1.0]])
        c = np.einsum("ia,ocdab,jb->cdjoi", hermite, g, hermite)
        return np.ascontiguousarray(c.reshape(n_t * n_h, 4, 16))

    @property
    def cell_coefficients(self):
        """Per-cell power-basis coefficients (n_polar * n_azimuth, 4, 16); read only."""
        c = self._coef.view()
        c.flags.writeable = False
        return c

    def evaluate_angles(self, t, h):
        """Normalised (f_X, f_Y, m, p) and their t- and h-derivatives at angles (t, h)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, math.pi)
        h = np.asarray(h, dtype=float)
        shape = t.shape
        x = t.ravel() / self.dt
        i0 = np.minimum(x.astype(np.int64), self.n_polar - 1)
        sx = x - i0
        y = np.mod(h.ravel(), _TWO_PI) / self.dh
        j0 = np.minimum(y.astype(np.int64), self.n_azimuth - 1)
        sy = y - j0
        c = self._coef[i0 * self.n_azimuth + j0]                # (cell, j, 4 o + i)
        sy = sy[:, None]
        qv = (((c[:, 3] * sy + c[:, 2]) * sy + c[:, 1]) * sy + c[:, 0]).reshape(-1, 4, 4)
        qd = ((3.0 * c[:, 3] * sy + 2.0 * c[:, 2]) * sy + c[:, 1]).reshape(-1, 4, 4)
        qv, qd = qv.transpose(2, 1, 0), qd.transpose(2, 1, 0)   # (i, o, cell)
        val = ((qv[3] * sx + qv[2]) * sx + qv[1]) * sx + qv[0]
        d_t = ((3.0 * qv[3] * sx + 2.0 * qv[2]) * sx + qv[1]) / self.dt
        d_h = (((qd[3] * sx + qd[2]) * sx + qd[1]) * sx + qd[0]) / self.dh
        out = (4,) + shape
        return val.reshape(out), d_t.reshape(out), d_h.reshape(out)

    def exact(self, t, h):
        """Direct (untabulated) evaluation, for checks."""
        t, h = np.asarray(t, dtype=float), np.asarray(h, dtype=float)
        return _rate_direction_integrals(np.sin(t) * np.cos(h), np.sin(t) * np.sin(h),
                                         np.cos(t), self.ellipticity).reshape((4,) + t.shape)
