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
# A source checkout (setup.py beside the package): its tests, benches and tools compile
# functions that call the package's kernels, and numba keys their caches on their own file.
_CHECKOUT_DIR = os.path.dirname(_PACKAGE_DIR)
_CHECKOUT_DIRS = tuple(os.path.join(_CHECKOUT_DIR, d) + os.sep
                       for d in ("test", "bench", "tools"))
_IS_CHECKOUT = os.path.isfile(os.path.join(_CHECKOUT_DIR, "setup.py"))


def _file_digest(path):
    """sha256 of a file's content (the shared part of every cache key of this package)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def _package_digest():
    """sha256 of every module of the package (the key of a checkout's test helpers)."""
    h = hashlib.sha256()
    for root, dirs, files in os.walk(_PACKAGE_DIR):
        dirs.sort()
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(root, name)
                h.update(os.path.relpath(path, _PACKAGE_DIR).encode())
                h.update(_file_digest(path).encode())
    return h.hexdigest()


def _install_dependency_locator(caching):
    """
    Make numba key this package's caches on their own file and on this one.

    A locator put first in numba's list: for a function defined in this package it finds the
    cache where numba would (``NUMBA_CACHE_DIR`` or ``__pycache__``) and extends numba's own
    source stamp with this file's digest.  A function of a source checkout's tests, benches
    or tools may call any kernel: its stamp is extended with every module's digest (a test
    helper that kept a kernel's old compiled code passed on code that had changed: seen).
    Other functions are left to numba.  Returns False if this numba has no such locator
    list (the hazard is then numba's).
    """
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if not isinstance(classes, list):
        return False
    shared = _file_digest(_THIS_FILE)
    whole = []      # _package_digest(), computed when a checkout's helper first needs it

    class _DependencyLocator:
        """numba's locator for the function, its source stamp extended (see above)."""

        def __init__(self, inner, helper=False):
            self._inner = inner
            self._helper = helper

        def ensure_cache_path(self):
            return self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            if self._helper:
                if not whole:
                    whole.append(_package_digest())
                return (self._inner.get_source_stamp(), shared, whole[0])
            return (self._inner.get_source_stamp(), shared)

        def get_disambiguator(self):
            return self._inner.get_disambiguator()

        @classmethod
        def from_function(cls, py_func, py_file):
            path = os.path.abspath(py_file)
            helper = _IS_CHECKOUT and path.startswith(_CHECKOUT_DIRS)
            if not (helper or path.startswith(_PACKAGE_DIR + os.sep)):
                return None
            for other in classes:
                if other is cls:
                    continue
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner, helper)
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

    def _patch_codegen(slopes):
        """Code of ``bicubic_patch`` (``slopes``: with the t- and h-derivatives)."""
        from llvmlite import ir

        def codegen(context, builder, sig, args):
            cf_t, out_t = sig.args[0], sig.args[6 if slopes else 4]
            cf_v, cell, sx, sy = args[0], args[1], args[2], args[3]
            out_v, base, stride = args[-3], args[-2], args[-1]
            dbl = ir.DoubleType()
            v8, v4 = ir.VectorType(dbl, 8), ir.VectorType(dbl, 4)
            i32, i64 = ir.IntType(32), ir.IntType(64)
            fma8 = _cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(v8, [v8, v8, v8]), "llvm.fmuladd.v8f64")
            fma4 = _cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(v4, [v4, v4, v4]), "llvm.fmuladd.v4f64")

            def splat(x, vt):
                one = builder.insert_element(ir.Constant(vt, ir.Undefined), x,
                                             ir.Constant(i32, 0))
                return builder.shuffle_vector(one, ir.Constant(vt, ir.Undefined),
                                              ir.Constant(ir.VectorType(i32, vt.count), None))

            cfa = context.make_array(cf_t)(context, builder, value=cf_v)
            zero = ir.Constant(i64, 0)
            cell_i = context.cast(builder, cell, sig.args[1], _types.intp)
            row0 = _cgutils.get_item_pointer(context, builder, cf_t, cfa,
                                             [cell_i, zero, zero])

            def load8(k):
                ld = builder.load(builder.bitcast(builder.gep(row0, [ir.Constant(i64, 8 * k)]),
                                                  v8.as_pointer()))
                ld.align = 8
                return ld

            rows = [load8(k) for k in range(8)]     # row j of the cell: rows[2 j], rows[2 j + 1]
            sy2 = builder.fmul(sy, sy)
            sy3 = builder.fmul(sy2, sy)
            sx2 = builder.fmul(sx, sx)
            sx3 = builder.fmul(sx2, sx)
            y1, y2, y3 = splat(sy, v8), splat(sy2, v8), splat(sy3, v8)
            # Coefficient b = 4 o + p at s_h: c0 + c1 s_h + c2 s_h^2 + c3 s_h^3, the scalar
            # expression's order.
            q = [builder.call(fma8, [rows[6 + h], y3, builder.call(
                fma8, [rows[4 + h], y2, builder.call(fma8, [rows[2 + h], y1, rows[h]])])])
                 for h in range(2)]

            def by_power(pair):
                # (o0 p0..p3, o1 ...), (o2 ..., o3 ...) -> per power p the four outputs.
                return [builder.shuffle_vector(pair[0], pair[1], ir.Constant(
                    ir.VectorType(i32, 4), [p, 4 + p, 8 + p, 12 + p])) for p in range(4)]

            x1, x2, x3 = splat(sx, v4), splat(sx2, v4), splat(sx3, v4)

            def in_sx(c):
                return builder.call(fma4, [c[3], x3, builder.call(
                    fma4, [c[2], x2, builder.call(fma4, [c[1], x1, c[0]])])])

            qp = by_power(q)
            outs = [(in_sx(qp), 4)]
            if slopes:
                two8, three8 = splat(ir.Constant(dbl, 2.0), v8), splat(ir.Constant(dbl, 3.0), v8)
                two4, three4 = splat(ir.Constant(dbl, 2.0), v4), splat(ir.Constant(dbl, 3.0), v4)
                d = [builder.call(fma8, [builder.fmul(three8, rows[6 + h]), y2, builder.call(
                    fma8, [builder.fmul(two8, rows[4 + h]), y1, rows[2 + h]])])
                     for h in range(2)]
                vt = builder.call(fma4, [builder.fmul(three4, qp[3]), x2, builder.call(
                    fma4, [builder.fmul(two4, qp[2]), x1, qp[1]])])
                outs.append((builder.fdiv(vt, splat(args[4], v4)), 3))
                outs.append((builder.fdiv(in_sx(by_power(d)), splat(args[5], v4)), 3))
            outa = context.make_array(out_t)(context, builder, value=out_v)
            b0 = context.cast(builder, base, sig.args[-2], _types.intp)
            st = context.cast(builder, stride, sig.args[-1], _types.intp)
            for g, (vec, count) in enumerate(outs):
                for o in range(count):
                    idx = builder.add(b0, builder.mul(st, ir.Constant(i64, 4 * g + o)))
                    ptr = _cgutils.get_item_pointer(context, builder, out_t, outa, [idx])
                    builder.store(builder.extract_element(vec, ir.Constant(i32, o)), ptr)
            return context.get_dummy_value()
        return codegen

    def _patch_types(cf, out, ints):
        """Tell whether ``bicubic_patch`` takes these argument types."""
        return (isinstance(cf, _types.Array) and cf.ndim == 3 and cf.layout == "C"
                and cf.dtype == _types.float64 and isinstance(out, _types.Array)
                and out.ndim == 1 and out.dtype == _types.float64 and out.mutable
                and all(isinstance(t, _types.Integer) for t in ints))

    @_intrinsic
    def bicubic_values(typingctx, cf, cell, sx, sy, out, base, stride):
        """
        Write the four values of a cell's bicubic patch to out[base + o stride], o = 0..3.

        cf (cells, 4, 16), C order: cf[cell, j, 4 o + p] multiplies s_h^j s_t^p in output o.
        Written as vector code (the four outputs side by side): LLVM's straight-line
        vectoriser left the scalar patch scalar, at 50 to 70 cycles a contact (measured).
        """
        if not _patch_types(cf, out, (cell, base, stride)):
            return None
        return _types.void(cf, cell, _types.float64, _types.float64, out, base,
                           stride), _patch_codegen(False)

    @_intrinsic
    def bicubic_patch(typingctx, cf, cell, sx, sy, dt, dh, out, base, stride):
        """
        Write ``bicubic_values`` and the t- and h-derivatives of outputs 0..2 (per unit t, h).

        Values at out[base + o stride], d/dt at out[base + (4 + o) stride], d/dh at
        out[base + (8 + o) stride]; dt, dh: the cell's size in t and h.
        """
        if not _patch_types(cf, out, (cell, base, stride)):
            return None
        return _types.void(cf, cell, _types.float64, _types.float64, _types.float64,
                           _types.float64, out, base, stride), _patch_codegen(True)

    @_intrinsic
    def fused_multiply_add(typingctx, a, b, c):
        """
        Return a * b + c rounded once (float64).

        LLVM's llvm.fma: the FMA instruction, or libm's fma on a CPU without one; never
        left unfused (as fastmath's contraction may be), so exact where the sum is.
        """
        if not all(t == _types.float64 for t in (a, b, c)):
            return None

        def codegen(context, builder, sig, args):
            from llvmlite import ir
            dbl = ir.DoubleType()
            fma = _cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(dbl, [dbl, dbl, dbl]), "llvm.fma.f64")
            return builder.call(fma, args)

        return _types.float64(a, b, c), codegen
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

    def bicubic_values(cf, cell, sx, sy, out, base, stride):
        """Without numba: the patch's four values (see the compiled one)."""
        patch_reference(cf, cell, sx, sy, 1.0, 1.0, out, base, stride, False)

    def bicubic_patch(cf, cell, sx, sy, dt, dh, out, base, stride):
        """Without numba: values and derivatives (see the compiled one)."""
        patch_reference(cf, cell, sx, sy, dt, dh, out, base, stride, True)

    def fused_multiply_add(a, b, c):
        """Without numba: a * b + c rounded once (exact rationals, rounded by float())."""
        from fractions import Fraction
        if not all(math.isfinite(v) for v in (a, b, c)):
            return a * b + c
        return float(Fraction(a) * Fraction(b) + Fraction(c))


def patch_reference(cf, cell, sx, sy, dt, dh, out, base, stride, slopes):
    """
    ``bicubic_patch`` (``slopes``) or ``bicubic_values`` as plain Python: the reference.

    The numpy model's ``FrictionMapSphere`` patch, written per output; without numba the
    kernels call it.
    """
    c = cf[cell]
    sy2, sy3, sx2, sx3 = sy * sy, sy * sy * sy, sx * sx, sx * sx * sx
    for o in range(4):
        q = [c[0, 4 * o + p] + c[1, 4 * o + p] * sy + c[2, 4 * o + p] * sy2
             + c[3, 4 * o + p] * sy3 for p in range(4)]
        out[base + o * stride] = q[0] + q[1] * sx + q[2] * sx2 + q[3] * sx3
        if slopes and o < 3:
            d = [c[1, 4 * o + p] + 2.0 * c[2, 4 * o + p] * sy + 3.0 * c[3, 4 * o + p] * sy2
                 for p in range(4)]
            out[base + (4 + o) * stride] = (q[1] + 2.0 * q[2] * sx + 3.0 * q[3] * sx2) / dt
            out[base + (8 + o) * stride] = (d[0] + d[1] * sx + d[2] * sx2 + d[3] * sx3) / dh


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
