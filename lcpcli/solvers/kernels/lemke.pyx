# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernel of the tableau Lemke method (Cython, ``nogil``).

The tableau is the *condensed* principal-pivoting tableau of ``w = q + M z + d z0``:
row ``r`` expresses the basic variable ``basic[r]`` as ``qb[r] + T[r, :] @ x_N`` in terms of the
``n + 1`` nonbasic variables ``nonbasic[:]``.  Each pivot is a rank-one update, O(n^2).

Variable codes: ``0..n-1`` are ``w_1..w_n``, ``n..2n-1`` are ``z_1..z_n``, ``2n`` is ``z0``.

Anti-cycling: the lexicographic minimum-ratio rule, i.e. the rule for the perturbed right-hand
side ``q + (eps, eps^2, ..., eps^n)``; the lexicographic key of row ``i`` is row ``i`` of the basis
inverse, read off the tableau (``d qb / d q_k`` is ``e_r`` when ``w_k`` is basic in row ``r`` and
``-T[:, col(w_k)]`` when ``w_k`` is nonbasic).  When ``z0`` ties for leaving it leaves (that
pivot ends the method with a solution).

C level (``lemke.pxd``): :c:func:`lemke_tableau` and :c:func:`polish` work on raw row-major
buffers without the GIL, so a batched driver can call them per problem; the ``def`` functions
below are the thin Python wrappers.  The ratio test, the lexicographic filter and
:c:func:`basic_solution` are shared with the revised kernel.
"""

from libc.math cimport INFINITY, fabs, isfinite
from libc.stdint cimport int64_t
from libc.stdlib cimport calloc, free, malloc
from libc.string cimport memcpy

from lcpcli.solvers.kernels.dense cimport solve_refined
from lcpcli.solvers.kernels.simd cimport axpy, big_alloc

import numpy as np

cimport numpy as cnp

from lcpcli.core.arrays cimport (
    empty_f64,
    empty_i64,
    f64,
    f64_ptr,
    i64,
    i64_ptr,
    inout,
    zeros_f64,
)

cnp.import_array()

# status codes returned by the kernel
OK = LEMKE_OK
RAY = LEMKE_RAY
MAX_ITER = LEMKE_MAX_ITER
TRIVIAL = LEMKE_TRIVIAL  # q >= 0: z = 0 without pivoting

# Basic values below this fraction of the largest one count as zero in the ratio test.
cdef double _DEGENERATE_RTOL = 1e-13
# Relative tolerance of the lexicographic comparison (floored at an identity entry's scale).
cdef double _LEX_RTOL = 1e-10

cdef enum:
    # the largest n whose polish works on the stack (:c:func:`polish`)
    _POLISH_SMALL_N = 16


cdef int64_t default_pivot_limit(int64_t n) noexcept nogil:
    """Lemke's pivot limit when none is given, ``max(1000, 100 n)``: generous, but finite
    (Murty's family needs 2^n).  The one definition: :func:`default_max_iter` reads it, and
    the kernels that take a limit of 0 for "the default" apply it."""
    return 100 * n if 100 * n > 1000 else 1000


def default_max_iter(int64_t n):
    """Pivot limit when none is given: generous, but finite (Murty's family needs 2^n):
    ``max(1000, 100 n)`` (:c:func:`default_pivot_limit`)."""
    return default_pivot_limit(n)
DEGENERATE_RTOL = _DEGENERATE_RTOL
LEX_RTOL = _LEX_RTOL


cdef void pivot(double* T, double* qb, Py_ssize_t nrows, Py_ssize_t ncols, Py_ssize_t r,
                Py_ssize_t c, double* rowr) noexcept nogil:
    """Pivot the ``nrows x ncols`` tableau on ``(r, c)``; ``rowr`` is work space (ncols)."""
    cdef Py_ssize_t i, j
    cdef double p = T[r * ncols + c]
    cdef double inv = 1.0 / p
    cdef double f, qr
    cdef double* Ti
    for j in range(ncols):
        rowr[j] = -T[r * ncols + j] * inv
    rowr[c] = inv
    qr = -qb[r] * inv
    for i in range(nrows):
        if i == r:
            continue
        Ti = T + i * ncols
        f = Ti[c]
        if f != 0.0:
            qb[i] += f * qr
            axpy(Ti, rowr, f, ncols)
            Ti[c] = f * inv
    for j in range(ncols):
        T[r * ncols + j] = rowr[j]
    qb[r] = qr


cdef Py_ssize_t initial_row(const double* q, const double* d, Py_ssize_t n,
                            double tie_tol) noexcept nogil:
    """Row of the initial pivot (most negative ``q_i / d_i``, ties: the largest index); -1 when
    ``q >= 0`` (no pivot needed)."""
    cdef Py_ssize_t i, r = -1
    cdef double v, best = 0.0
    for i in range(n):
        v = q[i] / d[i]
        if v < best:
            best = v
    if best >= 0.0:
        return -1
    for i in range(n):
        v = q[i] / d[i]
        # a ratio past the double range is -inf, the most negative: the -inf rows tie (the
        # bound best + tie_tol |best| is NaN there: no row, and 'q >= 0' was reported)
        if v == best if best == -INFINITY else v <= best + tie_tol * fabs(best):
            r = i
    return r


cdef Py_ssize_t ratio_candidates(const double* col, const double* qb, const int64_t* basic,
                                 Py_ssize_t n, int64_t nz, double piv_tol, double tie_tol,
                                 int64_t* cand, Py_ssize_t* z0_row,
                                 double* colmax) noexcept nogil:
    """The minimum-ratio test on the entering column ``col`` (basic = qb + col * t).

    Rows with ``col[i] < -piv_tol * max|col|`` block; ``qb`` entries below
    ``DEGENERATE_RTOL max(qb)`` count as zero; ratios within ``tie_tol`` (relative) of the
    minimum tie.  Fills ``cand[:nc]`` with the tied rows and returns ``nc`` (0: no blocking row,
    a ray); ``z0_row`` is the row of the artificial variable (code ``nz``) when it ties, else
    -1; ``colmax`` receives ``max|col|``.
    """
    cdef Py_ssize_t i, nc = 0
    cdef double a, v, t, cmax = 0.0, qmax = 0.0, ptol, ztol, tmin = INFINITY
    cdef bint blocks = False
    for i in range(n):
        a = fabs(col[i])
        if a > cmax:
            cmax = a
        if qb[i] > qmax:
            qmax = qb[i]
    colmax[0] = cmax
    z0_row[0] = -1
    ptol = piv_tol * cmax
    ztol = _DEGENERATE_RTOL * qmax
    for i in range(n):
        a = col[i]
        if a < -ptol:
            v = qb[i] if qb[i] > ztol else 0.0
            t = v / (-a)
            blocks = True
            if t < tmin:
                tmin = t
    if not blocks:  # no row falls: a ray (a ratio past the double range is inf and blocks
        return 0    # last; every ratio inf: those rows tie, as in the trace's replica)
    for i in range(n):
        a = col[i]
        if a < -ptol:
            v = qb[i] if qb[i] > ztol else 0.0
            t = v / (-a)
            if t <= tmin + tie_tol * tmin:
                cand[nc] = i
                nc += 1
                if basic[i] == nz:
                    z0_row[0] = i
    return nc


cdef double lex_unit(const double* col, const int64_t* cand, Py_ssize_t nc) noexcept nogil:
    """Scale of an identity entry of the basis inverse over the tied rows: 1 / largest pivot."""
    cdef Py_ssize_t s
    cdef double a, amax = 0.0
    for s in range(nc):
        a = -col[cand[s]]
        if a > amax:
            amax = a
    return 1.0 / amax


cdef Py_ssize_t keep_lex_min(const double* keys, int64_t* cand, Py_ssize_t nc,
                             double unit) noexcept nogil:
    """Keep the candidates whose key is the minimum, within roundoff; return their count.

    Entries equal in exact arithmetic may differ by roundoff, so the comparison carries a
    tolerance with a floor at ``unit``, the scale of an identity entry.
    """
    cdef Py_ssize_t s, m = 0
    cdef double v, kmin = INFINITY, kmax = 0.0
    for s in range(nc):
        v = keys[s]
        if v < kmin:
            kmin = v
        if fabs(v) > kmax:
            kmax = fabs(v)
    cdef double bound = kmin + _LEX_RTOL * (kmax if kmax > unit else unit)
    for s in range(nc):
        if keys[s] <= bound:
            cand[m] = cand[s]
            m += 1
    return m


cdef void basic_solution(const int64_t* basic, const double* qb, const double* col,
                         int64_t entering, bint ray, Py_ssize_t n, double* z, double* ray_dz,
                         double* z0, double* dz0) noexcept nogil:
    """Read z (and, on a ray, its direction) off the final basis; set z0 and dz0.

    ``col`` is the entering column: on a ray the entering variable grows at rate 1 and the
    basic variables at ``col``.  ``z`` and ``ray_dz`` must be zero on entry.
    """
    cdef Py_ssize_t i
    cdef int64_t b, nz = 2 * n
    z0[0] = 0.0
    dz0[0] = 0.0
    for i in range(n):
        b = basic[i]
        if n <= b < nz:
            z[b - n] = qb[i]
        elif b == nz:
            z0[0] = qb[i]
    if ray:
        if n <= entering < nz:
            ray_dz[entering - n] = 1.0
        for i in range(n):
            b = basic[i]
            if n <= b < nz:
                ray_dz[b - n] = col[i]
            elif b == nz:
                dz0[0] = col[i]


cdef inline void _record(int64_t* record, Py_ssize_t nrec, int64_t k, int64_t entering,
                         int64_t leaving, Py_ssize_t r) noexcept nogil:
    if k < nrec:
        record[3 * k] = entering
        record[3 * k + 1] = leaving
        record[3 * k + 2] = r


cdef int lemke_tableau(const double* M, const double* q, const double* d, Py_ssize_t n,
                       int64_t max_iter, double piv_tol, double tie_tol, int64_t* record,
                       Py_ssize_t nrec, double* z, int64_t* basic, double* ray_dz,
                       LemkeOut* out) noexcept nogil:
    """Run Lemke's method on row-major ``M`` (n x n); fill ``z``, ``basic``, ``ray_dz`` (n) and
    ``out``.  ``record`` (``nrec x 3``, may be NULL when ``nrec == 0``) receives (entering,
    leaving, row) of the first pivots.  Returns 0, or -1 when out of memory."""
    cdef Py_ssize_t m = n + 1
    cdef Py_ssize_t i, j, k, s, r, c, nc, z0_row
    cdef int64_t nz = 2 * n
    cdef int64_t entering, leaving, pivots, loc
    cdef int status
    cdef double colmax, unit, key
    cdef double* work = <double*>big_alloc((n * m + 4 * n + 2 * m + 1) * sizeof(double))
    cdef int64_t* iwork = <int64_t*>malloc((2 * n + 1 + m + n + 1) * sizeof(int64_t))
    if work == NULL or iwork == NULL:
        free(work)
        free(iwork)
        return -1
    cdef double* T = work
    cdef double* qb = T + n * m
    cdef double* keys = qb + n
    cdef double* col = keys + n
    cdef double* rowr = col + n
    cdef int64_t* where = iwork  # r >= 0 if basic in row r, -(c+1) if nonbasic
    cdef int64_t* nonbasic = where + 2 * n + 1
    cdef int64_t* cand = nonbasic + m
    for i in range(n):
        for j in range(n):
            T[i * m + j] = M[i * n + j]
        T[i * m + n] = d[i]
        qb[i] = q[i]
        basic[i] = i
        where[i] = i
        z[i] = 0.0
        ray_dz[i] = 0.0
    for j in range(m):
        nonbasic[j] = n + j
        where[n + j] = -(j + 1)
    out.z0 = 0.0
    out.dz0 = 0.0
    out.refactors = 0
    out.pivots = 0

    # initial pivot: z0 enters, the row with the most negative q_i / d_i leaves
    r = initial_row(q, d, n, tie_tol)
    if r < 0:
        out.status = LEMKE_TRIVIAL
        free(work)
        free(iwork)
        return 0
    entering = nz
    c = n
    leaving = basic[r]
    pivot(T, qb, n, m, r, c, rowr)
    basic[r] = entering
    nonbasic[c] = leaving
    where[entering] = r
    where[leaving] = -(c + 1)
    pivots = 1
    _record(record, nrec, 0, entering, leaving, r)
    status = LEMKE_MAX_ITER
    while pivots < max_iter:
        # complement of the variable that just left enters
        entering = leaving + n if leaving < n else leaving - n
        c = -where[entering] - 1
        for i in range(n):
            col[i] = T[i * m + c]
        nc = ratio_candidates(col, qb, basic, n, nz, piv_tol, tie_tol, cand, &z0_row, &colmax)
        if nc == 0:
            status = LEMKE_RAY
            break
        if z0_row >= 0:
            r = z0_row
        elif nc == 1:
            r = cand[0]
        else:
            # lexicographic minimum over rows of the basis inverse divided by the pivot element
            unit = lex_unit(col, cand, nc)
            for k in range(n):
                loc = where[k]
                for s in range(nc):
                    i = cand[s]
                    if loc >= 0:
                        key = 1.0 if loc == i else 0.0
                    else:
                        key = -T[i * m + (-loc - 1)]
                    keys[s] = key / (-col[i])
                nc = keep_lex_min(keys, cand, nc, unit)
                if nc == 1:
                    break
            r = cand[0]
        leaving = basic[r]
        pivot(T, qb, n, m, r, c, rowr)
        basic[r] = entering
        nonbasic[c] = leaving
        where[entering] = r
        where[leaving] = -(c + 1)
        _record(record, nrec, pivots, entering, leaving, r)
        pivots += 1
        if leaving == nz:
            status = LEMKE_OK
            break
    basic_solution(basic, qb, col, entering, status == LEMKE_RAY, n, z, ray_dz, &out.z0,
                   &out.dz0)
    out.status = status
    out.pivots = pivots
    free(work)
    free(iwork)
    return 0


cdef double min_residual(const double* M, const double* q, const double* z,
                         Py_ssize_t n) noexcept nogil:
    """``||min(z, M z + q)||_inf`` (row-major M)."""
    cdef Py_ssize_t i, j
    cdef double w, v, worst = 0.0
    for i in range(n):
        w = q[i]
        for j in range(n):
            w += M[i * n + j] * z[j]
        v = fabs(z[i] if z[i] < w else w)
        if v > worst:
            worst = v
    return worst


cdef int polish(const double* M, const double* q, Py_ssize_t n, const double* z,
                const int64_t* basic, double* out) noexcept nogil:
    """Re-solve the final basis ``M[b, b] z_b = -q_b`` by LU with one refinement step.

    ``out`` receives the better (by ``||min(z, Mz + q)||_inf``) of the kernel's answer
    ``max(z, 0)`` and the re-solve; a singular block keeps the kernel's answer.  Returns 0, or
    -1 when out of memory (``out`` is then ``max(z, 0)``).
    """
    cdef Py_ssize_t i, j, k, m = 0
    cdef int info
    cdef bint finite = True
    for i in range(n):
        out[i] = z[i] if z[i] > 0.0 else 0.0
        if n <= basic[i] < 2 * n:
            m += 1
    if m == 0:
        return 0
    # up to _POLISH_SMALL_N the work space is on the stack (about 5 KiB; malloc and free
    # would be a noticeable part of a small solve)
    cdef double small_work[2 * _POLISH_SMALL_N * _POLISH_SMALL_N + 4 * _POLISH_SMALL_N]
    cdef int64_t small_idx[2 * _POLISH_SMALL_N]
    cdef int small_piv[_POLISH_SMALL_N]
    cdef bint small = n <= _POLISH_SMALL_N
    cdef double* work
    cdef int64_t* idx
    cdef int* ipiv
    if small:
        work, idx, ipiv = small_work, small_idx, small_piv
    else:
        work = <double*>malloc((2 * m * m + 3 * m + n) * sizeof(double))
        idx = <int64_t*>malloc((m + n) * sizeof(int64_t))
        ipiv = <int*>malloc(m * sizeof(int))
        if work == NULL or idx == NULL or ipiv == NULL:
            free(work)
            free(idx)
            free(ipiv)
            return -1
    cdef double* A = work
    cdef double* lu = A + m * m
    cdef double* x = lu + m * m
    cdef double* r = x + m
    cdef double* zc = r + m
    cdef int64_t* mark = idx + m
    for j in range(n):
        mark[j] = 0
    for i in range(n):
        if n <= basic[i] < 2 * n:
            mark[basic[i] - n] = 1
    k = 0
    for j in range(n):  # sorted basic z indices
        if mark[j]:
            idx[k] = j
            k += 1
    for i in range(m):
        x[i] = -q[idx[i]]
        for j in range(m):
            A[i * m + j] = M[idx[i] * n + idx[j]]
    info = solve_refined(A, m, x, lu, r, ipiv)
    if info == 0:
        for j in range(n):
            zc[j] = 0.0
        for i in range(m):
            if not isfinite(x[i]):
                finite = False
            zc[idx[i]] = x[i] if x[i] > 0.0 else 0.0
        if finite and min_residual(M, q, zc, n) <= min_residual(M, q, out, n):
            for j in range(n):
                out[j] = zc[j]
    if not small:
        free(work)
        free(idx)
        free(ipiv)
    return 0


# ---------------------------------------------------------------------------- Python wrappers
def lemke_kernel(M, q, d, int64_t max_iter, double piv_tol, double tie_tol, record):
    """Run Lemke's method; return (status, z, pivots, basic, ray_dz, ray_dz0, z0).

    ``M`` (n x n), ``q``, ``d`` (n): float64 (converted when needed).  ``record`` (int64,
    C-contiguous, shape (k, 3)) receives (entering, leaving, row) of the first k pivots.
    """
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray da = f64(d, n, -1)
    cdef cnp.ndarray ra = inout(record, cnp.NPY_INT64, -1, 3)
    cdef Py_ssize_t nrec = cnp.PyArray_DIM(ra, 0)
    cdef cnp.ndarray z = zeros_f64(n)
    cdef cnp.ndarray ray = zeros_f64(n)
    cdef cnp.ndarray basic = empty_i64(n)
    cdef LemkeOut out
    cdef int rc
    if n == 0:
        return TRIVIAL, z, 0, basic, ray, 0.0, 0.0
    with nogil:
        rc = lemke_tableau(f64_ptr(Ma), f64_ptr(qa), f64_ptr(da), n, max_iter, piv_tol,
                           tie_tol, i64_ptr(ra) if nrec else NULL, nrec, f64_ptr(z),
                           i64_ptr(basic), f64_ptr(ray), &out)
    if rc:
        raise MemoryError()
    return out.status, z, out.pivots, basic, ray, out.dz0, out.z0


def polish_kernel(M, q, z, basic):
    """Re-solve the final basis by LU (one refinement); the better of that and ``max(z, 0)``.

    See :c:func:`polish`; a singular basic block keeps ``max(z, 0)``.
    """
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray za = f64(z, n, -1)
    cdef cnp.ndarray ba = i64(basic, n, -1)
    cdef cnp.ndarray res = empty_f64(n)
    cdef int rc
    if n == 0:
        return res
    with nogil:
        rc = polish(f64_ptr(Ma), f64_ptr(qa), n, f64_ptr(za), i64_ptr(ba), f64_ptr(res))
    if rc:
        raise MemoryError()
    return res


cdef double* _ones(Py_ssize_t n) noexcept nogil:
    cdef double* d = <double*>malloc(n * sizeof(double))
    cdef Py_ssize_t i
    if d != NULL:
        for i in range(n):
            d[i] = 1.0
    return d


cdef list basis_list(const int64_t* basic, Py_ssize_t n):
    """The sorted 0-based indices of the z's in a final basis (codes ``n..2n-1``), as a list."""
    cdef list out = []
    cdef Py_ssize_t i, j
    cdef char* mark = <char*>calloc(n + 1, 1)
    if mark == NULL:
        raise MemoryError()
    for i in range(n):
        if n <= basic[i] < 2 * n:
            mark[basic[i] - n] = 1
    for j in range(n):
        if mark[j]:
            out.append(j)
    free(mark)
    return out


def lemke_solve(M, q, d, int64_t max_iter, double piv_tol, double tie_tol):
    """Kernel and final polish in one call (the small-solve path: one C call, no record).

    ``d`` None means the covering vector of all ones.  Returns
    ``(status, z, pivots, basis, ray_dz, z0)`` with ``basis`` the sorted 0-based indices of
    the basic z's (a list); on ``OK`` ``z`` is already polished
    (:func:`polish_kernel`), otherwise it is the kernel's raw ``z`` (not clipped).
    """
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray da
    cdef const double* dp = NULL
    if d is not None:
        da = f64(d, n, -1)
        dp = f64_ptr(da)
    cdef cnp.ndarray z = empty_f64(n)
    cdef cnp.ndarray ray = empty_f64(n)
    cdef cnp.ndarray basic = empty_i64(n)
    if n == 0:
        return TRIVIAL, z, 0, [], ray, 0.0
    cdef const double* Mp = f64_ptr(Ma)
    cdef const double* qp = f64_ptr(qa)
    cdef double* zp = f64_ptr(z)
    cdef double* rp = f64_ptr(ray)
    cdef int64_t* bp = <int64_t*>cnp.PyArray_DATA(basic)
    cdef LemkeOut out
    cdef int rc = 0
    cdef double* ones = NULL
    cdef double* raw = NULL
    with nogil:
        if dp == NULL:
            ones = _ones(n)
            dp = ones
        raw = <double*>malloc(n * sizeof(double))
        if dp == NULL or raw == NULL:
            rc = -1
        else:
            rc = lemke_tableau(Mp, qp, dp, n, max_iter, piv_tol, tie_tol, NULL, 0,
                               raw, bp, rp, &out)
        if rc == 0:
            if out.status == LEMKE_OK:
                rc = polish(Mp, qp, n, raw, bp, zp)
            else:
                memcpy(zp, raw, n * sizeof(double))
        free(ones)
        free(raw)
    if rc:
        raise MemoryError()
    return out.status, z, out.pivots, basis_list(bp, n), ray, out.z0
