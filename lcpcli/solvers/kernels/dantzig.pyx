# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernel of the Dantzig / Cottle-Dantzig principal-pivoting method (box form).

Problem: ``w = M z + q``, ``l <= z <= u``; ``w >= 0`` where ``z = l``, ``w <= 0`` where
``z = u``, ``w = 0`` strictly between (LCP: ``l = 0``, ``u = inf``; free: ``l = -inf, u = inf``).

Index states: 0 not yet processed (``z`` held at ``clip(0, l, u)``), 1 clamped (``w = 0``,
in the active block ``C``), 2 at the lower bound, 3 at the upper bound, 4 fixed (``l = u``).
Indices are processed one at a time (free ones first); the driving index ``i`` moves ``z_i``
in the direction that brings ``w_i`` to zero, while the clamped ``z_C`` follow so that
``w_C`` stays zero; the step stops at the first event (``w_i = 0``: clamp ``i``; ``z_i`` at a
bound; a clamped ``z_j`` at a bound: unclamp ``j``; a bounded ``w_j`` reaching zero: clamp
``j``).  This is ODE's dLCP / Baraff's method (Cottle-Dantzig's principal pivoting).

The inverse of ``M[C, C]`` is kept explicitly and updated by bordering (add: O(k^2)) and by
the block-inverse downdate (remove: O(k^2)), and recomputed from scratch every ``64 + k``
updates, which bounds the drift (a singular block at a refactorisation keeps the updated
inverse); the caller re-solves the final active set.  (An optional step of iterative
refinement per direction, ``refine=True``, doubled the time at n = 1000 for no measurable gain
in accuracy.)

C level: :c:func:`dantzig` on raw row-major buffers, without the GIL.
"""

from libc.math cimport INFINITY, fabs
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc

from lcpcli.solvers.kernels.dense cimport invert
from lcpcli.solvers.kernels.simd cimport axpy, axpy_scaled, big_alloc

cimport numpy as cnp

from lcpcli.core.arrays cimport (
    f64,
    f64_ptr,
    i64,
    i64_ptr,
    zeros_f64,
    zeros_i64,
)

cnp.import_array()

cdef enum:
    DZ_OK = 0
    DZ_UNBOUNDED = 1
    DZ_MAX_ITER = 2
    DZ_SINGULAR = 3

OK = DZ_OK
UNBOUNDED = DZ_UNBOUNDED
MAX_ITER = DZ_MAX_ITER
SINGULAR = DZ_SINGULAR

cdef enum:
    S_FREE = 0
    S_CLAMPED = 1
    S_AT_LOWER = 2
    S_AT_UPPER = 3
    S_FIXED = 4

FREE, CLAMPED, AT_LOWER, AT_UPPER, FIXED = S_FREE, S_CLAMPED, S_AT_LOWER, S_AT_UPPER, S_FIXED

# Relative size of a Schur complement below which bordering reports a singular block.
cdef double _SCHUR_RTOL = 1e-13
# |w_i| below this (relative to mu max(1, |z_i|) + |q_i|) counts as zero.
cdef double _W_RTOL = 1e-13
# Direction entries below this (relative to max(1, |dz|)) count as zero in the events.
cdef double _DIR_RTOL = 1e-12


cdef bint _add(double* Binv, Py_ssize_t n, int64_t* C, Py_ssize_t k, const double* M,
               int64_t j, double* x, double* y, double* col) noexcept nogil:
    """Border the inverse of M[C, C] (size k, row stride n) with index j; False if singular."""
    cdef Py_ssize_t a, b
    cdef double sx, mb, s, big, t, inv
    for a in range(k):
        x[a] = 0.0
        y[a] = 0.0
    for b in range(k):
        col[b] = M[C[b] * n + j]
    for a in range(k):
        sx = 0.0
        for b in range(k):
            sx += Binv[a * n + b] * col[b]
        x[a] = sx
    for b in range(k):  # y = M[j, C] Binv, row by row of Binv (contiguous)
        mb = M[j * n + C[b]]
        if mb != 0.0:
            for a in range(k):
                y[a] += mb * Binv[b * n + a]
    s = M[j * n + j]
    big = fabs(M[j * n + j])
    for a in range(k):
        t = M[j * n + C[a]] * x[a]
        s -= t
        big += fabs(t)
    if fabs(s) <= _SCHUR_RTOL * big or big == 0.0:
        return False
    inv = 1.0 / s
    for a in range(k):
        axpy_scaled(Binv + a * n, y, x[a], inv, k)  # += x[a] * y[b] * inv
        Binv[a * n + k] = -x[a] * inv
        Binv[k * n + a] = -y[a] * inv
    Binv[k * n + k] = inv
    C[k] = j
    return True


cdef void _remove(double* Binv, Py_ssize_t n, int64_t* C, int64_t* pos, Py_ssize_t k,
                  Py_ssize_t p) noexcept nogil:
    """Remove position p from the inverse of M[C, C] (size k); the last index moves to p."""
    cdef Py_ssize_t a, b, last = k - 1
    cdef double t, h, f
    cdef int64_t moved
    if p != last:
        for a in range(k):
            t = Binv[a * n + p]
            Binv[a * n + p] = Binv[a * n + last]
            Binv[a * n + last] = t
        for b in range(k):
            t = Binv[p * n + b]
            Binv[p * n + b] = Binv[last * n + b]
            Binv[last * n + b] = t
        moved = C[last]
        C[p] = moved
        pos[moved] = p
    h = Binv[last * n + last]
    for a in range(last):
        f = Binv[a * n + last] / h
        if f != 0.0:
            axpy(Binv + a * n, Binv + last * n, -f, last)


cdef int _refactor(double* Binv, Py_ssize_t n, const int64_t* C, Py_ssize_t k,
                   const double* M, double** space) noexcept nogil:
    """Binv = inv(M[C, C]) from scratch; a singular block keeps the updated inverse.
    ``space`` holds the work buffer (allocated on first use).  Returns -1 when out of
    memory."""
    cdef Py_ssize_t a, b
    if k == 0:
        return 0
    if space[0] == NULL:
        space[0] = <double*>malloc((3 * n * n + 2 * n + 1) * sizeof(double))
        if space[0] == NULL:
            return -1
    cdef double* K = space[0]
    cdef double* inv = K + n * n
    cdef double* work = inv + n * n
    cdef int* ipiv = <int*>(work + n * n + n)
    for a in range(k):
        for b in range(k):
            K[a * k + b] = M[C[a] * n + C[b]]
    if invert(K, k, inv, work, ipiv) == 0:
        for a in range(k):
            for b in range(k):
                Binv[a * n + b] = inv[a * k + b]
    return 0


cdef int dantzig(const double* M, const double* q, const double* lo, const double* up,
                 const int64_t* order, Py_ssize_t n, int64_t max_piv, int64_t refactor_period,
                 bint refine, double* z, int64_t* state, int* status_out,
                 int64_t* pivots_out) noexcept nogil:
    """Run the method on row-major ``M``; fill ``z``, ``state`` (n).  Returns 0 or -1 (no
    memory).  ``refactor_period`` 0: refactorise every ``64 + k`` updates; p > 0: every p."""
    cdef Py_ssize_t a, b, t, k = 0, ev_j
    cdef int64_t i, j, pivots = 0, updates = 0, period
    cdef int status = DZ_OK, event
    cdef double mscale = 0.0, v, wi, zscale, qs, tolw, direc, s, dmax, epsz, epsw, tmin, tt, d
    cdef double* space = NULL
    cdef double* work = <double*>big_alloc((n * n + 9 * n + 1) * sizeof(double))
    cdef int64_t* iwork = <int64_t*>malloc((2 * n + 1) * sizeof(int64_t))
    if work == NULL or iwork == NULL:
        free(work)
        free(iwork)
        return -1
    cdef double* Binv = work
    cdef double* w = Binv + n * n
    cdef double* dz = w + n
    cdef double* dw = dz + n
    cdef double* rhs = dw + n
    cdef double* col = rhs + n
    cdef double* x = col + n
    cdef double* y = x + n
    cdef double* col2 = y + n
    cdef int64_t* C = iwork
    cdef int64_t* pos = C + n
    for a in range(n * n):
        v = fabs(M[a])
        if v > mscale:
            mscale = v
        Binv[a] = 0.0
    if mscale == 0.0:
        mscale = 1.0
    for a in range(n):
        z[a] = min(max(0.0, lo[a]), up[a])
        w[a] = 0.0
        state[a] = S_FIXED if lo[a] == up[a] else S_FREE
        pos[a] = -1
        dz[a] = 0.0
        dw[a] = 0.0
        rhs[a] = 0.0
        col[a] = 0.0
    for t in range(n):
        i = order[t]
        if state[i] == S_FIXED:
            continue
        # w_i from scratch (unprocessed rows are not maintained)
        wi = q[i]
        for b in range(n):
            wi += M[i * n + b] * z[b]
        w[i] = wi
        while True:
            wi = w[i]
            zscale = 1.0
            qs = fabs(q[i])
            tolw = _W_RTOL * (mscale * max(zscale, fabs(z[i])) + qs) + 1e-300
            if z[i] <= lo[i] and wi >= -tolw:
                state[i] = S_AT_LOWER
                z[i] = lo[i]
                break
            if z[i] >= up[i] and wi <= tolw:
                state[i] = S_AT_UPPER
                z[i] = up[i]
                break
            if fabs(wi) <= tolw:
                if not _add(Binv, n, C, k, M, i, x, y, col2):
                    status = DZ_SINGULAR
                    break
                pos[i] = k
                k += 1
                updates += 1
                state[i] = S_CLAMPED
                w[i] = 0.0
                break
            direc = 1.0 if wi < 0.0 else -1.0
            # dz_C = -M_CC^-1 M_Ci dir
            for b in range(k):
                col[b] = M[C[b] * n + i]
            for a in range(k):
                s = 0.0
                for b in range(k):
                    s += Binv[a * n + b] * col[b]
                dz[a] = -s * direc
            if refine:
                for a in range(k):
                    s = col[a] * direc
                    for b in range(k):
                        s += M[C[a] * n + C[b]] * dz[b]
                    rhs[a] = s
                for a in range(k):
                    s = 0.0
                    for b in range(k):
                        s += Binv[a * n + b] * rhs[b]
                    dz[a] -= s
            dmax = 1.0
            for a in range(k):
                if fabs(dz[a]) > dmax:
                    dmax = fabs(dz[a])
            epsz = _DIR_RTOL * dmax
            epsw = _DIR_RTOL * mscale * dmax
            # dw for the driving index and the bounded (non-clamped) processed indices
            tmin = INFINITY
            event = -1
            ev_j = -1
            for j in range(n):
                if j != i and state[j] != S_AT_LOWER and state[j] != S_AT_UPPER:
                    continue
                s = M[j * n + i] * direc
                for b in range(k):
                    s += M[j * n + C[b]] * dz[b]
                dw[j] = s
            # (A) w_i reaches zero
            if dw[i] * direc > epsw:
                tt = -wi / dw[i]
                if tt < 0.0:
                    tt = 0.0
                tmin = tt
                event = 0
            # (B) z_i reaches a bound (preferred on a tie)
            if direc > 0.0 and up[i] < INFINITY:
                tt = up[i] - z[i]
                if tt <= tmin:
                    tmin = max(tt, 0.0)
                    event = 1
            elif direc < 0.0 and lo[i] > -INFINITY:
                tt = z[i] - lo[i]
                if tt <= tmin:
                    tmin = max(tt, 0.0)
                    event = 1
            # (C) a clamped z_j reaches a bound
            for a in range(k):
                j = C[a]
                d = dz[a]
                if d < -epsz and lo[j] > -INFINITY:
                    tt = max(z[j] - lo[j], 0.0) / (-d)
                    if tt < tmin:
                        tmin = tt
                        event = 2
                        ev_j = a
                elif d > epsz and up[j] < INFINITY:
                    tt = max(up[j] - z[j], 0.0) / d
                    if tt < tmin:
                        tmin = tt
                        event = 2
                        ev_j = a
            # (D, E) a bounded w_j reaches zero
            for j in range(n):
                if state[j] == S_AT_LOWER and dw[j] < -epsw:
                    tt = max(w[j], 0.0) / (-dw[j])
                    if tt < tmin:
                        tmin = tt
                        event = 3
                        ev_j = j
                elif state[j] == S_AT_UPPER and dw[j] > epsw:
                    tt = max(-w[j], 0.0) / dw[j]
                    if tt < tmin:
                        tmin = tt
                        event = 3
                        ev_j = j
            if event < 0:
                status = DZ_UNBOUNDED
                break
            # take the step
            for a in range(k):
                z[C[a]] += tmin * dz[a]
            z[i] += tmin * direc
            for j in range(n):
                if j == i or state[j] == S_AT_LOWER or state[j] == S_AT_UPPER:
                    w[j] += tmin * dw[j]
            pivots += 1
            if event == 0:
                if not _add(Binv, n, C, k, M, i, x, y, col2):
                    status = DZ_SINGULAR
                    break
                pos[i] = k
                k += 1
                updates += 1
                state[i] = S_CLAMPED
                w[i] = 0.0
                break
            if event == 1:
                if direc > 0.0:
                    z[i] = up[i]
                    state[i] = S_AT_UPPER
                else:
                    z[i] = lo[i]
                    state[i] = S_AT_LOWER
                break
            if event == 2:
                j = C[ev_j]
                if dz[ev_j] < 0.0:
                    z[j] = lo[j]
                    state[j] = S_AT_LOWER
                else:
                    z[j] = up[j]
                    state[j] = S_AT_UPPER
                # w_j is zero at the moment it leaves the block
                w[j] = 0.0
                _remove(Binv, n, C, pos, k, ev_j)
                pos[j] = -1
                k -= 1
                updates += 1
            elif event == 3:
                j = ev_j
                if not _add(Binv, n, C, k, M, j, x, y, col2):
                    status = DZ_SINGULAR
                    break
                pos[j] = k
                k += 1
                updates += 1
                state[j] = S_CLAMPED
                w[j] = 0.0
            period = refactor_period if refactor_period > 0 else 64 + k
            if updates >= period:
                if _refactor(Binv, n, C, k, M, &space):
                    free(space)
                    free(work)
                    free(iwork)
                    return -1
                updates = 0
            if pivots >= max_piv:
                status = DZ_MAX_ITER
                break
        if status != DZ_OK:
            break
    status_out[0] = status
    pivots_out[0] = pivots
    free(space)
    free(work)
    free(iwork)
    return 0


def dantzig_kernel(M, q, lo, up, order, int64_t max_piv, int64_t refactor_period=0,
                   bint refine=False):
    """Run the method; return (status, z, pivots, state).

    ``refactor_period`` 0: refactorise the block inverse every ``64 + k`` updates (default);
    p > 0: every p updates (1 = refactorisation after every change, for comparison).
    ``refine``: one step of iterative refinement of every direction against ``M[C, C]``
    (off by default, the periodic refactorisation bounds the drift and the caller re-solves
    the final active set).
    """
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef cnp.ndarray la = f64(lo, n, -1)
    cdef cnp.ndarray ua = f64(up, n, -1)
    cdef cnp.ndarray oa = i64(order, n, -1)
    cdef cnp.ndarray z = zeros_f64(n)
    cdef cnp.ndarray state = zeros_i64(n)
    cdef int status = DZ_OK, rc
    cdef int64_t pivots = 0
    if n == 0:
        return status, z, 0, state
    with nogil:
        rc = dantzig(f64_ptr(Ma), f64_ptr(qa), f64_ptr(la), f64_ptr(ua), i64_ptr(oa), n,
                     max_piv, refactor_period, refine, f64_ptr(z), i64_ptr(state), &status,
                     &pivots)
    if rc:
        raise MemoryError()
    return status, z, pivots, state
