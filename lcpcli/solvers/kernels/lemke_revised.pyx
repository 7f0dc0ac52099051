# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernel of the revised Lemke method (Cython, ``nogil``).

The engine is Dai & Drumwright's principal pivoting transform: with ``Maug = [M, d]`` (``n x (n+1)``),
``alpha`` the nonbasic w's, ``beta`` the basic z's (``z0`` is index ``n``) and
``A = Maug[alpha, beta]`` (``m x m``), the kernel keeps ``B = A^{-1}`` explicitly and
*updates* it at every pivot in O(m^2), one formula per case:

* z_j enters, w_i leaves: ``A`` gains row ``i`` and column ``j`` (bordering, Schur complement);
* z_j enters, z_l leaves: column ``l`` of ``A`` is replaced by column ``j`` (Sherman-Morrison);
* w_k enters, w_i leaves: row ``k`` of ``A`` is replaced by row ``i`` (Sherman-Morrison);
* w_k enters, z_l leaves: row ``k`` and column ``l`` are removed (inverse of a Schur complement).

The entering column is computed by Dai & Drumwright's eqs (5)-(6) (w enters) or (7)-(8) (z enters) in
O(n m); ``q'`` is updated along the ray of the pivot and recomputed by eqs (2)-(3) after every
refactorisation.  ``B`` is recomputed from scratch (``inv(A)``) every ``refactor_every`` pivots
and whenever a pivot is small relative to its column (an unstable update).

Instability is detected a posteriori: every ``CHECK_EVERY`` pivots the entering column's
beta part is substituted back into ``M^{alpha beta} x = rhs``; a relative residual above
``RESID_TOL`` triggers a refactorisation before the column is used.

The pivot rule is the tableau kernel's (:mod:`lcpcli.solvers.kernels.lemke`): same initial
pivot, same lexicographic minimum-ratio test with the same tolerances, ``z0`` preferred on ties.
Variable codes: ``0..n-1`` = ``w_1..w_n``, ``n..2n-1`` = ``z_1..z_n``, ``2n`` = ``z0``.

C level (``lemke_revised.pxd``): :c:func:`lemke_revised` on raw row-major buffers, no GIL.
"""

from libc.math cimport fabs, isfinite
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy

from lcpcli.analysis._scaling cimport _balanced
from lcpcli.core._certificate cimport CertOut, certify_dense
from lcpcli.solvers.kernels.dense cimport invert
from lcpcli.solvers.kernels.lemke cimport (
    LEMKE_MAX_ITER,
    LEMKE_OK,
    LEMKE_RAY,
    LEMKE_SINGULAR,
    LEMKE_TRIVIAL,
    LemkeOut,
    _ones,
    basic_solution,
    basis_list,
    default_pivot_limit,
    initial_row,
    keep_lex_min,
    lex_unit,
    polish,
    ratio_candidates,
)

from lcpcli.solvers.kernels.simd cimport axpy, big_alloc, dot4

import numpy as np

from lcpcli.core.certificate import certificate_of

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

OK = LEMKE_OK
RAY = LEMKE_RAY
MAX_ITER = LEMKE_MAX_ITER
TRIVIAL = LEMKE_TRIVIAL
SINGULAR = LEMKE_SINGULAR

# A pivot smaller than this fraction of its column's largest entry triggers a refactorisation.
cdef double _SMALL_PIVOT = 1e-7
# At a refactorisation, q' entries that moved less than this (relative) keep their value.
cdef double _DRIFT_TOL = 1e-9
# Every CHECK_EVERY pivots the entering column is checked against M^{alpha beta} ...
cdef int64_t _CHECK_EVERY = 8
# ... and a relative residual above RESID_TOL triggers a refactorisation.
cdef double _RESID_TOL = 1e-9
SMALL_PIVOT = _SMALL_PIVOT
DRIFT_TOL = _DRIFT_TOL
CHECK_EVERY = _CHECK_EVERY
RESID_TOL = _RESID_TOL

cdef enum:
    # Problems up to this size are solved without releasing the GIL (the whole call takes a
    # few microseconds; releasing and taking back the GIL is a noticeable part of it) ...
    GIL_FREE_N = 32
    # ... and up to this size with their work space on the stack (about 15 KiB).
    SMALL_N = 16


cdef int64_t default_refactor(int64_t n) noexcept nogil:
    """Pivots between two refactorisations when not given: ``max(50, n)`` (the one definition:
    :func:`default_refactor_every` reads it; :func:`lemke_solve_certified` applies it to 0)."""
    return n if n > 50 else 50


def default_refactor_every(int64_t n):
    """Pivots between two refactorisations when not given: ``max(50, n)``."""
    return default_refactor(n)


cdef struct State:
    # sizes
    Py_ssize_t n
    Py_ssize_t m
    # data: MT = [M, d]^T ((n + 1) x n), q (n)
    const double* MT
    const double* q
    # index sets: alpha (nonbasic w's), beta (basic z's, n = z0), their inverse positions
    int64_t* alpha
    int64_t* beta
    int64_t* apos
    int64_t* bpos
    int64_t* basic
    int64_t* where
    # B = inv(Maug[alpha, beta]) (stride n), Ct[s, :] = Maug[:, beta[s]] (stride n)
    double* B
    double* Ct
    # work vectors (n)
    double* qb
    double* xb
    double* tmp
    # refactorisation work space (allocated on first use)
    double* fA
    double* fwork
    int* fpiv


cdef bint _refactor(State* S) noexcept nogil:
    """B[:m, :m] = inv(Maug[alpha, beta]); False when singular, non-finite or out of memory."""
    cdef Py_ssize_t m = S.m, n = S.n, p, s
    cdef double v
    if m == 0:
        return True
    if S.fA == NULL:
        S.fA = <double*>malloc((2 * n * n + n) * sizeof(double))
        S.fwork = <double*>malloc((n * n + n) * sizeof(double))
        S.fpiv = <int*>malloc(n * sizeof(int))
        if S.fA == NULL or S.fwork == NULL or S.fpiv == NULL:
            return False
    cdef double* A = S.fA
    cdef double* Ainv = S.fA + n * n
    for p in range(m):
        for s in range(m):
            A[p * m + s] = S.MT[S.beta[s] * n + S.alpha[p]]
    if invert(A, m, Ainv, S.fwork, S.fpiv):
        return False
    for s in range(m):
        for p in range(m):
            v = Ainv[s * m + p]
            if not isfinite(v):
                return False
            S.B[s * n + p] = v
    return True


cdef void _combine_rows(const double* Ct, const double* xb, Py_ssize_t m, Py_ssize_t n,
                        double* tmp) noexcept nogil:
    """``tmp[:n] = sum_s xb[s] * Ct[s, :n]`` (M[:, beta] times the beta part)."""
    cdef Py_ssize_t i, s
    cdef double x
    for i in range(n):
        tmp[i] = 0.0
    for s in range(m):
        x = xb[s]
        if x != 0.0:
            axpy(tmp, Ct + s * n, x, n)


cdef void _q_prime(State* S) noexcept nogil:
    """q' by Dai & Drumwright's eqs (2)-(3), in row order (into S.qb)."""
    cdef Py_ssize_t m = S.m, n = S.n, s, p, r
    cdef int64_t b
    cdef double acc
    for s in range(m):
        acc = 0.0
        for p in range(m):
            acc += S.B[s * n + p] * S.q[S.alpha[p]]
        S.xb[s] = -acc
    _combine_rows(S.Ct, S.xb, m, n, S.tmp)
    for r in range(n):
        b = S.basic[r]
        if b < n:
            S.qb[r] = S.q[b] + S.tmp[b]
    for s in range(m):
        S.qb[S.where[n + S.beta[s]]] = S.xb[s]


cdef void _column(State* S, int64_t e, double* col) noexcept nogil:
    """Column of M' for entering code ``e``, row order (eqs 5-6 or 7-8); S.xb = its beta part."""
    cdef Py_ssize_t m = S.m, n = S.n, s, p, r
    cdef int64_t b, j
    if e < n:
        p = S.apos[e]
        for s in range(m):
            S.xb[s] = S.B[s * n + p]
    else:
        j = e - n
        for p in range(m):
            S.tmp[p] = S.MT[j * n + S.alpha[p]]
        for s in range(m):
            S.xb[s] = -dot4(S.B + s * n, S.tmp, m)  # four partial sums (SIMD lanes)
    _combine_rows(S.Ct, S.xb, m, n, S.tmp)
    for r in range(n):
        b = S.basic[r]
        if b < n:
            col[r] = S.tmp[b] + (S.MT[(e - n) * n + b] if e >= n else 0.0)
    for s in range(m):
        col[S.where[n + S.beta[s]]] = S.xb[s]


cdef void _fresh_q_prime(State* S, double* old) noexcept nogil:
    """q' by eqs (2)-(3) after a refactorisation; entries that moved only at roundoff level
    keep their updated value, so degenerate zeros stay exact zeros (the lexicographic rule then
    sees the same degeneracy as before, as the tableau method does)."""
    cdef Py_ssize_t i, n = S.n
    cdef double scale = 0.0
    for i in range(n):
        old[i] = S.qb[i]
    _q_prime(S)
    for i in range(n):
        scale = max(scale, fabs(old[i]), fabs(S.q[i]))
    for i in range(n):
        if fabs(S.qb[i] - old[i]) <= _DRIFT_TOL * scale:
            S.qb[i] = old[i]


cdef double column_residual(const double* MT, const double* Ct, const int64_t* alpha,
                            const int64_t* apos, Py_ssize_t m, int64_t e, Py_ssize_t n,
                            const double* xb, double* acc, double* size) noexcept nogil:
    """Relative residual of the beta part of the entering column: ``A xb = rhs`` with
    ``A = Maug[alpha, beta]`` and rhs ``e_gamma`` (w enters) or ``-g^alpha`` (z enters).
    ``acc`` and ``size`` are work vectors of length >= m; ``Ct`` has row stride n."""
    cdef Py_ssize_t p, s
    cdef double rhs, x, t, rel, worst = 0.0
    for p in range(m):
        if e < n:
            rhs = 1.0 if apos[e] == p else 0.0
        else:
            rhs = -MT[(e - n) * n + alpha[p]]
        acc[p] = -rhs
        size[p] = fabs(rhs)
    for s in range(m):
        x = xb[s]
        for p in range(m):
            t = Ct[s * n + alpha[p]] * x
            acc[p] += t
            size[p] += fabs(t)
    for p in range(m):
        if size[p] > 0.0:
            rel = fabs(acc[p]) / size[p]
            if rel > worst:
                worst = rel
    return worst


cdef void _row_times_B(const double* Ct, const double* B, Py_ssize_t m, Py_ssize_t n,
                       int64_t i, double* out) noexcept nogil:
    """out[:m] = Maug[i, beta] @ B (row access of B only)."""
    cdef Py_ssize_t p, s
    cdef double c
    for p in range(m):
        out[p] = 0.0
    for s in range(m):
        c = Ct[s * n + i]
        if c != 0.0:
            axpy(out, B + s * n, c, m)


cdef double _wcol_entry(State* S, int64_t k, Py_ssize_t r) noexcept nogil:
    """Entry at row r of the column of the nonbasic w_k (for the lexicographic keys)."""
    cdef Py_ssize_t p = S.apos[k], s, m = S.m, n = S.n
    cdef int64_t b = S.basic[r]
    cdef double acc = 0.0
    if b >= n:  # a z row (z0 included): B[s, p] with s the beta position of that z
        return S.B[S.bpos[b - n] * n + p]
    for s in range(m):
        acc += S.Ct[s * n + b] * S.B[s * n + p]
    return acc


cdef int lemke_revised(const double* M, const double* q, const double* d, Py_ssize_t n,
                       int64_t max_iter, double piv_tol, double tie_tol, int64_t* record,
                       Py_ssize_t nrec, int64_t refactor_every, double* z, int64_t* basic,
                       double* ray_dz, LemkeOut* out) noexcept nogil:
    """Revised Lemke on row-major ``M``; fills ``z``, ``basic``, ``ray_dz`` and ``out`` as
    :c:func:`lcpcli.solvers.kernels.lemke.lemke_tableau`.  Returns 0, or -1 (no memory)."""
    cdef Py_ssize_t i, j, i0, j0, s, p, k, r, m, nc, z0_row, s0, p0, last, blk = 32
    cdef int64_t nz = 2 * n, entering, leaving, pivots, since, refactors, loc, jj
    cdef int status
    cdef double colmax, unit, key, piv, qr, inv, bu, f, y0, x0, bsp
    cdef State S
    # up to SMALL_N the work space lives on the stack (the refactorisation's too): a solve of
    # a microsecond or two would otherwise spend a tenth of it in malloc and free
    cdef double small_work[(SMALL_N + 1) * SMALL_N + 2 * SMALL_N * SMALL_N + 8 * SMALL_N + 1]
    cdef int64_t small_iwork[7 * SMALL_N + 2]
    cdef double small_factor[3 * SMALL_N * SMALL_N + 2 * SMALL_N]
    cdef int small_piv[SMALL_N]
    cdef bint small = n <= SMALL_N
    cdef double* work
    cdef int64_t* iwork
    if small:
        work, iwork = small_work, small_iwork
    else:
        work = <double*>big_alloc(((n + 1) * n + 2 * n * n + 8 * n + 1) * sizeof(double))
        iwork = <int64_t*>malloc((2 * n + 1 + 4 * n + 1 + n) * sizeof(int64_t))
        if work == NULL or iwork == NULL:
            free(work)
            free(iwork)
            return -1
    cdef double* MT = work
    S.B = MT + (n + 1) * n
    S.Ct = S.B + n * n
    S.qb = S.Ct + n * n
    S.xb = S.qb + n
    S.tmp = S.xb + n
    cdef double* col = S.tmp + n
    cdef double* w1 = col + n
    cdef double* w2 = w1 + n
    cdef double* keys = w2 + n
    S.where = iwork
    S.alpha = S.where + 2 * n + 1
    S.beta = S.alpha + n
    S.apos = S.beta + n
    S.bpos = S.apos + n
    cdef int64_t* cand = S.bpos + n + 1
    S.n = n
    S.m = 0
    S.MT = MT
    S.q = q
    S.basic = basic
    S.fA = NULL  # allocated on first use (_refactor), on the stack when small
    S.fwork = NULL
    S.fpiv = NULL
    if small:
        S.fA, S.fwork, S.fpiv = small_factor, small_factor + 2 * n * n + n, small_piv
    # MT = [M, d]^T, so that a column of [M, d] is a contiguous row (blocked transpose)
    i0 = 0
    while i0 < n:
        j0 = 0
        while j0 < n:
            for i in range(i0, min(i0 + blk, n)):
                for j in range(j0, min(j0 + blk, n)):
                    MT[j * n + i] = M[i * n + j]
            j0 += blk
        i0 += blk
    for i in range(n):
        MT[n * n + i] = d[i]
        basic[i] = i
        S.where[i] = i
        S.apos[i] = -1
        S.bpos[i] = -1
        S.qb[i] = q[i]
        z[i] = 0.0
        ray_dz[i] = 0.0
        col[i] = 0.0
    for i in range(n, 2 * n + 1):
        S.where[i] = -1
    S.bpos[n] = -1
    refactors = 0
    out.z0 = 0.0
    out.dz0 = 0.0
    out.pivots = 0
    out.refactors = 0

    r = initial_row(q, d, n, tie_tol)
    if r < 0:
        out.status = LEMKE_TRIVIAL
        if not small:
            free(work)
            free(iwork)
        return 0
    # initial pivot: z0 enters, w_r leaves: A = [d_r]
    S.m = 1
    S.alpha[0] = r
    S.apos[r] = 0
    S.beta[0] = n
    S.bpos[n] = 0
    S.B[0] = 1.0 / d[r]
    for i in range(n):
        S.Ct[i] = d[i]
    entering = nz
    leaving = r
    basic[r] = nz
    S.where[nz] = r
    S.where[r] = -1
    _q_prime(&S)
    pivots = 1
    since = 0
    if nrec > 0:
        record[0] = entering
        record[1] = leaving
        record[2] = r
    status = LEMKE_MAX_ITER
    while pivots < max_iter:
        entering = leaving + n if leaving < n else leaving - n
        _column(&S, entering, col)
        if pivots % _CHECK_EVERY == 0 and column_residual(
                MT, S.Ct, S.alpha, S.apos, S.m, entering, n, S.xb, w1, w2) > _RESID_TOL:
            # the updated inverse has drifted: refactorise before using the column
            if not _refactor(&S):
                status = LEMKE_SINGULAR
                break
            _fresh_q_prime(&S, w2)
            refactors += 1
            since = 0
            _column(&S, entering, col)
        nc = ratio_candidates(col, S.qb, basic, n, nz, piv_tol, tie_tol, cand, &z0_row,
                              &colmax)
        if nc == 0:
            status = LEMKE_RAY
            break
        if z0_row >= 0:
            r = z0_row
        elif nc == 1:
            r = cand[0]
        else:
            unit = lex_unit(col, cand, nc)
            for k in range(n):
                loc = S.where[k]
                for s in range(nc):
                    i = cand[s]
                    if loc >= 0:
                        key = 1.0 if loc == i else 0.0
                    else:
                        key = -_wcol_entry(&S, k, i)
                    keys[s] = key / (-col[i])
                nc = keep_lex_min(keys, cand, nc, unit)
                if nc == 1:
                    break
            r = cand[0]
        leaving = basic[r]
        piv = col[r]
        # q' along the pivot: the entering variable rises to qr
        qr = -S.qb[r] / piv
        for i in range(n):
            if i != r:
                S.qb[i] += col[i] * qr
        S.qb[r] = qr
        m = S.m
        # update B = inv(Maug[alpha, beta]) for the four cases
        if entering >= n and leaving < n:  # z_j in, w_i out: border
            jj = entering - n
            _row_times_B(S.Ct, S.B, m, n, leaving, w1)
            inv = 1.0 / piv
            for s in range(m):
                bu = -S.xb[s]
                f = bu * inv
                axpy(S.B + s * n, w1, f, m)
                S.B[s * n + m] = -f
            for p in range(m):
                S.B[m * n + p] = -w1[p] * inv
            S.B[m * n + m] = inv
            S.alpha[m] = leaving
            S.apos[leaving] = m
            S.beta[m] = jj
            S.bpos[jj] = m
            for i in range(n):
                S.Ct[m * n + i] = MT[jj * n + i]
            S.m = m + 1
        elif entering >= n:  # z_j in, z_l out: replace column
            jj = entering - n
            s0 = S.bpos[leaving - n]
            y0 = -S.xb[s0]
            for p in range(m):
                S.B[s0 * n + p] /= y0
            for s in range(m):
                if s != s0:
                    f = -S.xb[s]
                    if f != 0.0:
                        axpy(S.B + s * n, S.B + s0 * n, -f, m)
            S.beta[s0] = jj
            S.bpos[leaving - n] = -1
            S.bpos[jj] = s0
            for i in range(n):
                S.Ct[s0 * n + i] = MT[jj * n + i]
        elif leaving < n:  # w_k in, w_i out: replace row
            p0 = S.apos[entering]
            _row_times_B(S.Ct, S.B, m, n, leaving, w1)
            x0 = w1[p0]
            for s in range(m):
                S.B[s * n + p0] /= x0
            w1[p0] = 0.0
            for s in range(m):
                bsp = S.B[s * n + p0]
                if bsp != 0.0:
                    axpy(S.B + s * n, w1, -bsp, m)
            S.alpha[p0] = leaving
            S.apos[entering] = -1
            S.apos[leaving] = p0
        else:  # w_k in, z_l out: remove row and column
            p0 = S.apos[entering]
            s0 = S.bpos[leaving - n]
            bsp = S.B[s0 * n + p0]
            for p in range(m):
                w2[p] = S.B[s0 * n + p] / bsp
            for s in range(m):
                if s != s0:
                    f = S.B[s * n + p0]
                    if f != 0.0:
                        axpy(S.B + s * n, w2, -f, m)
            last = m - 1
            # move the last row into s0 and the last column into p0
            if s0 != last:
                for p in range(m):
                    S.B[s0 * n + p] = S.B[last * n + p]
                S.beta[s0] = S.beta[last]
                S.bpos[S.beta[s0]] = s0
                for i in range(n):
                    S.Ct[s0 * n + i] = S.Ct[last * n + i]
            if p0 != last:
                for s in range(m):
                    S.B[s * n + p0] = S.B[s * n + last]
                S.alpha[p0] = S.alpha[last]
                S.apos[S.alpha[p0]] = p0
            S.apos[entering] = -1
            S.bpos[leaving - n] = -1
            S.m = m - 1
        basic[r] = entering
        S.where[entering] = r
        S.where[leaving] = -1
        if pivots < nrec:
            record[3 * pivots] = entering
            record[3 * pivots + 1] = leaving
            record[3 * pivots + 2] = r
        pivots += 1
        since += 1
        if leaving == nz:
            status = LEMKE_OK
            break
        if since >= refactor_every or fabs(piv) < _SMALL_PIVOT * colmax:
            if not _refactor(&S):
                status = LEMKE_SINGULAR
                break
            _fresh_q_prime(&S, w2)
            refactors += 1
            since = 0

    if status == LEMKE_OK:  # final values by eqs (2)-(3) (the caller polishes them by LU)
        _q_prime(&S)
    basic_solution(basic, S.qb, col, entering, status == LEMKE_RAY, n, z, ray_dz, &out.z0,
                   &out.dz0)
    out.status = status
    out.pivots = pivots
    out.refactors = refactors
    if not small:
        free(S.fA)
        free(S.fwork)
        free(S.fpiv)
        free(work)
        free(iwork)
    return 0


# ---------------------------------------------------------------------------- Python wrappers
def lemke_revised_kernel(M, q, d, int64_t max_iter, double piv_tol, double tie_tol, record,
                         int64_t refactor_every):
    """Revised Lemke; return (status, z, pivots, basic, ray_dz, ray_dz0, z0, refactors).

    ``record`` (int64, C-contiguous, shape (k, 3)) receives (entering, leaving, row) of the
    first k pivots.
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
        return TRIVIAL, z, 0, basic, ray, 0.0, 0.0, 0
    with nogil:
        rc = lemke_revised(f64_ptr(Ma), f64_ptr(qa), f64_ptr(da), n, max_iter, piv_tol,
                           tie_tol, i64_ptr(ra) if nrec else NULL, nrec, refactor_every,
                           f64_ptr(z), i64_ptr(basic), f64_ptr(ray), &out)
    if rc:
        raise MemoryError()
    return out.status, z, out.pivots, basic, ray, out.dz0, out.z0, out.refactors


def _column_residual(MT, Ct, alpha, apos, Py_ssize_t m, int64_t e, Py_ssize_t n, xb, acc,
                     size):
    """Python access to :c:func:`column_residual` (for tests); ``Ct`` is ``m x n``; ``acc``
    and ``size`` are work vectors (float64, length >= m)."""
    cdef cnp.ndarray MTa = f64(MT, -1, n)
    cdef cnp.ndarray Cta = f64(Ct, -1, n)
    cdef cnp.ndarray aa = i64(alpha, -1, -1)
    cdef cnp.ndarray pa = i64(apos, -1, -1)
    cdef cnp.ndarray xa = f64(xb, -1, -1)
    cdef cnp.ndarray acca = inout(acc, cnp.NPY_FLOAT64, -1, -1)
    cdef cnp.ndarray sizea = inout(size, cnp.NPY_FLOAT64, -1, -1)
    if cnp.PyArray_DIM(Cta, 0) < m or cnp.PyArray_DIM(aa, 0) < m or cnp.PyArray_DIM(xa, 0) < m \
            or cnp.PyArray_DIM(acca, 0) < m or cnp.PyArray_DIM(sizea, 0) < m:
        raise ValueError("_column_residual: inconsistent shapes")
    return column_residual(f64_ptr(MTa), f64_ptr(Cta), i64_ptr(aa), i64_ptr(pa), m, e, n,
                           f64_ptr(xa), f64_ptr(acca), f64_ptr(sizea))


cdef class LemkeRun:
    """What :func:`lemke_solve_certified` returns, by name: ``status`` (OK, RAY, MAX_ITER,
    SINGULAR, TRIVIAL), ``z`` (polished on OK, else ``max(z, 0)`` of the kernel's), ``w = M z
    + q``, ``pivots``, ``basis`` (sorted 0-based indices of the basic z's, a list), ``ray``
    (the secondary ray's direction, None unless RAY), ``z0`` (the artificial variable's last
    value), ``refactors``, ``cert``: the tuple of
    :func:`lcpcli.core._certificate.certify_arrays` (first entry 2: out of range, certify again
    with :func:`lcpcli.core.certificate.check`, which rescales), None when TRIVIAL, and
    :meth:`certificate`: the same numbers as a :class:`~lcpcli.core.certificate.Certificate`
    at a tolerance."""

    cdef readonly int status
    cdef readonly object z
    cdef readonly object w
    cdef readonly int64_t pivots
    cdef readonly list basis
    cdef readonly object ray
    cdef readonly double z0
    cdef readonly int64_t refactors
    cdef CertOut _cert
    cdef bint _certified  # _cert holds the certificate of z (not TRIVIAL)

    @property
    def cert(self):
        if not self._certified:
            return None
        cdef CertOut c = self._cert
        return (c.status, c.error, c.backward_error, c.growth, c.residual, c.bound_violation,
                c.w_violation, c.complementarity, c.equality_residual, c.worst)

    def certificate(self, tol):
        """The :class:`~lcpcli.core.certificate.Certificate` of ``z`` at ``tol``
        (:func:`~lcpcli.core.certificate.certificate_of`, the one rule for ``passed``; no tuple
        in between, this is on the small-solve path); None when TRIVIAL, out of range
        (``cert[0] == 2``: :func:`~lcpcli.core.certificate.check` rescales) or when ``z`` is
        not finite (1: the kernel stopped before computing ``w``, which ``check`` gives)."""
        if not self._certified or self._cert.status != 0:
            return None
        cdef CertOut c = self._cert
        return certificate_of(c.status, c.error, c.backward_error, c.growth, c.residual,
                              c.bound_violation, c.w_violation, c.complementarity,
                              c.equality_residual, c.worst, tol)

    def __repr__(self):
        return (f"LemkeRun(status={self.status}, pivots={self.pivots}, "
                f"refactors={self.refactors})")


cdef LemkeRun _run(int status, object z, object w, int64_t pivots, list basis, object ray,
                   double z0, int64_t refactors, const CertOut* cert):
    """The record (``cert`` NULL: no certificate, TRIVIAL)."""
    cdef LemkeRun r = LemkeRun.__new__(LemkeRun)
    r.status, r.z, r.w, r.pivots, r.basis = status, z, w, pivots, basis
    r.ray, r.z0, r.refactors = ray, z0, refactors
    r._certified = cert != NULL
    if cert != NULL:
        r._cert = cert[0]
    return r




cdef int _solve_certified(const double* Mp, const double* qp, const double* dp, Py_ssize_t n,
                          int64_t max_iter, double piv_tol, double tie_tol,
                          int64_t refactor_every, double* raw, int64_t* bp, double* rp,
                          Py_ssize_t* iwork, double* zp, double* wp, LemkeOut* out,
                          CertOut* cert) noexcept nogil:
    """The compiled part of :func:`lemke_solve_certified` (workspace as laid out there; ``dp``
    NULL: the covering vector of ones, written at ``rp + n``): kernel, final polish of an
    answer, ``max(z, 0)`` of any other end, and the certificate.  0, or -1 (no memory)."""
    cdef int rc
    cdef Py_ssize_t i
    if dp == NULL:
        for i in range(n):
            rp[n + i] = 1.0
        dp = rp + n
    rc = lemke_revised(Mp, qp, dp, n, max_iter, piv_tol, tie_tol, NULL, 0, refactor_every, raw,
                       bp, rp, out)
    if rc == 0:
        if out.status == LEMKE_OK:
            rc = polish(Mp, qp, n, raw, bp, zp)
        else:
            for i in range(n):
                zp[i] = raw[i] if raw[i] > 0.0 else 0.0
    if rc == 0 and out.status != LEMKE_TRIVIAL:
        certify_dense(n, Mp, n, qp, zp, 0, NULL, NULL, wp, raw + n, iwork, NULL, cert)
    return rc


def lemke_solve_certified(M, q, d, int64_t max_iter, double piv_tol, double tie_tol,
                          int64_t refactor_every, balance=None):
    """Kernel, final polish and the certificate in one compiled call (a :class:`LemkeRun`).

    ``d`` None means the covering vector of all ones.  The certificate is
    :c:func:`lcpcli.core._certificate.certify_dense`'s (the project's one definition, for an
    LCP) of the returned ``z``.  ``balance``: None, or the thresholds ``(balanced,
    q_balanced)`` of :data:`lcpcli.analysis.scaling.BALANCE`: the call then first makes the
    equilibration's balance test (:c:func:`lcpcli.analysis._scaling._balanced`, the one
    definition, as :func:`lcpcli.analysis.scaling.is_balanced`) and returns None, without
    solving, when the problem is not balanced.  ``max_iter`` or ``refactor_every`` 0 (or
    less): the defaults, :func:`lcpcli.solvers.kernels.lemke.default_max_iter` and
    :func:`default_refactor_every` (no Python call for them on the small path).
    """
    cdef Py_ssize_t n = len(q)
    if max_iter <= 0:
        max_iter = default_pivot_limit(n)
    if refactor_every <= 0:
        refactor_every = default_refactor(n)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray da
    cdef const double* dp = NULL
    if d is not None:
        da = f64(d, n, -1)
        dp = f64_ptr(da)
    cdef cnp.ndarray z = empty_f64(n)
    cdef cnp.ndarray w = empty_f64(n)
    cdef CertOut cert
    if n == 0:  # the certificate of the empty problem
        cert.status, cert.error, cert.backward_error, cert.growth = 0, 0.0, 0.0, 1.0
        cert.residual = cert.bound_violation = cert.w_violation = 0.0
        cert.complementarity = cert.equality_residual = 0.0
        cert.worst = -1
        return _run(TRIVIAL, z, w, 0, [], None, 0.0, 0, &cert)
    cdef const double* Mp = f64_ptr(Ma)
    cdef const double* qp = f64_ptr(qa)
    cdef double* zp = f64_ptr(z)
    cdef LemkeOut out
    cdef int rc = 0
    # one block of 8-byte words: raw z (6 n doubles, the kernel's workspace), the ray (n), the
    # covering vector of ones (n), the basis (n int64) and the certificate's 3 n indices; on
    # the stack up to SMALL_N
    cdef double small_raw[12 * SMALL_N]
    cdef double* raw = &small_raw[0]
    if n > SMALL_N:
        raw = <double*>malloc(12 * n * sizeof(double))
        if raw == NULL:
            raise MemoryError()
    cdef double* rp = raw + 6 * n
    cdef int64_t* bp = <int64_t*>(raw + 8 * n)
    cdef Py_ssize_t* iwork = <Py_ssize_t*>(raw + 9 * n)
    cdef int balanced, q_balanced
    if balance is not None:
        balanced, q_balanced = balance
        # the test's workspace (4 n long longs) is the block's first 4 n words
        if not _balanced(n, Mp, n, qp, balanced, q_balanced, <long long*> raw):
            if n > SMALL_N:
                free(raw)
            return None
    cdef double* wp = f64_ptr(w)
    if n > GIL_FREE_N:
        with nogil:
            rc = _solve_certified(Mp, qp, dp, n, max_iter, piv_tol, tie_tol, refactor_every,
                                  raw, bp, rp, iwork, zp, wp, &out, &cert)
    else:  # a call of a microsecond or two: releasing the GIL would cost more than it frees
        rc = _solve_certified(Mp, qp, dp, n, max_iter, piv_tol, tie_tol, refactor_every, raw,
                              bp, rp, iwork, zp, wp, &out, &cert)
    if rc:
        if n > SMALL_N:
            free(raw)
        raise MemoryError()
    cdef cnp.ndarray ray = None
    cdef list basis = []
    try:
        if out.status == LEMKE_RAY:
            ray = empty_f64(n)
            memcpy(f64_ptr(ray), rp, n * sizeof(double))
        if out.status != LEMKE_TRIVIAL:
            basis = basis_list(bp, n)
    finally:
        if n > SMALL_N:
            free(raw)
    if out.status == LEMKE_TRIVIAL:  # z = 0: the caller certifies it the ordinary way
        return _run(out.status, z, w, 0, basis, ray, 0.0, 0, NULL)
    return _run(out.status, z, w, out.pivots, basis, ray, out.z0, out.refactors, &cert)
