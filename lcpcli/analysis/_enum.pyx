# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernel of the enumeration method (Cython, parallel over cones with OpenMP).

A cone is coded by an integer ``code`` whose bit ``j`` is set when ``z_j`` is the complementary
basic variable (column ``-M_j``) and clear when it is ``w_j`` (column ``I_j``).  With
``S = {j : bit j set}`` the complementary system ``A_r y = q`` splits into

* ``M[S, S] z_S = -q_S``                       (the rows of S: ``w_S = 0``)
* ``w_i = q_i + M[i, S] z_S``  for ``i`` not in S,

so ``det A_r = (-1)^|S| det M[S, S]`` and each cone costs one pivoted LU of size ``|S|``.

Status codes written per cone (see :data:`INFEASIBLE` ...): a cheap sign test first (a row
``i`` with ``q_i < 0`` whose entries on S are all ``<= 0`` can never give ``w_i >= 0``; a row
``i`` in S with ``q_i > 0`` and entries ``>= 0`` on S can never give ``w_i = 0``), then the
solve.  A (numerically) singular ``M[S, S]`` is re-eliminated with complete pivoting to decide
whether ``-q_S`` lies in its range; consistent singular cones are left to an LP in Python.

Parallelism: blocks of cones run in OpenMP threads (``prange``; the module is built with
``-fopenmp`` where the compiler has it, serial otherwise); every task allocates its own
scratch, the cone functions are ``nogil`` on raw buffers.  Worker pools that fork must not
fork a process that has run a parallel region (GNU OpenMP's threads do not survive ``fork``):
lcpcli's pools use ``forkserver``/``spawn`` (see :mod:`lcpcli.batch.pool`).
"""

from cython.parallel cimport prange
from libc.math cimport fabs, frexp, ldexp
from libc.stdint cimport int64_t, uint8_t
from libc.stdlib cimport free, malloc

import numpy as np

cimport numpy as cnp

from lcpcli.core.arrays cimport (
    f64,
    f64_ptr,
    i64,
    i64_ptr,
    inout,
    u8_ptr,
)

cnp.import_array()

cdef enum:
    E_INFEASIBLE = 0
    E_FEASIBLE = 1
    E_SINGULAR_CONSISTENT = 2
    E_PRUNED = 3
    E_SINGULAR_EMPTY = 4
    E_CANDIDATE = 5

INFEASIBLE = E_INFEASIBLE
FEASIBLE = E_FEASIBLE
SINGULAR_CONSISTENT = E_SINGULAR_CONSISTENT
PRUNED = E_PRUNED
SINGULAR_EMPTY = E_SINGULAR_EMPTY
CANDIDATE = E_CANDIDATE

# Cones handled by one parallel task of the direct path.
cdef int64_t _BLOCK = 512
BLOCK = _BLOCK
#: Below this many cones one thread does the work (thread start-up costs milliseconds).
SERIAL_BELOW = 8192
#: Sub-block size (bits) of one parallel task of the fast path.
TASK_BITS = 12

# fast path (see classify_chunk_fast)
# Relative threshold of a pivot against the largest entry of its row and column.
cdef double _PIVOT_THRESHOLD = 1e-6
# Loose relative tolerance of the leaf test (candidates are re-checked strictly).
cdef double _LOOSE_RTOL = 1e-6
# A tableau entry beyond this multiple of the base scale triggers the direct path.
cdef double _GROWTH_LIMIT = 1e8
PIVOT_THRESHOLD = _PIVOT_THRESHOLD
LOOSE_RTOL = _LOOSE_RTOL
GROWTH_LIMIT = _GROWTH_LIMIT


cdef struct Data:
    const double* M
    const double* q
    const int64_t* pos_mask
    const int64_t* neg_mask
    Py_ssize_t n
    double piv_tol
    double feas_rel
    double mu
    double qnorm
    double prune_tol


cdef inline void _swap_rows(double* A, double* b, Py_ssize_t k, Py_ssize_t p, Py_ssize_t bi,
                            Py_ssize_t start) noexcept nogil:
    """Swap rows ``p`` and ``bi`` of the k x k ``A`` (columns ``start`` on) and of ``b``."""
    cdef Py_ssize_t j
    cdef double t
    for j in range(start, k):
        t = A[p * k + j]
        A[p * k + j] = A[bi * k + j]
        A[bi * k + j] = t
    t = b[p]
    b[p] = b[bi]
    b[bi] = t


cdef inline void _eliminate_below(double* A, double* b, Py_ssize_t k,
                                  Py_ssize_t p) noexcept nogil:
    """One step of Gaussian elimination on the k x k ``A`` and ``b``: subtract multiples of
    row ``p`` (pivot ``A[p, p]``, nonzero) from the rows below it."""
    cdef Py_ssize_t i, j
    cdef double piv = A[p * k + p]
    cdef double f
    for i in range(p + 1, k):
        f = A[i * k + p] / piv
        if f != 0.0:
            for j in range(p + 1, k):
                A[i * k + j] -= f * A[p * k + j]
            b[i] -= f * b[p]


cdef bint _complete_pivot_consistent(double* A, double* b, Py_ssize_t k, double piv_tol,
                                     double cons_tol) noexcept nogil:
    """Gaussian elimination with complete pivoting on the k x k A (overwritten).

    Returns True when ``A x = b`` is consistent (remaining right-hand side below cons_tol).
    """
    cdef Py_ssize_t p, i, j, bi, bj
    cdef double best, a, t
    for p in range(k):
        best = 0.0
        bi = p
        bj = p
        for i in range(p, k):
            for j in range(p, k):
                a = fabs(A[i * k + j])
                if a > best:
                    best = a
                    bi = i
                    bj = j
        if best <= piv_tol:
            for i in range(p, k):
                if fabs(b[i]) > cons_tol:
                    return False
            return True
        if bi != p:
            _swap_rows(A, b, k, p, bi, 0)
        if bj != p:
            for i in range(k):
                t = A[i * k + p]
                A[i * k + p] = A[i * k + bj]
                A[i * k + bj] = t
        _eliminate_below(A, b, k, p)
    return True


cdef void _fill_block(const Data* D, const int64_t* idx, Py_ssize_t k, double* A, double* b,
                      int* ce) noexcept nogil:
    """``A = M[S, S]``, ``b = -q_S``, equilibrated by powers of two (exact): every row, then
    every column, divided by its largest entry's binary exponent (``ce`` keeps the column
    exponents: the solution of the scaled block is ``z_j 2^ce[j]``).  The singularity test on
    the result is relative to the block itself: the same on ``D1 M[S, S] D2`` for power-of-two
    ``D1``, ``D2``, and independent of the other entries of M."""
    cdef Py_ssize_t n = D.n, r, c
    cdef double big
    cdef int e
    for r in range(k):
        b[r] = -D.q[idx[r]]
        big = 0.0
        for c in range(k):
            A[r * k + c] = D.M[idx[r] * n + idx[c]]
            big = max(big, fabs(A[r * k + c]))
        if big > 0.0:
            frexp(big, &e)
            for c in range(k):
                A[r * k + c] = ldexp(A[r * k + c], -e)
            b[r] = ldexp(b[r], -e)
    for c in range(k):
        big = 0.0
        for r in range(k):
            big = max(big, fabs(A[r * k + c]))
        ce[c] = 0
        if big > 0.0:
            frexp(big, &e)
            ce[c] = e
            for r in range(k):
                A[r * k + c] = ldexp(A[r * k + c], -e)


cdef uint8_t one_cone(const Data* D, int64_t code, int64_t* idx, double* A, double* b,
                      double* z, double* Tm) noexcept nogil:
    """Status of cone ``code``; ``idx`` (2 n), ``A`` (n * n), ``b``, ``z`` (n) are scratch.

    ``D.piv_tol`` is relative: the block is singular when, in some column of the elimination,
    every remaining entry is at most ``piv_tol`` times the magnitude of the terms it was
    computed from (``Tm``, n * n scratch; as :func:`lcpcli.analysis.classify` tests principal
    pivots): a test that is the same on ``D1 M[S, S] D2`` for any positive diagonal ``D1``,
    ``D2``, whatever the other entries of M."""
    cdef Py_ssize_t n = D.n, i, j, k = 0, r, c, p, bi
    cdef const double* M = D.M
    cdef const double* q = D.q
    cdef double best, a, t, s, zmax, tau, bmax, cons_tol
    cdef bint singular = False
    # ---- cheap sign tests (exact zero/sign patterns of M, q beyond the tolerance)
    for i in range(n):
        if q[i] < -D.prune_tol and (code & D.pos_mask[i]) == 0:
            return E_PRUNED
        if q[i] > D.prune_tol and ((code >> i) & 1) == 1 and (code & D.neg_mask[i]) == 0:
            return E_PRUNED
    for j in range(n):
        if (code >> j) & 1:
            idx[k] = j
            k += 1
    if k == 0:
        for i in range(n):
            if q[i] < -D.feas_rel * D.qnorm:
                return E_INFEASIBLE
        return E_FEASIBLE
    cdef int* ce = <int*> (idx + n)  # the column exponents, after the n indices
    cdef bint shown
    cdef double f, piv
    _fill_block(D, idx, k, A, b, ce)
    for r in range(k * k):
        Tm[r] = fabs(A[r])
    # ---- LU with partial pivoting, applied to b on the fly
    for p in range(k):
        best = -1.0
        bi = p
        shown = False  # some entry of the column is larger than its rounding could make it
        for i in range(p, k):
            a = fabs(A[i * k + p])
            if a > D.piv_tol * Tm[i * k + p]:
                shown = True
            if a > best:
                best = a
                bi = i
        if not shown or best == 0.0:
            singular = True
            break
        if bi != p:
            _swap_rows(A, b, k, p, bi, p)
            for j in range(p, k):
                t = Tm[p * k + j]
                Tm[p * k + j] = Tm[bi * k + j]
                Tm[bi * k + j] = t
        piv = A[p * k + p]
        for i in range(p + 1, k):
            f = A[i * k + p] / piv
            if f != 0.0:
                for j in range(p + 1, k):
                    A[i * k + j] -= f * A[p * k + j]
                    Tm[i * k + j] += fabs(f) * Tm[p * k + j]
                b[i] -= f * b[p]
    if singular:
        _fill_block(D, idx, k, A, b, ce)
        bmax = 0.0
        for r in range(k):
            bmax = max(bmax, fabs(b[r]))
        cons_tol = 1e-9 * (bmax + D.piv_tol) * k
        if _complete_pivot_consistent(A, b, k, D.piv_tol, cons_tol):
            return E_SINGULAR_CONSISTENT
        return E_SINGULAR_EMPTY
    # ---- back substitution
    zmax = 0.0
    for p in range(k - 1, -1, -1):
        s = b[p]
        for j in range(p + 1, k):
            s -= A[p * k + j] * z[j]
        z[p] = s / A[p * k + p]
    for p in range(k):
        z[p] = ldexp(z[p], -ce[p])
        zmax = max(zmax, fabs(z[p]))
    tau = D.feas_rel * (D.mu * zmax + D.qnorm)
    for p in range(k):
        if D.mu * z[p] < -tau:
            return E_INFEASIBLE
    for i in range(n):
        if (code >> i) & 1:
            continue
        s = q[i]
        for p in range(k):
            s += M[i * n + idx[p]] * z[p]
        if s < -tau:
            return E_INFEASIBLE
    return E_FEASIBLE


cdef int classify_range(const Data* D, int64_t start, int64_t lo, int64_t hi,
                        uint8_t* out) noexcept nogil:
    """Direct path for cones ``start + lo .. start + hi - 1`` into ``out[lo:hi]``; -1: no
    memory."""
    cdef Py_ssize_t n = D.n
    cdef int64_t t
    cdef double* work = <double*>malloc((2 * n * n + 2 * n + 1) * sizeof(double))
    cdef int64_t* idx = <int64_t*>malloc((2 * n + 1) * sizeof(int64_t))  # + one_cone's ce
    if work == NULL or idx == NULL:
        free(work)
        free(idx)
        return -1
    for t in range(lo, hi):
        out[t] = one_cone(D, start + t, idx, work, work + n * n, work + n * n + n,
                          work + n * n + 2 * n)
    free(work)
    free(idx)
    return 0


cdef int _fill(Data* D, M, q, pos_mask, neg_mask, double piv_tol, double feas_rel, double mu,
               double qnorm, double prune_tol, list keep) except -1:
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray pa = i64(pos_mask, n, -1)
    cdef cnp.ndarray na = i64(neg_mask, n, -1)
    if n == 0:
        raise ValueError("enum: empty problem")
    if n > 62:
        raise ValueError("enum: n > 62 does not fit the bit coding")
    keep.extend((Ma, qa, pa, na))  # the arrays outlive the call
    D.M = f64_ptr(Ma)
    D.q = f64_ptr(qa)
    D.pos_mask = i64_ptr(pa)
    D.neg_mask = i64_ptr(na)
    D.n = n
    D.piv_tol = piv_tol
    D.feas_rel = feas_rel
    D.mu = mu
    D.qnorm = qnorm
    D.prune_tol = prune_tol
    return 0


def classify_chunk(M, q, int64_t start, int64_t count, pos_mask, neg_mask, double piv_tol,
                   double feas_rel, double mu, double qnorm, double prune_tol, out):
    """Status of the cones ``start .. start + count - 1`` into ``out[0:count]`` (uint8)."""
    cdef Data D
    keep = []
    _fill(&D, M, q, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm, prune_tol, keep)
    cdef cnp.ndarray oa = inout(out, cnp.NPY_UINT8, -1, -1)
    cdef uint8_t* op = u8_ptr(oa)
    if cnp.PyArray_DIM(oa, 0) < count:
        raise ValueError("classify_chunk: out is too short")
    cdef int64_t nblocks, blk, lo, hi
    cdef int failed = 0
    if count <= 0:
        return
    if count < SERIAL_BELOW:
        with nogil:
            failed = classify_range(&D, start, 0, count, op)
    else:
        nblocks = (count + _BLOCK - 1) // _BLOCK
        for blk in prange(nblocks, nogil=True, schedule="dynamic"):
            lo = blk * _BLOCK
            hi = min(count, lo + _BLOCK)
            if classify_range(&D, start, lo, hi, op):
                failed = 1
    if failed:
        raise MemoryError()


# ---------------------------------------------------------------------------- fast path
# Depth-first principal pivoting.  The cone of the z-basic set S is feasible exactly when the
# principal pivot transform (PPT) of the tableau ``w = M z + q`` on S has a nonnegative
# constant column q' (the basic values y).  The codes of an aligned block
# ``start .. start + 2^k - 1`` form a binary tree (bits k-1 .. 0 decided in turn); a z-child
# is its parent pivoted on one index (O(n d) work, d = indices still undecided), a w-child
# shares its parent's tableau, and a leaf is an O(n) sign check of q'.  Total about
# 2 n 2^k operations instead of an LU per cone.
#
# Safety: a pivot that is small against its row and column (threshold pivoting), or a
# tableau that grows beyond GROWTH_LIMIT, sends the whole subtree to the direct LU path.
# Leaves passing a loose sign test are only CANDIDATES: the caller re-classifies them with
# the direct path, which is the authority.  So the fast path can only lose a feasible cone
# through a rounding error larger than the loose tolerance after passing the guards.

cdef bint _ppt_pivot(const double* Ts, const double* qs, double* Td, double* qd, Py_ssize_t d,
                     Py_ssize_t n, double base) noexcept nogil:
    """Principal pivot of (Ts, qs) on index d into (Td, qd), columns 0..d-1 only (row stride
    n).  Returns False (nothing usable written) when the pivot fails the threshold or growth
    test."""
    cdef Py_ssize_t i, j
    cdef double p = Ts[d * n + d], big = 0.0, a, inv, qdp, limit, f, v
    for i in range(n):
        a = fabs(Ts[i * n + d])
        if a > big:
            big = a
    for j in range(d):
        a = fabs(Ts[d * n + j])
        if a > big:
            big = a
    if p == 0.0 or fabs(p) < _PIVOT_THRESHOLD * big:
        return False
    inv = 1.0 / p
    qdp = qs[d] * inv
    limit = _GROWTH_LIMIT * base
    for i in range(n):
        if i == d:
            continue
        f = Ts[i * n + d] * inv
        qd[i] = qs[i] - f * qs[d]
        for j in range(d):
            v = Ts[i * n + j] - f * Ts[d * n + j]
            if fabs(v) > limit:
                return False
            Td[i * n + j] = v
    for j in range(d):
        Td[d * n + j] = -Ts[d * n + j] * inv
    qd[d] = -qdp
    return True


cdef uint8_t _leaf(const double* qv, int64_t code, Py_ssize_t n, double mu, double qnorm,
                   double loose) noexcept nogil:
    cdef Py_ssize_t i
    cdef double zmax = 0.0, a, tau, v
    for i in range(n):
        if (code >> i) & 1:
            a = fabs(qv[i])
            if a > zmax:
                zmax = a
    tau = loose * (mu * zmax + qnorm)
    for i in range(n):
        v = qv[i] * mu if (code >> i) & 1 else qv[i]
        if v < -tau:
            return E_INFEASIBLE
    return E_CANDIDATE


cdef int ppt_block(const Data* D, int64_t start, Py_ssize_t k, uint8_t* out, int64_t off,
                   double base) noexcept nogil:
    """Classify the aligned block ``start .. start + 2^k - 1`` into ``out[off:off + 2^k]``.
    Returns -1 when out of memory."""
    cdef Py_ssize_t n = D.n, i, j, d, level, s, c
    cdef int64_t t, low
    cdef bint ok = True
    cdef double* work = <double*>malloc(((k + 3) * n * n + (k + 4) * n + 1) * sizeof(double))
    cdef int64_t* iwork = <int64_t*>malloc((2 * n + 2 * (k + 1) + 1) * sizeof(int64_t))
    if work == NULL or iwork == NULL:
        free(work)
        free(iwork)
        return -1
    cdef double* T = work                       # (k + 1) tableaux of n x n
    cdef double* Q = T + (k + 1) * n * n        # (k + 1) vectors of n
    cdef double* tmpT = Q + (k + 1) * n
    cdef double* tmpQ = tmpT + n * n
    cdef double* b = tmpQ + n
    cdef double* z = b + n
    cdef double* Tm = z + n  # one_cone's magnitudes (n x n)
    cdef double* A = tmpT  # direct-path scratch (tmpT is free once the root is pivoted)
    cdef int64_t* idx = iwork
    cdef int64_t* slot = idx + 2 * n  # idx: n indices, then one_cone's column exponents
    cdef int64_t* choice = slot + k + 1
    # root: pivot (M, q) on the fixed high bits of start, highest first
    for i in range(n):
        Q[i] = D.q[i]
        for j in range(n):
            T[i * n + j] = D.M[i * n + j]
    d = n - 1
    while d >= k:
        if (start >> d) & 1:
            if not _ppt_pivot(T, Q, tmpT, tmpQ, d, n, base):
                ok = False
                break
            for i in range(n):
                Q[i] = tmpQ[i]
                for j in range(d):
                    T[i * n + j] = tmpT[i * n + j]
        d -= 1
    if not ok:
        for t in range(1 << k):
            out[off + t] = one_cone(D, start + t, idx, A, b, z, Tm)
        free(work)
        free(iwork)
        return 0
    for i in range(k + 1):
        slot[i] = 0
        choice[i] = -1
    low = 0
    level = 0
    while level >= 0:
        if level == k:
            out[off + low] = _leaf(Q + slot[level] * n, start + low, n, D.mu, D.qnorm,
                                   _LOOSE_RTOL)
            level -= 1
            continue
        c = choice[level] + 1
        if c == 2:
            choice[level] = -1
            level -= 1
            continue
        choice[level] = c
        d = k - 1 - level
        low = (low >> (d + 1)) << (d + 1)
        if c == 0:
            slot[level + 1] = slot[level]
            level += 1
            continue
        low |= (<int64_t>1) << d
        s = slot[level]
        if _ppt_pivot(T + s * n * n, Q + s * n, T + (level + 1) * n * n, Q + (level + 1) * n,
                      d, n, base):
            slot[level + 1] = level + 1
            level += 1
        else:  # direct path for the whole subtree of this z-choice
            for t in range((<int64_t>1) << d):
                out[off + low + t] = one_cone(D, start + low + t, idx, A, b, z, Tm)
    free(work)
    free(iwork)
    return 0


def classify_chunk_fast(M, q, int64_t start, int64_t count, pos_mask, neg_mask,
                        double piv_tol, double feas_rel, double mu, double qnorm,
                        double prune_tol, out):
    """Like :func:`classify_chunk`, by depth-first principal pivoting where it is safe.

    ``count`` must be a power of two and ``start`` a multiple of it; the statuses are those of
    :func:`classify_chunk` except that feasible cones come back as CANDIDATE (re-check them
    with :func:`classify_chunk` on that single code).
    """
    cdef Data D
    keep = []
    _fill(&D, M, q, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm, prune_tol, keep)
    cdef cnp.ndarray oa = inout(out, cnp.NPY_UINT8, -1, -1)
    cdef uint8_t* op = u8_ptr(oa)
    cdef Py_ssize_t k = int(count).bit_length() - 1
    if count <= 0 or count != (<int64_t>1) << k or start % count:
        raise ValueError("classify_chunk_fast needs an aligned power-of-two block")
    if cnp.PyArray_DIM(oa, 0) < count:
        raise ValueError("classify_chunk_fast: out is too short")
    amax = float(np.max(np.abs(M)))
    cdef double base = max(amax, 1.0 / max(amax, 1e-300), 1.0)
    cdef Py_ssize_t sub = min(k, TASK_BITS)
    cdef int64_t ntasks, task
    cdef int failed = 0
    if k == sub:
        with nogil:
            failed = ppt_block(&D, start, k, op, 0, base)
    else:
        ntasks = (<int64_t>1) << (k - sub)
        for task in prange(ntasks, nogil=True, schedule="dynamic"):
            if ppt_block(&D, start + (task << sub), sub, op, task << sub, base):
                failed = 1
    if failed:
        raise MemoryError()
