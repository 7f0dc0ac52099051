# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Small dense LU, solves and inverses for the kernels (row-major, ``nogil``).

Sizes below :data:`LAPACK_MIN` use the loops here (partial pivoting, row-oriented
elimination: no library call, no import).  From ``LAPACK_MIN`` up, and once
:func:`bind_lapack` has run, the same functions call LAPACK's ``dgetrf``/``dgetrs``/``dgetri``
through function pointers: first those of the OpenBLAS that numpy's own build loaded
(``numpy.libs``: ``scipy_dgetrf_64_`` and its siblings, 64-bit integers, called through the
small wrappers below), found with ``dlopen``/``dlsym`` without importing anything; otherwise
those that ``scipy.linalg.cython_lapack`` exports as capsules in ``__pyx_capi__`` (importing
``scipy.linalg``, about 0.3 s).  A row-major buffer is LAPACK's column-major transpose, so the LAPACK path
transposes in place first (O(m^2)) and factors ``A`` itself, as ``numpy.linalg.solve`` does
(same pivoting, same answers).

The crossover (:data:`LAPACK_MIN` = 64) is above the per-call one (32-40 on the development
machine, single-threaded OpenBLAS: ``benchmarks/bench_kernels.py --crossover``); with numpy's
OpenBLAS found, no size imports scipy (the dense Lemke path never does).

All functions return 0 on success and ``k + 1`` when the ``k``-th pivot is exactly zero
(LAPACK's ``info`` convention: singular to working precision means an exact zero pivot).
"""

from cpython.pycapsule cimport PyCapsule_GetName, PyCapsule_GetPointer
from libc.math cimport fabs
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy
from posix.dlfcn cimport RTLD_NOW, dlopen, dlsym

cimport numpy as cnp

from lcpcli.core.arrays cimport f64, f64_ptr

cnp.import_array()

ctypedef void (*dgetrf_t)(int* m, int* n, double* a, int* lda, int* ipiv,
                          int* info) noexcept nogil
ctypedef void (*dgetrs_t)(char* trans, int* n, int* nrhs, double* a, int* lda, int* ipiv,
                          double* b, int* ldb, int* info) noexcept nogil
ctypedef void (*dgetri_t)(int* n, double* a, int* lda, int* ipiv, double* work, int* lwork,
                          int* info) noexcept nogil

cdef dgetrf_t _dgetrf = NULL
cdef dgetrs_t _dgetrs = NULL
cdef dgetri_t _dgetri = NULL

# LAPACK with 64-bit integers (ILP64: numpy's bundled OpenBLAS), behind the wrappers below
ctypedef void (*dgetrf64_t)(int64_t* m, int64_t* n, double* a, int64_t* lda, int64_t* ipiv,
                            int64_t* info) noexcept nogil
ctypedef void (*dgetrs64_t)(char* trans, int64_t* n, int64_t* nrhs, double* a, int64_t* lda,
                            int64_t* ipiv, double* b, int64_t* ldb, int64_t* info) noexcept nogil
ctypedef void (*dgetri64_t)(int64_t* n, double* a, int64_t* lda, int64_t* ipiv, double* work,
                            int64_t* lwork, int64_t* info) noexcept nogil
cdef dgetrf64_t _dgetrf64 = NULL
cdef dgetrs64_t _dgetrs64 = NULL
cdef dgetri64_t _dgetri64 = NULL
#: Where the LAPACK in use comes from ("" until bound).
cdef str _source = ""
#: numpy's OpenBLAS symbols, 64-bit integer interface (numpy >= 2 wheels), by prefix.
_ILP64_NAMES = (b"scipy_%s_64_", b"%s_64_")


cdef void _dgetrf_ilp64(int* m, int* n, double* a, int* lda, int* ipiv,
                        int* info) noexcept nogil:
    cdef int64_t mm = m[0], nn = n[0], ld = lda[0], inf = 0
    cdef Py_ssize_t k, r = mm if mm < nn else nn
    cdef int64_t* piv = <int64_t*>malloc((r + 1) * sizeof(int64_t))
    if piv == NULL:
        info[0] = -1000
        return
    _dgetrf64(&mm, &nn, a, &ld, piv, &inf)
    for k in range(r):
        ipiv[k] = <int>piv[k]
    free(piv)
    info[0] = <int>inf


cdef int64_t* _pivots64(const int* ipiv, int64_t n) noexcept nogil:
    """A malloc'ed 64-bit copy of LAPACK's ``n`` pivot indices (NULL: out of memory)."""
    cdef int64_t* piv = <int64_t*>malloc((n + 1) * sizeof(int64_t))
    cdef Py_ssize_t k
    if piv != NULL:
        for k in range(n):
            piv[k] = ipiv[k]
    return piv


cdef void _dgetrs_ilp64(char* trans, int* n, int* nrhs, double* a, int* lda, int* ipiv,
                        double* b, int* ldb, int* info) noexcept nogil:
    cdef int64_t nn = n[0], nr = nrhs[0], la = lda[0], lb = ldb[0], inf = 0
    cdef int64_t* piv = _pivots64(ipiv, nn)
    if piv == NULL:
        info[0] = -1000
        return
    _dgetrs64(trans, &nn, &nr, a, &la, piv, b, &lb, &inf)
    free(piv)
    info[0] = <int>inf


cdef void _dgetri_ilp64(int* n, double* a, int* lda, int* ipiv, double* work, int* lwork,
                        int* info) noexcept nogil:
    cdef int64_t nn = n[0], la = lda[0], lw = lwork[0], inf = 0
    cdef int64_t* piv = _pivots64(ipiv, nn)
    if piv == NULL:
        info[0] = -1000
        return
    _dgetri64(&nn, a, &la, piv, work, &lw, &inf)
    free(piv)
    info[0] = <int>inf

#: From this size up the LU, solves and inverses call LAPACK (once :func:`bind_lapack` ran).
LAPACK_MIN = 64
cdef Py_ssize_t _lapack_min = LAPACK_MIN


cdef Py_ssize_t lapack_min() noexcept nogil:
    return _lapack_min


def set_lapack_min(Py_ssize_t m):
    """Change the LAPACK crossover (for benchmarks; ``m <= 0`` restores the default)."""
    global _lapack_min
    _lapack_min = m if m > 0 else LAPACK_MIN
    return None


def lapack_bound():
    """Whether the LAPACK pointers are bound (after :func:`bind_lapack`)."""
    return _dgetrf != NULL


cdef void* _pointer(object capi, str name) except NULL:
    cap = capi[name]
    return PyCapsule_GetPointer(cap, PyCapsule_GetName(cap))


def _numpy_blas_files():
    """The OpenBLAS libraries numpy's wheel ships (``numpy.libs`` beside the package; numpy
    loaded them already, so ``dlopen`` only finds them)."""
    import glob
    import os

    import numpy
    root = os.path.dirname(os.path.dirname(os.path.abspath(numpy.__file__)))
    return sorted(glob.glob(os.path.join(root, "numpy.libs", "*openblas*")) +
                  glob.glob(os.path.join(os.path.dirname(numpy.__file__), ".dylibs",
                                         "*openblas*")))


def bind_numpy_lapack():
    """Bind dgetrf/dgetrs/dgetri from the OpenBLAS numpy loaded (no import); True if bound
    (now or before)."""
    global _dgetrf, _dgetrs, _dgetri, _dgetrf64, _dgetrs64, _dgetri64, _source
    if _dgetrf != NULL:
        return True
    cdef void* handle
    cdef void* f
    cdef void* s
    cdef void* i
    for path in _numpy_blas_files():
        handle = dlopen(path.encode(), RTLD_NOW)
        if handle == NULL:
            continue
        for pattern in _ILP64_NAMES:
            f = dlsym(handle, pattern % b"dgetrf")
            s = dlsym(handle, pattern % b"dgetrs")
            i = dlsym(handle, pattern % b"dgetri")
            if f != NULL and s != NULL and i != NULL:
                _dgetrf64, _dgetrs64, _dgetri64 = <dgetrf64_t>f, <dgetrs64_t>s, <dgetri64_t>i
                _dgetrs, _dgetri = _dgetrs_ilp64, _dgetri_ilp64
                _dgetrf = _dgetrf_ilp64
                _source = path
                return True
    return False


def lapack_source():
    """Where the bound LAPACK comes from: numpy's OpenBLAS file, "scipy", or "" (unbound)."""
    return _source


def bind_lapack():
    """Bind dgetrf/dgetrs/dgetri (idempotent): numpy's OpenBLAS when found
    (:func:`bind_numpy_lapack`), else scipy's capsules, which imports ``scipy.linalg``
    (about 0.3 s), so callers do it only for a size that needs it (see :func:`need`).
    Without either the loops here are used at every size.
    """
    global _dgetrf, _dgetrs, _dgetri, _source
    if _dgetrf != NULL or bind_numpy_lapack():
        return
    # heavy import (scipy.linalg, ~0.3 s): only when numpy's OpenBLAS was not found
    from scipy.linalg import cython_lapack
    capi = cython_lapack.__pyx_capi__
    _dgetrs = <dgetrs_t>_pointer(capi, "dgetrs")
    _dgetri = <dgetri_t>_pointer(capi, "dgetri")
    _dgetrf = <dgetrf_t>_pointer(capi, "dgetrf")
    _source = "scipy"


def need(Py_ssize_t m):
    """Bind LAPACK now if a factorisation of size ``m`` will use it (optional: the functions
    bind it themselves on first need, taking the GIL once; a batched driver may call this
    before its parallel loop)."""
    ensure_lapack(m)


cdef int ensure_lapack(Py_ssize_t m) except -1:
    """C-level :func:`need` (with the GIL): bind LAPACK when ``m`` reaches the crossover."""
    if m >= _lapack_min and _dgetrf == NULL:
        bind_lapack()
    return 0


cdef bint _use_lapack(Py_ssize_t m) noexcept nogil:
    """Whether size ``m`` goes to LAPACK; binds it on first need (takes the GIL for that once;
    if scipy is missing the loops here are used at every size)."""
    if m < _lapack_min:
        return False
    if _dgetrf == NULL:
        with gil:
            try:
                bind_lapack()
            except Exception:  # no scipy: keep the own loops
                set_lapack_min(1 << 62)
    return _dgetrf != NULL


cdef void _transpose(double* a, Py_ssize_t m) noexcept nogil:
    cdef Py_ssize_t i, j
    cdef double v
    for i in range(m):
        for j in range(i + 1, m):
            v = a[i * m + j]
            a[i * m + j] = a[j * m + i]
            a[j * m + i] = v


cdef int lu_factor(double* a, Py_ssize_t m, int* ipiv) noexcept nogil:
    """In-place LU with partial pivoting of the row-major ``m x m`` ``a``.

    Own loops: ``P A = L U`` with ``ipiv[k]`` the row swapped with row ``k``.  LAPACK (large
    m): ``dgetrf``'s column-major factors of ``A`` (use only through :func:`lu_solve`).
    """
    cdef Py_ssize_t i, j, k, p
    cdef double best, v, f, piv
    cdef double* rk
    cdef double* ri
    cdef int mm, info
    if _use_lapack(m):
        _transpose(a, m)
        mm = <int>m
        info = 0
        _dgetrf(&mm, &mm, a, &mm, ipiv, &info)
        return info if info > 0 else 0
    for k in range(m):
        p = k
        best = fabs(a[k * m + k])
        for i in range(k + 1, m):
            v = fabs(a[i * m + k])
            if v > best:
                best = v
                p = i
        ipiv[k] = <int>p
        if best == 0.0:
            return <int>(k + 1)
        if p != k:
            for j in range(m):
                v = a[k * m + j]
                a[k * m + j] = a[p * m + j]
                a[p * m + j] = v
        rk = a + k * m
        piv = rk[k]
        for i in range(k + 1, m):
            ri = a + i * m
            f = ri[k] / piv
            ri[k] = f
            if f != 0.0:
                for j in range(k + 1, m):
                    ri[j] -= f * rk[j]
    return 0


cdef void lu_solve(const double* lu, Py_ssize_t m, const int* ipiv, double* b) noexcept nogil:
    """Solve ``A x = b`` in place from :func:`lu_factor`'s output."""
    cdef Py_ssize_t i, j, k
    cdef double s, v
    cdef int mm, one, info
    cdef char trans
    if _use_lapack(m):
        mm = <int>m
        one = 1
        info = 0
        trans = b'N'
        _dgetrs(&trans, &mm, &one, <double*>lu, &mm, <int*>ipiv, b, &mm, &info)
        return
    for k in range(m):
        i = ipiv[k]
        if i != k:
            v = b[k]
            b[k] = b[i]
            b[i] = v
    for i in range(1, m):
        s = b[i]
        for j in range(i):
            s -= lu[i * m + j] * b[j]
        b[i] = s
    for i in range(m - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, m):
            s -= lu[i * m + j] * b[j]
        b[i] = s / lu[i * m + i]


cdef int invert(const double* a, Py_ssize_t m, double* out, double* work,
                int* ipiv) noexcept nogil:
    """``out = inv(a)`` (row-major ``m x m``); ``work`` holds ``m * m + m`` doubles, ``ipiv`` m.

    Returns 0, or ``k + 1`` for an exactly zero pivot (``out`` is then undefined).
    """
    cdef Py_ssize_t i, j, k, p
    cdef int info, mm, lwork
    cdef double best, v, piv, f
    cdef double* rk
    cdef double* ri
    cdef double* ok
    cdef double* oi
    if _use_lapack(m):
        memcpy(out, a, m * m * sizeof(double))
        _transpose(out, m)
        mm = <int>m
        info = 0
        _dgetrf(&mm, &mm, out, &mm, ipiv, &info)
        if info > 0:
            return info
        lwork = <int>(m * m + m)
        _dgetri(&mm, out, &mm, ipiv, work, &lwork, &info)
        _transpose(out, m)
        return info if info > 0 else 0
    # Gauss-Jordan with partial pivoting on [A | I] (row-major rows of length 2m would need
    # 2 m^2 work; instead A is reduced in ``work`` while the same row operations build ``out``)
    memcpy(work, a, m * m * sizeof(double))
    for i in range(m):
        for j in range(m):
            out[i * m + j] = 0.0
        out[i * m + i] = 1.0
    for k in range(m):
        p = k
        best = fabs(work[k * m + k])
        for i in range(k + 1, m):
            v = fabs(work[i * m + k])
            if v > best:
                best = v
                p = i
        if best == 0.0:
            return <int>(k + 1)
        if p != k:
            for j in range(m):
                v = work[k * m + j]
                work[k * m + j] = work[p * m + j]
                work[p * m + j] = v
                v = out[k * m + j]
                out[k * m + j] = out[p * m + j]
                out[p * m + j] = v
        rk = work + k * m
        ok = out + k * m
        piv = 1.0 / rk[k]
        for j in range(m):
            rk[j] *= piv
            ok[j] *= piv
        for i in range(m):
            if i == k:
                continue
            ri = work + i * m
            oi = out + i * m
            f = ri[k]
            if f != 0.0:
                for j in range(k, m):
                    ri[j] -= f * rk[j]
                for j in range(m):
                    oi[j] -= f * ok[j]
    return 0


cdef int solve_refined(const double* a, Py_ssize_t m, double* x, double* lu, double* r,
                       int* ipiv) noexcept nogil:
    """Solve ``a x = b`` (``x`` holds ``b`` on entry) with one step of iterative refinement.

    ``lu`` (``m * m``) and ``r`` (``m``) are work space.  Returns 0 or ``k + 1`` (singular).
    """
    cdef Py_ssize_t i, j
    cdef double s
    cdef int info
    memcpy(lu, a, m * m * sizeof(double))
    memcpy(r, x, m * sizeof(double))  # r = b for now
    info = lu_factor(lu, m, ipiv)
    if info:
        return info
    lu_solve(lu, m, ipiv, x)
    for i in range(m):
        s = 0.0
        for j in range(m):
            s += a[i * m + j] * x[j]
        r[i] = r[i] - s
    lu_solve(lu, m, ipiv, r)
    for i in range(m):
        x[i] += r[i]
    return 0


def solve(a, b):
    """``x`` with ``a x = b`` (one refinement step); ``LinAlgError`` when singular.

    A thin wrapper for tests: the kernels call the C functions directly.
    """
    import numpy as np
    cdef Py_ssize_t m = len(b)
    cdef cnp.ndarray A = f64(a, m, m)
    cdef cnp.ndarray x = f64(b, m, -1).copy()
    cdef double* lu = <double*>malloc((m * m + m + 1) * sizeof(double))
    cdef int* ipiv = <int*>malloc((m + 1) * sizeof(int))
    cdef int info
    if lu == NULL or ipiv == NULL:
        free(lu)
        free(ipiv)
        raise MemoryError()
    with nogil:
        info = solve_refined(f64_ptr(A), m, f64_ptr(x), lu, lu + m * m, ipiv)
    free(lu)
    free(ipiv)
    if info:
        raise np.linalg.LinAlgError("singular matrix")
    return x


def inv(a):
    """``inv(a)``; ``LinAlgError`` when singular (a thin wrapper for tests)."""
    import numpy as np
    cdef Py_ssize_t m = len(a)
    cdef cnp.ndarray A = f64(a, m, m)
    cdef cnp.npy_intp dims[2]
    dims[0] = m
    dims[1] = m
    cdef cnp.ndarray out = cnp.PyArray_EMPTY(2, dims, cnp.NPY_FLOAT64, 0)
    if m == 0:
        return out
    cdef double* work = <double*>malloc((m * m + m) * sizeof(double))
    cdef int* ipiv = <int*>malloc(m * sizeof(int))
    cdef int info
    if work == NULL or ipiv == NULL:
        free(work)
        free(ipiv)
        raise MemoryError()
    with nogil:
        info = invert(f64_ptr(A), m, f64_ptr(out), work, ipiv)
    free(work)
    free(ipiv)
    if info:
        raise np.linalg.LinAlgError("singular matrix")
    return out
