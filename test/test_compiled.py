"""
The shared compiled linear algebra (Gauss solver, block back-substitution) and the cache.

Compared with numpy's LAPACK solve of the same systems; the singular retry is checked
against its definition (the Levenberg-Marquardt shifted matrix).  The on-disk cache of a
kernel is checked to follow an edit of the functions it calls in compiled.py, and of its own
file when its size and time stay the same.
"""

import os
from pathlib import Path
import subprocess
import sys

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


def test_gauss_eliminate_solves_and_leaves_a_singular_matrix_to_the_caller():
    """The elimination alone: numpy's solution, or False (no shift) for a singular matrix."""
    d = RNG.normal(size=(7, 7))
    w = RNG.normal(size=(7, 9))
    ref = np.linalg.solve(d, w)
    assert compiled.gauss_eliminate(d.copy(), w, 7, 0)
    np.testing.assert_allclose(w, ref, rtol=1e-12, atol=1e-12)
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    assert not compiled.gauss_eliminate(singular, np.ones((2, 1)), 2, 0)


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


_PROBE_KERNEL = '''
from probe_pkg.compiled import jit, probe_value


@jit
def kernel_value():
    return probe_value() + 0
'''


def _run_probe(root, cache_dir):
    env = dict(os.environ, PYTHONPATH=str(root), NUMBA_CACHE_DIR=str(cache_dir))
    out = subprocess.run(
        [sys.executable, "-c", "from probe_pkg import kern; print(kern.kernel_value(), "
         "sum(kern.kernel_value.stats.cache_hits.values()))"],
        env=env, capture_output=True, text=True, check=True, timeout=300)
    value, hits = out.stdout.split()
    return int(value), int(hits)


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
@pytest.mark.parametrize("cache", ["numba_cache_dir", "pycache"])
def test_a_kernel_never_loads_a_stale_compile_of_a_function_it_calls(tmp_path, cache):
    """
    An edit of compiled.py (or a switch of branch) recompiles the kernels that call into it.

    numba keys a cache on the function's own file; a kernel in another module that calls
    compiled.py's functions kept their old compiled code (measured before ``jit`` keyed the
    caches on compiled.py too).  A copy of compiled.py and a kernel module calling it, run
    in fresh processes: the edited function's new value comes out, from a fresh compile;
    run again, from the cache.
    """
    pkg = tmp_path / "probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    source = Path(compiled.__file__).read_text()
    probe = "\n\n@jit\ndef probe_value():\n    return {}\n"
    (pkg / "compiled.py").write_text(source + probe.format(1))
    (pkg / "kern.py").write_text(_PROBE_KERNEL)
    cache_dir = tmp_path / "cache" if cache == "numba_cache_dir" else ""
    assert _run_probe(tmp_path, cache_dir) == (1, 0)
    assert _run_probe(tmp_path, cache_dir) == (1, 1)        # the cache is used
    (pkg / "compiled.py").write_text(source + probe.format(2))
    assert _run_probe(tmp_path, cache_dir)[0] == 2           # not the stale 1
    assert _run_probe(tmp_path, cache_dir) == (2, 1)


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
def test_a_kernel_never_loads_the_compile_of_another_version_of_the_same_size_and_time(
        tmp_path):
    """
    Two versions of a kernel module alike in size and modification time each run their own code.

    A layout constant changed (32 -> 64) by a checkout within the same second, or by a copy
    that keeps times, must not load the other version's machine code: a cache stamped with
    the file's time and size alone would; numba 0.68 stamps it with the
    file's sha256, and ``jit`` adds compiled.py's.  The constant is a module global, outside
    the function's own bytecode (part of numba's key too).  Each version is run twice, the
    second time from the cache.
    """
    pkg = tmp_path / "probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    source = Path(compiled.__file__).read_text()
    (pkg / "compiled.py").write_text(source + "\n\n@jit\ndef probe_value():\n    return 0\n")
    kern = pkg / "kern.py"
    version = _PROBE_KERNEL.replace("\n\n@jit", "\nLAYOUT = {}\n\n\n@jit").replace(
        "+ 0", "+ LAYOUT")
    cache_dir = tmp_path / "cache"
    stamp = (1_700_000_000, 1_700_000_000)
    for value in (32, 64, 32):
        kern.write_text(version.format(value))
        os.utime(kern, stamp)
        assert _run_probe(tmp_path, cache_dir)[0] == value
        assert _run_probe(tmp_path, cache_dir) == (value, 1)


_PROBE_HELPER = '''
from probe_pkg.compiled import jit
from probe_pkg import kern


@jit
def helper_value():
    return kern.kernel_value() * 10
'''


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
def test_a_test_helper_never_loads_a_stale_compile_of_a_kernel_it_calls(tmp_path):
    """
    A function of a checkout's tests that calls a kernel recompiles when the kernel changes.

    numba keys its cache on the helper's own file: a test kept passing on the kernel's old
    machine code.  A probe checkout (setup.py, the package, test/): the kernel's value
    changed, the helper's value follows, from a fresh compile, then from the cache.
    """
    (tmp_path / "setup.py").write_text("")
    pkg = tmp_path / "probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    source = Path(compiled.__file__).read_text()
    (pkg / "compiled.py").write_text(source + "\n\n@jit\ndef probe_value():\n    return 1\n")
    (tmp_path / "test").mkdir()
    (tmp_path / "test" / "helper_mod.py").write_text(_PROBE_HELPER)
    env = dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{tmp_path / 'test'}",
               NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    code = ("import helper_mod; print(helper_mod.helper_value(), "
            "sum(helper_mod.helper_value.stats.cache_hits.values()))")

    def run():
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True, timeout=300)
        return tuple(int(v) for v in out.stdout.split())

    for add in (0, 5):
        (pkg / "kern.py").write_text(_PROBE_KERNEL.replace("+ 0", f"+ {add}"))
        assert run() == (10 * (1 + add), 0)      # compiled afresh: not the stale value
        assert run() == (10 * (1 + add), 1)      # then from the cache


def test_kernel_modules_call_compiled_functions_of_their_own_file_and_compiled_py_only():
    """What makes the cache key above complete: no kernel imports another kernel module."""
    root = Path(compiled.__file__).parent
    for path in root.rglob("*.py"):
        text = path.read_text()
        if "compiled import jit" not in text:
            continue
        for line in text.splitlines():
            if line.startswith(("from bb_friction_ros", "import bb_friction_ros")):
                assert "kernel" not in line or path.name == "kernel.py" and "compiled" in line, \
                    f"{path.relative_to(root)}: {line}"


if compiled.HAVE_NUMBA:
    @compiled.jit
    def _borrowed_sum_and_double(a, b):
        v = compiled.borrowed(a)
        w = compiled.borrowed(b)
        s = 0.0
        for i in range(v.shape[0]):
            s += v[i]
            v[i] *= 2.0
        corner = w[1:, ::2]          # a view of the borrowed view
        corner[0, 0] = s
        return s, corner.shape[0] * corner.shape[1]

    @compiled.jit
    def _borrowed_through_a_call(a):
        v = compiled.borrowed(a)
        out = np.empty(2)
        out[0], out[1] = _borrowed_sum_and_double(v[:3], v.reshape((2, 2)))
        return out


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
def test_a_borrowed_view_reads_and_writes_the_array_it_borrows():
    """Same values, shape and strides; writes land in the caller's array, views of it too."""
    a = np.arange(1.0, 6.0)
    b = np.zeros((3, 4))
    s, size = _borrowed_sum_and_double(a, b)
    assert s == 15.0 and size == 4
    np.testing.assert_array_equal(a, [2.0, 4.0, 6.0, 8.0, 10.0])
    expected = np.zeros((3, 4))
    expected[1, 0] = 15.0
    np.testing.assert_array_equal(b, expected)
    a = np.arange(4.0)
    out = _borrowed_through_a_call(a)
    np.testing.assert_array_equal(out, [3.0, 1.0])
    np.testing.assert_array_equal(a, [0.0, 2.0, 3.0, 3.0])


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
def test_borrowed_views_neither_leak_nor_free_what_they_borrow():
    """
    Repeated calls leave numba's allocation count where it was and the arrays alive.

    A view that owned a reference it never gave back would leak the array, one that gave
    back a reference it never took would free it under the caller.
    """
    from numba.core.runtime import _nrt_python as nrt, rtsys
    a = np.arange(4.0)
    b = np.zeros((3, 4))
    _borrowed_through_a_call(a)
    _borrowed_sum_and_double(a, b)
    nrt.memsys_enable_stats()
    try:
        before = rtsys.get_allocation_stats()
        refs = sys.getrefcount(a), sys.getrefcount(b)
        for _ in range(1000):
            _borrowed_through_a_call(a)
            _borrowed_sum_and_double(a, b)
        after = rtsys.get_allocation_stats()
    finally:
        nrt.memsys_disable_stats()
    # What the calls allocate (the result, the meminfos of the arguments) is all freed.
    assert after.alloc - before.alloc == after.free - before.free >= 1000
    assert after.mi_alloc - before.mi_alloc == after.mi_free - before.mi_free >= 1000
    assert (sys.getrefcount(a), sys.getrefcount(b)) == refs
    assert a[0] == 0.0 and b[1, 0] > 0.0     # still the callers' arrays


if compiled.HAVE_NUMBA:
    @compiled.jit
    def _carved_views(ws, n):
        a = compiled.carved(ws, 3, (n, 2))
        b = compiled.carved(ws, 3 + 2 * n, (2, n, 3))
        a[1, 1] = -1.0
        return a.sum(), b[1, 2, 0], a.strides, b.strides

    @compiled.jit
    def _carved_of_a_local(n):
        ws = np.arange(40.0)
        return compiled.carved(ws, 3, (n, 2))      # the view keeps ws alive


@pytest.mark.skipif(not compiled.HAVE_NUMBA, reason="numba not installed")
def test_carved_is_the_reshaped_slice():
    """carved(ws, off, shape) is ws[off:off + size].reshape(shape): values, strides, writes."""
    ws = np.arange(40.0)
    ref = ws.copy()
    a = ref[3:11].reshape((4, 2))
    b = ref[11:35].reshape((2, 4, 3))
    a[1, 1] = -1.0
    total, b120, sa, sb = _carved_views(ws, 4)
    np.testing.assert_array_equal(ws, ref)
    assert (total, b120, sa, sb) == (a.sum(), b[1, 2, 0], a.strides, b.strides)
    out = _carved_of_a_local(4)
    np.testing.assert_array_equal(out, np.arange(3.0, 11.0).reshape((4, 2)))
