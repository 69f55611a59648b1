"""
The kernel laid out for the vector units: its atan2, hypot and batched block solves.

The contact evaluation runs with the balls across the vector lanes (``kernel.evaluate_lanes``).
Its two written-out functions are checked against libm, which the numpy model calls: the
polynomial atan2 within its stated bound of 2 ulp, the hypot bit for bit (the contact loads
of the kernel equal the numpy model's exactly, test_fast_solver).  The free balls' 6 x 6
Newton blocks, solved eight lanes at a time, are checked against the scalar Gauss solve,
including the lanes that need a row exchange and a singular block (its Levenberg-Marquardt
retry); so are the written-out solves of a chain's blocks.  These solves are generated
code, and must be what their generator writes.  The friction map's patch, written as vector
code, is checked against its plain reference and for writing its rows and nothing else.
"""

import copy
import importlib.util
import math
import pathlib

import numpy as np
import pytest

from bb_friction_ros import compiled
from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw

pytestmark = pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="numba not installed")
RNG = np.random.default_rng(36)


@compiled.jit
def _atan2_all(y, x, out):
    for i in range(y.shape[0]):
        out[i] = kernel.atan2_poly(y[i], x[i])


@compiled.jit
def _patches(cf, cells, sx, sy, dt, dh, slopes, out, stride):
    for i in range(cells.shape[0]):
        if slopes:
            compiled.bicubic_patch(cf, cells[i], sx[i], sy[i], dt, dh, out, i, stride)
        else:
            compiled.bicubic_values(cf, cells[i], sx[i], sy[i], out, i, stride)


@compiled.jit(exact=True)
def _sincos_all(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = kernel.sincos_poly(x[i])


@compiled.jit(exact=True)
def _fma_all(a, b, c):
    out = np.empty_like(a)
    for i in range(a.shape[0]):
        out[i] = compiled.fused_multiply_add(a[i], b[i], c[i])
    return out


@compiled.jit(exact=True)
def _hypot_all(x, y, out):
    for i in range(x.shape[0]):
        out[i] = kernel.hypot_exact(x[i], y[i])


def _points(n):
    """Every quadrant, ratios 1e-8..1e8, magnitudes 1e-6..1e6, the axes and the diagonals."""
    mag = 10.0 ** RNG.uniform(-6.0, 6.0, n)
    ratio = 10.0 ** RNG.uniform(-8.0, 8.0, n)
    sx = RNG.choice([-1.0, 1.0], n)
    sy = RNG.choice([-1.0, 1.0], n)
    x = np.concatenate([sx * mag, RNG.normal(size=n), [1.0, -1.0, 0.0, 0.0, 1.0, -1.0, 2.0]])
    y = np.concatenate([sy * mag * ratio, RNG.normal(size=n), [0.0, 0.0, 1.0, -1.0, 1.0, 1.0,
                                                               -2.0]])
    return y, x


def test_polynomial_atan2_is_within_two_ulp_of_libm():
    y, x = _points(400_000)
    got = np.empty_like(y)
    _atan2_all(y, x, got)
    ref = np.arctan2(y, x)
    ulp = np.spacing(np.abs(ref))
    assert np.all(np.abs(got - ref) <= 2.0 * ulp)
    assert np.abs(got - ref).max() <= 4.5e-16          # the bound the kernel states, in rad


def test_polynomial_sin_and_cos_are_within_one_ulp_of_libm():
    k = np.arange(-200_000, 200_000)
    x = np.concatenate([RNG.uniform(-1e5, 1e5, 400_000), RNG.uniform(-4.0, 4.0, 400_000),
                        k * (np.pi / 2), k * (np.pi / 2) + RNG.uniform(-1e-6, 1e-6, k.size),
                        10.0 ** RNG.uniform(-12.0, 0.0, 100_000),
                        [0.0, -0.0, 0.3, 0.78125, np.pi / 4, 0.8 * kernel._TRIG_LIMIT]])
    s = np.empty_like(x)
    c = np.empty_like(x)
    _sincos_all(x, s, c)
    for got, ref in ((s, np.sin(x)), (c, np.cos(x))):
        assert np.all(np.abs(got - ref) <= np.spacing(np.abs(ref)))
    # The quadrants: signs and the swap of sine and cosine, on exact values.
    _sincos_all(np.array([np.pi / 2, np.pi, -np.pi / 2, 1.5 * np.pi]), s[:4], c[:4])
    assert s[:4] == pytest.approx([1.0, 0.0, -1.0, -1.0], abs=1e-15)
    assert c[:4] == pytest.approx([0.0, -1.0, 0.0, 0.0], abs=1e-15)


def test_theta_centres_take_libm_beyond_the_polynomial_range():
    # Near the range the polynomial's theta is within 1 ulp of the libm expression; beyond
    # it (a long run: the track azimuth grows with the nut angle) it is libm's exactly.
    amp, cycles, phase, offset, ecc, beta0 = 0.06, 2.0, 0.1, 0.01, 1.2e-4, 0.78
    for phi0, exact in ((0.4 * kernel._TRIG_LIMIT, False), (0.6 * kernel._TRIG_LIMIT, True)):
        phi = phi0 + np.linspace(0.0, 4.0 * np.pi, 37)
        theta, centres = kernel.theta_centres(phi, amp, cycles, phase, offset, ecc, beta0)
        ref = offset + amp * np.sin(cycles * phi + phase)
        cm = ecc * np.cos(beta0 - ref)
        if exact:
            assert np.array_equal(theta, ref)
            assert np.array_equal(centres[:, 0, 0], cm)
        else:
            assert np.abs(theta - ref).max() <= 2.0 * np.spacing(amp)
            assert np.abs(centres[:, 0, 0] - cm).max() <= 2.0 * np.spacing(ecc)


def test_track_azimuth_is_numpys_mod_bit_for_bit():
    # The balls' azimuth in the loaded track by one fused multiply-add, against np.mod:
    # far from the track (a long run), near it, on and next to multiples of the loop, NaN.
    loop = 4.0 * np.pi
    k = np.arange(-3000, 3000)
    az = np.concatenate([RNG.uniform(-1e5, 1e5, 200_000), RNG.uniform(-3 * loop, 3 * loop,
                                                                      200_000),
                         k * loop, k * loop + 1e-13, k * loop - 1e-13,
                         [0.0, -0.0, loop, -loop, np.nextafter(loop, 0.0), 1e-300, -1e-300,
                          np.nan]])
    for start in (0.0, 123.456, -5000.0, 1e4 * loop):
        phi = np.empty_like(az)
        kernel._track_azimuth_into(az, start, loop, phi)
        ref = start + np.mod(az - start, loop)
        assert np.array_equal(phi, ref, equal_nan=True)


def test_fused_multiply_add_rounds_once():
    # a * b + c with the product kept exact: against exact rationals, where a product
    # rounded first would differ.
    from fractions import Fraction
    a = RNG.uniform(-10.0, 10.0, 2000)
    b = RNG.uniform(-10.0, 10.0, 2000)
    c = -a * b + RNG.uniform(-1e-12, 1e-12, 2000)
    got = _fma_all(a, b, c)
    ref = np.array([float(Fraction(x) * Fraction(y) + Fraction(z)) for x, y, z in zip(a, b, c)])
    assert np.array_equal(got, ref)
    assert not np.array_equal(a * b + c, ref)


def test_written_out_hypot_is_libm_bit_for_bit():
    y, x = _points(400_000)
    # Contact-like inputs too: a distance of about 1e-3 with a tiny second component.
    x = np.concatenate([x, RNG.uniform(0.9, 1.1, 100_000) * 1e-3])
    y = np.concatenate([y, RNG.uniform(-1.0, 1.0, 100_000) * 1e-9])
    # Both scaling branches (huge and tiny operands) and a zero.
    x = np.concatenate([x, [1e300, 3e-310, 1e-320, 0.0, 2.0 ** 520]])
    y = np.concatenate([y, [2e299, 1e-310, 0.0, 0.0, 3.0]])
    got = np.empty_like(x)
    _hypot_all(x, y, got)
    np.testing.assert_array_equal(got, np.hypot(x, y))


def _scalar_solve(jac, res, b):
    d, w = np.empty((7, 7)), np.empty((7, 9))
    d[:6, :6] = jac[b, :, :6]
    w[:6, 7] = res[b]
    w[:6, 8] = jac[b, :, 6]
    assert compiled.gauss_solve(d, w, 6, 7, np.empty((7, 7)), np.empty((7, 9)))
    return w[:6, 7:9]


@pytest.mark.parametrize("nf", [1, 8, 21, 70])
def test_free_blocks_solved_across_lanes_equal_the_scalar_solve(nf):
    n = nf + 3
    jac = RNG.normal(size=(n, 6, 7))
    res = RNG.normal(size=(n, 6))
    jac[0, 0, 0] = 0.0                                    # needs a row exchange
    jac[1, :, 1] = 2.0 * jac[1, :, 0]                     # singular: the shifted retry
    order = RNG.permutation(n)[:nf]
    free = np.stack([order, np.arange(nf)], axis=1).astype(np.int64)
    xs = np.full((n, 7, 9), np.nan)
    work = [np.empty((7, 7)), np.empty((7, 9)), np.empty((7, 7)), np.empty((7, 9))]
    kernel.solve_free_blocks(jac, res, free, nf, xs, np.empty(kernel.FB_ROWS * 64), *work,
                             np.empty(0), False, 1.0, 1.0)
    for b, k in free:
        np.testing.assert_allclose(xs[k, :6, 7:9], _scalar_solve(jac, res, b), rtol=1e-11,
                                   atol=1e-11 * np.abs(_scalar_solve(jac, res, b)).max())


def test_a_copied_screw_has_work_arrays_of_its_own():
    """The look-ahead steps a copy of the live screw, possibly in another thread."""
    screw = WholeScrew(load_ball_screw())
    other = copy.copy(screw)
    assert all(a is not b for a, b in zip(screw._work, other._work))
    w = 2.0 * math.pi
    for k in range(1, 6):
        ra = screw.step(k * 0.03, w, 1500.0, 0.005)
    for k in range(1, 6):
        rb = other.step(k * 0.03, w, 1500.0, 0.005)
    assert ra.torque_total_nm == rb.torque_total_nm


def test_block_solves_are_what_their_generator_writes():
    root = pathlib.Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("gen_block_solves",
                                                  root / "tools" / "gen_block_solves.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    text = gen.KERNEL.read_text()
    assert gen.rewritten(text) == text, "run tools/gen_block_solves.py"
    assert gen.main(["--check"]) == 0
    # The check fails on a kernel whose generated function was edited by hand.
    edited = text.replace("bad = 0.0", "bad = 0.5", 1)
    assert gen.rewritten(edited) != edited


@compiled.jit
def _block_solves(d, w, n):
    return kernel._block_solve7(d, w) if n == 7 else kernel._block_solve6(d, w)


@pytest.mark.parametrize("n, j0", [(7, 0), (6, 7)])
def test_chain_block_solves_equal_the_scalar_gauss_solve(n, j0):
    for case in range(20):
        d = RNG.normal(size=(7, 7))
        w = RNG.normal(size=(7, 9))
        if case % 2:
            d[0, 0] = 0.0                   # needs row exchanges
        want_w = w.copy()
        assert compiled.gauss_solve(d.copy(), want_w, n, j0, np.empty((7, 7)),
                                    np.empty((7, 9)))
        got_w = w.copy()
        assert _block_solves(d.copy(), got_w, n)
        np.testing.assert_allclose(got_w[:n, j0:], want_w[:n, j0:], rtol=1e-12,
                                   atol=1e-12 * np.abs(want_w[:n, j0:]).max())
        # Columns outside the right-hand sides are left alone.
        np.testing.assert_array_equal(got_w[:, :j0], w[:, :j0])


@pytest.mark.parametrize("n", [7, 6])
def test_a_singular_chain_block_is_left_for_the_retry(n):
    d = RNG.normal(size=(7, 7))
    d[:, 1] = 0.0                           # singular: the caller's gauss_solve retries
    w = RNG.normal(size=(7, 9))
    d_in, w_in = d.copy(), w.copy()
    assert not _block_solves(d, w, n)
    np.testing.assert_array_equal(d, d_in)
    np.testing.assert_array_equal(w, w_in)


@pytest.mark.parametrize("n", [5, 37, 64])
def test_free_blocks_read_in_place_from_the_evaluation_rows_equal_those_copied_out(n):
    # evaluate_lanes leaves ball b's Jacobian entry (r, j) at row _ACC_JAC + 7 j + r and its
    # unscaled residual at row r, lane b; the residual is scaled by 1 / scale (forces) and
    # 1 / (R_B scale) (moments), here 2 and 4: exact, so both solves see the same numbers.
    jac = RNG.normal(size=(n, 6, 7))
    res = RNG.normal(size=(n, 6))
    jac[0, 0, 0] = 0.0                                    # needs a row exchange
    jac[1, :, 1] = 0.0                                    # singular: the shifted retry
    rows = np.full(kernel._ACC_ROWS * kernel._CHUNK, np.nan)
    for b in range(n):
        for r in range(6):
            rows[r * kernel._CHUNK + b] = res[b, r] / (2.0 if r < 3 else 4.0)
            for j in range(7):
                rows[(kernel._ACC_JAC + 7 * j + r) * kernel._CHUNK + b] = jac[b, r, j]
    for r in range(kernel._ACC_ROWS):                     # padded lanes: open contacts
        rows[r * kernel._CHUNK + n:(r + 1) * kernel._CHUNK] = 0.0
    free = np.stack([RNG.permutation(n), np.arange(n)], axis=1).astype(np.int64)[:n - 2]
    nf = free.shape[0]
    work = [np.empty((7, 7)), np.empty((7, 9)), np.empty((7, 7)), np.empty((7, 9))]
    xs_rows = np.full((n, 7, 9), np.nan)
    kernel.solve_free_blocks(np.empty((0, 6, 7)), res, free, nf, xs_rows,
                             np.empty(kernel.FB_ROWS * 64), *work, rows, True, 2.0, 4.0)
    xs_arrays = np.full((n, 7, 9), np.nan)
    kernel.solve_free_blocks(jac, res, free, nf, xs_arrays, np.empty(kernel.FB_ROWS * 64),
                             *work, np.empty(0), False, 2.0, 4.0)
    ks = free[:, 1]
    np.testing.assert_array_equal(xs_rows[ks, :6, 7:9], xs_arrays[ks, :6, 7:9])
    assert np.isfinite(xs_rows[ks, :6, 7:9]).all()


@pytest.mark.parametrize("slopes", [True, False])
def test_vector_map_patch_equals_its_reference_and_writes_only_its_rows(slopes):
    # A table of cells of 4 x 16 coefficients spanning magnitudes, points anywhere in a cell.
    n_cells, n, stride = 50, 40, 48
    cf = RNG.standard_normal((n_cells, 4, 16)) * 10.0 ** RNG.uniform(-3, 3, (n_cells, 4, 16))
    cells = RNG.integers(0, n_cells, n)
    sx, sy = RNG.uniform(0, 1, n), RNG.uniform(0, 1, n)
    dt, dh = 0.0175, 0.0349
    out = np.full(12 * stride, np.nan)
    ref = np.full(12 * stride, np.nan)
    _patches(cf, cells, sx, sy, dt, dh, slopes, out, stride)
    for i in range(n):
        compiled.patch_reference(cf, cells[i], sx[i], sy[i], dt, dh, ref, i, stride, slopes)
    rows = [0, 1, 2, 3] + ([4, 5, 6, 8, 9, 10] if slopes else [])
    got, want = out.reshape(12, stride), ref.reshape(12, stride)
    # Every coefficient's term bounds the rounding: a few ulp of the largest term.
    scale = np.abs(cf[cells]).max(axis=(1, 2)) / min(dt, dh)
    for r in rows:
        assert np.all(np.abs(got[r, :n] - want[r, :n]) <= 8 * np.finfo(float).eps * scale), r
    # Nothing else written: the other rows, and the lanes past the last.
    untouched = [r for r in range(12) if r not in rows]
    assert np.all(np.isnan(got[untouched])) and np.all(np.isnan(got[:, n:]))
