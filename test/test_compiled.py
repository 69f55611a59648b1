"""
The shared compiled linear algebra: Gauss solver and block back-substitution.

Compared with numpy's LAPACK solve of the same systems; the singular retry is checked
against its definition (the Levenberg-Marquardt shifted matrix).
"""

import numpy as np
import pytest

from bb_friction_ros import compiled

RNG = np.random.default_rng(20)


@pytest.mark.parametrize("n, cols, j0", [(7, 9, 0), (6, 9, 7), (9, 11, 0), (4, 1, 0)])
def test_gauss_solve_equals_numpy_solve(n, cols, j0):
    """d[:n, :n] X = w[:n, j0:] in place, also when w has more rows and columns than used."""
    size = max(n, 9)
    d = RNG.normal(size=(size, size))
    w = RNG.normal(size=(size, cols))
    ref = np.linalg.solve(d[:n, :n], w[:n, j0:])
    untouched = w[:, :j0].copy()
    work_d, work_w = np.empty((size, size)), np.empty((size, cols))
    assert compiled.gauss_solve(d.copy(), w, n, j0, work_d, work_w)
    np.testing.assert_allclose(w[:n, j0:], ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(w[:, :j0], untouched)


def test_gauss_solve_pivots():
    """A zero on the diagonal needs a row exchange, not the singular retry."""
    d = np.array([[0.0, 2.0], [3.0, 1.0]])
    w = np.array([[4.0], [5.0]])
    assert compiled.gauss_solve(d.copy(), w, 2, 0, np.empty((2, 2)), np.empty((2, 1)))
    np.testing.assert_allclose(w[:, 0], [1.0, 2.0], rtol=1e-15)


def test_gauss_solve_singular_matrix_gets_the_levenberg_marquardt_shift():
    """A singular block is solved with d + sqrt(eps) max|d| I, as the numpy paths do."""
    d = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 3.0]])
    w = np.array([[1.0], [2.0], [3.0]])
    shift = np.sqrt(np.finfo(float).eps) * np.abs(d).max()
    ref = np.linalg.solve(d + shift * np.eye(3), w)
    assert compiled.gauss_solve(d.copy(), w, 3, 0, np.empty((3, 3)), np.empty((3, 1)))
    np.testing.assert_allclose(w, ref, rtol=1e-6)


def test_gauss_solve_reports_a_matrix_it_cannot_solve():
    """Non-finite entries stay unsolvable after the shift: False, for the caller to stop."""
    d = np.full((2, 2), np.nan)
    assert not compiled.gauss_solve(d, np.ones((2, 1)), 2, 0, np.empty((2, 2)),
                                    np.empty((2, 1)))


@pytest.mark.parametrize("nb, blocks", [(7, 5), (9, 4), (2, 1)])
def test_back_substitution_solves_the_block_tridiagonal_system(nb, blocks):
    """
    A Thomas sweep (forward elimination here, back-substitution by the shared function)
    solves a block-tridiagonal system with two right-hand sides like a dense solve.
    """
    dim = nb * blocks
    diag = [RNG.normal(size=(nb, nb)) + 4.0 * np.eye(nb) for _ in range(blocks)]
    upper = [RNG.normal(size=(nb, nb)) for _ in range(blocks - 1)]
    lower = [RNG.normal(size=(nb, nb)) for _ in range(blocks - 1)]
    rhs = RNG.normal(size=(dim, 2))
    full = np.zeros((dim, dim))
    for k in range(blocks):
        s = slice(k * nb, (k + 1) * nb)
        full[s, s] = diag[k]
        if k < blocks - 1:
            t = slice((k + 1) * nb, (k + 2) * nb)
            full[s, t] = upper[k]
            full[t, s] = lower[k]
    ref = np.linalg.solve(full, rhs)
    xs = np.empty((blocks, nb, nb + 2))
    ys = np.empty((blocks, nb, 2))
    for k in range(blocks):
        d = diag[k].copy()
        w = np.concatenate([upper[k] if k < blocks - 1 else np.zeros((nb, nb)),
                            rhs[k * nb:(k + 1) * nb]], axis=1)
        if k:
            d -= lower[k - 1] @ xs[k - 1, :, :nb]
            w[:, nb:] -= lower[k - 1] @ xs[k - 1, :, nb:]
        xs[k] = np.linalg.solve(d, w)
    for k in range(blocks - 1, -1, -1):
        compiled.back_substitute_block(xs, ys, k, k == blocks - 1)
    np.testing.assert_allclose(ys.reshape(dim, 2), ref, rtol=1e-10, atol=1e-12)
