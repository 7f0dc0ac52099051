# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernel of Murty's least-index principal pivoting method (Cython, ``nogil``).

The condensed principal-pivoting tableau of ``w = M z + q`` (as in
:mod:`lcpcli.solvers.kernels.lemke`, without the artificial column): row ``i`` always holds one
variable of the pair ``(w_i, z_i)`` as ``qb[i] + T[i, :] @ x_N``, and its complement is the
nonbasic variable of column ``i``, so a principal pivot on ``(i, i)`` exchanges ``w_i`` and
``z_i`` (O(n^2), rank-one update).

Variable codes: ``0..n-1`` are ``w_1..w_n``, ``n..2n-1`` are ``z_1..z_n``.

Status codes: 0 solved (all basic values >= 0), 1 pivot limit, 2 non-positive pivot (the matrix is
not a P-matrix: a principal pivot transform of a P-matrix has a positive diagonal).
"""

from libc.math cimport fabs
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy

from lcpcli.solvers.kernels.lemke cimport pivot
from lcpcli.solvers.kernels.simd cimport big_alloc

cimport numpy as cnp

from lcpcli.core.arrays cimport (
    f64,
    f64_ptr,
    i64_ptr,
    inout,
    zeros_f64,
)

cnp.import_array()

cdef enum:
    MURTY_OK = 0
    MURTY_LIMIT = 1
    MURTY_BAD_PIVOT = 2

OK = MURTY_OK
LIMIT = MURTY_LIMIT
BAD_PIVOT = MURTY_BAD_PIVOT


cdef int murty(const double* M, const double* q, Py_ssize_t n, int64_t max_iter,
               double piv_tol, double neg_tol, int64_t* basic, double* z, int* status,
               int64_t* pivots_out, int64_t* bad_out) noexcept nogil:
    """Run the least-index rule from the complementary basis ``basic`` (codes, updated in
    place) on row-major ``M``; ``z`` (n) receives the basic z values.  Returns 0, or -1 (no
    memory)."""
    cdef Py_ssize_t i, j, r
    cdef int64_t pivots = 0, bad = -1
    cdef double qscale = 0.0, p, scale
    cdef double* work = <double*>big_alloc((n * n + 2 * n) * sizeof(double))
    if work == NULL:
        return -1
    cdef double* T = work
    cdef double* qb = T + n * n
    cdef double* rowr = qb + n
    memcpy(T, M, n * n * sizeof(double))
    memcpy(qb, q, n * sizeof(double))
    for i in range(n):
        z[i] = 0.0
    # pivot the starting basis in (principal pivots on the rows whose z is basic)
    for i in range(n):
        if basic[i] >= n:
            basic[i] = i
            if fabs(T[i * n + i]) <= piv_tol:
                status[0] = MURTY_BAD_PIVOT
                pivots_out[0] = 0
                bad_out[0] = i
                free(work)
                return 0
            pivot(T, qb, n, n, i, i, rowr)
            basic[i] = n + i
    for i in range(n):
        if fabs(q[i]) > qscale:
            qscale = fabs(q[i])
    status[0] = MURTY_LIMIT
    while pivots < max_iter:
        r = -1
        for i in range(n):
            if qb[i] < -neg_tol * qscale:
                r = i
                break
        if r < 0:
            status[0] = MURTY_OK
            break
        p = T[r * n + r]
        scale = 0.0
        for j in range(n):
            if fabs(T[r * n + j]) > scale:
                scale = fabs(T[r * n + j])
        if not p > piv_tol * max(scale, 1e-300):
            status[0] = MURTY_BAD_PIVOT
            bad = r
            break
        pivot(T, qb, n, n, r, r, rowr)
        basic[r] = n + r if basic[r] < n else r
        pivots += 1
    for i in range(n):
        if basic[i] >= n:
            z[i] = qb[i] if qb[i] > 0.0 else 0.0
    pivots_out[0] = pivots
    bad_out[0] = bad
    free(work)
    return 0


def murty_kernel(M, q, int64_t max_iter, double piv_tol, double neg_tol, basic):
    """Run the least-index rule from the complementary basis ``basic`` (int64 codes,
    C-contiguous, updated in place).  Returns (status, z, pivots, failing row)."""
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray ba = inout(basic, cnp.NPY_INT64, n, -1)
    cdef cnp.ndarray z = zeros_f64(n)
    cdef int status = MURTY_OK, rc
    cdef int64_t pivots = 0, bad = -1
    if n == 0:
        return status, z, 0, -1
    with nogil:
        rc = murty(f64_ptr(Ma), f64_ptr(qa), n, max_iter, piv_tol, neg_tol, i64_ptr(ba),
                   f64_ptr(z), &status, &pivots, &bad)
    if rc:
        raise MemoryError()
    return status, z, pivots, bad
