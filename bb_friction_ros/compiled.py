"""
What the compiled (numba) kernels share: the jit decorator and two linear-algebra loops.

The ball-screw kernel (``ball_screw/kernel.py``) and the linear-bearing kernel
(``linear_bearing/kernel.py``) each solved small dense systems with their own Gaussian
elimination, and the ball screw's rigid and elastic Newton systems each had their own block
back-substitution.  One implementation of each lives here.

Why hand-written loops rather than scipy/LAPACK: the systems are 7 x 7 to 9 x 9 (ball screw)
and 3 g x 3 g (linear bearing) and are solved inside compiled loops thousands of times per
second; a call out to LAPACK from numba costs more than the elimination itself (measured on
both models: the numpy paths were dominated by such per-call overhead).

Without numba the module still imports: ``jit`` returns the plain Python function and
``HAVE_NUMBA`` is False (the models then use their numpy paths, which call nothing here
except the ball screw's elastic system, run as plain Python).

The on-disk cache: numba keys a function's cache on its own source file only, so a kernel
of ``ball_screw/kernel.py`` would keep the compiled copy of an old ``gauss_solve`` after an
edit here (found 2026-11-26, when an edit here timed the same code twice).  ``jit`` therefore
keys every cache of this package on its own file *and* this one (``_DependencyLocator``): an
edit of either, or a switch of git branch, recompiles.  Rule that makes this complete: a
kernel module calls compiled functions of its own file and of this one only
(test_compiled checks both).
"""

import hashlib
import math
import os
import sys


def _import_numba():
    """
    Import numba without two imports of its own that these kernels never use (start-up).

    - ``coverage`` (58 ms, measured with -X importtime): numba's coverage support imports it
      whenever it is installed (pytest-cov puts it in the venv, many ROS installs have it),
      but uses it only with ``NUMBA_JIT_COVERAGE`` set.
    - ``scipy.linalg`` (0.14-0.2 s): importing numba's numpy registry
      (``numba.np.arraymath``, at the first compiled call otherwise) checks for a BLAS by
      importing ``scipy.linalg.cython_blas``, whose package imports most of scipy.  The
      check only picks the inner product of np.correlate and np.convolve, which no kernel
      here calls; np.dot and np.linalg in a kernel would still find BLAS (they import it
      when compiled).

    Each is hidden (``sys.modules[name] = None``: the import raises ImportError) only while
    numba's modules import, and only if nothing imported it yet; the entries are removed
    afterwards, so a later ``import coverage`` or ``import scipy.linalg`` works as always.
    Half of the node's ~0.45 s of numba loading was these two (docs/node_latency.md).
    """
    hidden = [name for name in ("coverage", "scipy.linalg.cython_blas")
              if name not in sys.modules
              and not (name == "coverage" and os.environ.get("NUMBA_JIT_COVERAGE"))]
    for name in hidden:
        sys.modules[name] = None
    try:
        import numba
        try:
            import numba.np.arraymath   # noqa: F401  (the registry module with the BLAS check)
        except ImportError:     # another numba layout: its registries load as they come
            pass
    finally:
        for name in hidden:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]
    return numba


_THIS_FILE = os.path.abspath(__file__)
_PACKAGE_DIR = os.path.dirname(_THIS_FILE)


def _file_digest(path):
    """sha256 of a file's content (the shared part of every cache key of this package)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def _install_dependency_locator(caching):
    """
    Make numba key this package's caches on their own file and on this one.

    A locator put first in numba's list: for a function defined in this package it finds the
    cache where numba would (``NUMBA_CACHE_DIR`` or ``__pycache__``) and extends numba's own
    source stamp with this file's digest.  Functions outside the package are left to numba.
    Returns False if this numba has no such locator list (the hazard is then numba's).
    """
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if not isinstance(classes, list):
        return False
    shared = _file_digest(_THIS_FILE)

    class _DependencyLocator:
        """numba's locator for the function, its source stamp extended (see above)."""

        def __init__(self, inner):
            self._inner = inner

        def ensure_cache_path(self):
            return self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return (self._inner.get_source_stamp(), shared)

        def get_disambiguator(self):
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.abspath(py_file).startswith(_PACKAGE_DIR + os.sep):
                return None
            for other in classes:
                if other is cls:
                    continue
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    classes.insert(0, _DependencyLocator)
    return True


try:
    numba = _import_numba()
    HAVE_NUMBA = True
    from numba.core import caching as _caching
    DEPENDENCY_KEYED_CACHE = _install_dependency_locator(_caching)

    def jit(fn=None, exact=False, inline=False):
        """
        Compile ``fn`` with numba (no Python objects), cached on disk.

        fastmath limited to FMA contraction, reciprocals and reassociation (20 % faster
        evaluation in the ball-screw kernel, agrees with the numpy path to ~1e-14); never
        nnan/ninf: the line searches test for non-finite residuals.  ``exact=True``
        (``@jit(exact=True)``): no fastmath at all, for code that must round exactly as the
        numpy code it replaces (a fused multiply-add differs in the last bit).  nogil: the
        live node's input thread takes and answers inputs while the model thread is inside
        a solve.  ``inline=True``: numba inlines the function into its callers' own code (a
        call inside a loop keeps the loop from being vectorised; LLVM's own inlining of a
        function with several results into a loop was measured not to happen).
        """
        if fn is None:
            return lambda f: jit(f, exact, inline)
        return numba.njit(cache=True, error_model="numpy", nogil=True,
                          inline="always" if inline else "never",
                          fastmath=False if exact else {"contract", "arcp", "reassoc"})(fn)
    from numba.core import cgutils as _cgutils
    from numba.core import types as _types
    from numba.core.extending import intrinsic as _intrinsic

    @_intrinsic
    def borrowed(typingctx, arr):
        """
        Return a view of ``arr`` that owns nothing (meminfo NULL), inside compiled code.

        Every array a compiled function holds, passes or slices is reference counted by
        numba (an atomic increment and decrement of its owner's count each time; measured
        with perf: about a fifth of a warm step of the ball screw, ~100 array arguments and
        views per evaluation).  A view without an owner skips both, and so do the views and
        slices taken of it.  Only for an array that stays alive for the whole call that
        borrows it, i.e. an argument passed in: never return such a view, store it, or take
        it of an array the function allocates (numba frees a local after its last use).
        """
        if not isinstance(arr, _types.Array):
            return None

        def codegen(context, builder, sig, args):
            view = context.make_array(arr)(context, builder, value=args[0])
            view.meminfo = _cgutils.get_null_value(view.meminfo.type)
            view.parent = _cgutils.get_null_value(view.parent.type)
            return view._getvalue()

        return arr(arr), codegen

    @_intrinsic
    def carved(typingctx, base, off, shape):
        """
        Return base[off:off + prod(shape)] as a C-contiguous array of ``shape`` (a view).

        ``base[a:b].reshape(shape)`` without numba's reshape, which calls out to a C
        helper for every view (measured: with the views' own bookkeeping about 3 % of a
        warm step, ~100 views per step).  base: a 1-D C-contiguous array.
        """
        if not (isinstance(base, _types.Array) and base.ndim == 1 and base.layout == "C"
                and isinstance(off, _types.Integer) and isinstance(shape, _types.BaseTuple)
                and all(isinstance(t, _types.Integer) for t in shape)):
            return None
        rettype = base.copy(ndim=len(shape), layout="C")

        def codegen(context, builder, sig, args):
            from numba.core.imputils import impl_ret_borrowed
            from numba.np.arrayobj import populate_array
            src = context.make_array(base)(context, builder, value=args[0])
            intp = context.get_value_type(_types.intp)
            dims = [context.cast(builder, v, t, _types.intp)
                    for v, t in zip(_cgutils.unpack_tuple(builder, args[2]), shape)]
            itemsize = context.get_constant(_types.intp, context.get_abi_sizeof(
                context.get_data_type(base.dtype)))
            strides = [None] * len(dims)
            acc = itemsize
            for k in range(len(dims) - 1, -1, -1):
                strides[k] = acc
                acc = builder.mul(acc, dims[k])
            start = context.cast(builder, args[1], off, _types.intp)
            out = context.make_array(rettype)(context, builder)
            populate_array(out, data=builder.gep(src.data, [start]),
                           shape=_cgutils.pack_array(builder, dims, ty=intp),
                           strides=_cgutils.pack_array(builder, strides, ty=intp),
                           itemsize=itemsize, meminfo=src.meminfo, parent=None)
            return impl_ret_borrowed(context, builder, rettype, out._getvalue())

        return rettype(base, off, shape), codegen
except ImportError:        # pragma: no cover - numba is an exec_depend
    HAVE_NUMBA = False
    DEPENDENCY_KEYED_CACHE = False

    def jit(fn=None, exact=False, inline=False):
        """Without numba: the plain Python function."""
        if fn is None:
            return lambda f: f
        return fn

    def borrowed(arr):
        """Without numba: the array itself."""
        return arr

    def carved(base, off, shape):
        """Without numba: base[off:off + prod(shape)].reshape(shape)."""
        size = 1
        for d in shape:
            size *= d
        return base[off:off + size].reshape(shape)

# Levenberg-Marquardt shift of a singular matrix, relative to its largest entry: sqrt(eps)
# of float64 (the numpy paths use the same shift).
_LM_SHIFT = math.sqrt(2.220446049250313e-16)


@jit
def gauss_eliminate(d, w, n, j0):
    """
    Solve d[:n, :n] @ X = w[:n, j0:] in place (w <- X) by Gaussian elimination, no retry.

    Partial pivoting; d is overwritten.  Returns False, with d and w part way through, if a
    pivot is zero or not finite (``gauss_solve`` then retries from its copies).
    """
    m = w.shape[1]
    for col in range(n):
        piv = col
        big = abs(d[col, col])
        for r in range(col + 1, n):
            if abs(d[r, col]) > big:
                big = abs(d[r, col])
                piv = r
        if big == 0.0 or not math.isfinite(big):
            return False
        if piv != col:
            for j in range(n):
                tmp = d[col, j]
                d[col, j] = d[piv, j]
                d[piv, j] = tmp
            for j in range(j0, m):
                tmp = w[col, j]
                w[col, j] = w[piv, j]
                w[piv, j] = tmp
        inv = 1.0 / d[col, col]
        for r in range(col + 1, n):
            fac = d[r, col] * inv
            if fac != 0.0:
                for j in range(col + 1, n):
                    d[r, j] -= fac * d[col, j]
                for j in range(j0, m):
                    w[r, j] -= fac * w[col, j]
    for col in range(n - 1, -1, -1):
        inv = 1.0 / d[col, col]
        for j in range(j0, m):
            acc = w[col, j]
            for k in range(col + 1, n):
                acc -= d[col, k] * w[k, j]
            w[col, j] = acc * inv
    return True


@jit
def gauss_solve(d, w, n, j0, d0, w0):
    """
    Solve d[:n, :n] @ X = w[:n, j0:] in place (w <- X) by Gaussian elimination.

    Partial pivoting (``gauss_eliminate``).  A singular (or non-finite) matrix is solved once
    more with a Levenberg-Marquardt diagonal shift sqrt(eps) max|d| (the numpy paths' shift).
    d is overwritten; d0 (>= n x n) and w0 (>= n x w.shape[1]) are work arrays for the copies
    the retry needs.  Returns False if the shifted matrix is singular too (w is then
    undefined).
    """
    m = w.shape[1]
    for r in range(n):
        for j in range(n):
            d0[r, j] = d[r, j]
        for j in range(j0, m):
            w0[r, j] = w[r, j]
    if gauss_eliminate(d, w, n, j0):
        return True
    big = 1e-300
    for r in range(n):
        for j in range(n):
            big = max(big, abs(d0[r, j]))
    shift = _LM_SHIFT * big
    for r in range(n):
        for j in range(n):
            d[r, j] = d0[r, j]
        d[r, r] += shift
        for j in range(j0, m):
            w[r, j] = w0[r, j]
    return gauss_eliminate(d, w, n, j0)


@jit
def back_substitute_block(xs, ys, k, last):
    """
    One block of the back-substitution of a block-tridiagonal (Thomas) sweep.

    The forward sweep left, per block k of size b = ys.shape[1], xs[k, :, :b] = D_k^-1 U_k
    (the coupling to block k+1) and xs[k, :, b:b+2] = D_k^-1 times the two right-hand sides.
    Writes block k's two solutions ys[k, :, 0:2] = xs[k, :, b:b+2] - xs[k, :, :b] @ ys[k+1]
    (without the product when ``last``: block k is the last of its sweep).  Called for k
    from the last block down; shared by the rigid (b = 7) and the elastic (b = 9) Newton
    systems of the ball screw.
    """
    nb = ys.shape[1]
    for r in range(nb):
        yv = xs[k, r, nb]
        zv = xs[k, r, nb + 1]
        if not last:
            for m in range(nb):
                yv -= xs[k, r, m] * ys[k + 1, m, 0]
                zv -= xs[k, r, m] * ys[k + 1, m, 1]
        ys[k, r, 0] = yv
        ys[k, r, 1] = zv
