"""Compiled kernel of the revised Lemke method (numba, cached on disk).

The engine is seed 000's principal pivoting transform: with ``Maug = [M, d]`` (``n x (n+1)``),
``alpha`` the nonbasic w's, ``beta`` the basic z's (``z0`` is index ``n``) and
``A = Maug[alpha, beta]`` (``m x m``), the kernel keeps ``B = A^{-1}`` explicitly and
*updates* it at every pivot in O(m^2), one formula per case:

* z_j enters, w_i leaves: ``A`` gains row ``i`` and column ``j`` (bordering, Schur complement);
* z_j enters, z_l leaves: column ``l`` of ``A`` is replaced by column ``j`` (Sherman-Morrison);
* w_k enters, w_i leaves: row ``k`` of ``A`` is replaced by row ``i`` (Sherman-Morrison);
* w_k enters, z_l leaves: row ``k`` and column ``l`` are removed (inverse of a Schur complement).

The entering column is computed by seed eqs (5)-(6) (w enters) or (7)-(8) (z enters) in
O(n m); ``q'`` is updated along the ray of the pivot and recomputed by eqs (2)-(3) after every
refactorisation.  ``B`` is recomputed from scratch (``inv(A)``) every ``refactor_every`` pivots
and whenever a pivot is small relative to its column (an unstable update).

Instability is detected a posteriori: every ``CHECK_EVERY`` pivots the entering column's
beta part is substituted back into ``M^{alpha beta} x = rhs``; a relative residual above
``RESID_TOL`` triggers a refactorisation before the column is used.

The pivot rule is the tableau kernel's (:mod:`lcpcli.solvers.kernels.lemke`): same initial
pivot, same lexicographic minimum-ratio test with the same tolerances, ``z0`` preferred on ties.
Variable codes: ``0..n-1`` = ``w_1..w_n``, ``n..2n-1`` = ``z_1..z_n``, ``2n`` = ``z0``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lcpcli.solvers.kernels.lemke import (
    basic_solution,
    keep_lex_min,
    lex_unit,
    ratio_candidates,
)

OK = 0
RAY = 1
MAX_ITER = 2
TRIVIAL = 3
SINGULAR = 4

#: A pivot smaller than this fraction of its column's largest entry triggers a refactorisation.
SMALL_PIVOT = 1e-7
#: At a refactorisation, q' entries that moved less than this (relative) keep their value.
DRIFT_TOL = 1e-9
#: Every CHECK_EVERY pivots the entering column is checked against M^{alpha beta} ...
CHECK_EVERY = 8
#: ... and a relative residual above RESID_TOL triggers a refactorisation.
RESID_TOL = 1e-9


@njit(cache=True)
def _refactor(MT, alpha, beta, m, B):
    """B[:m, :m] = inv(Maug[alpha, beta]); False when singular or non-finite."""
    if m == 0:
        return True
    A = np.empty((m, m))
    for p in range(m):
        for s in range(m):
            A[p, s] = MT[beta[s], alpha[p]]
    Ainv = np.linalg.inv(A)
    for s in range(m):
        for p in range(m):
            v = Ainv[s, p]
            if not np.isfinite(v):
                return False
            B[s, p] = v
    return True


@njit(cache=True)
def _combine_rows(Ct, xb, m, n, tmp):
    """``tmp[:n] = sum_s xb[s] * Ct[s, :n]`` (M[:, beta] times the beta part)."""
    for i in range(n):
        tmp[i] = 0.0
    for s in range(m):
        x = xb[s]
        if x != 0.0:
            for i in range(n):
                tmp[i] += Ct[s, i] * x


@njit(cache=True)
def _q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp):
    """q' by seed eqs (2)-(3), in row order."""
    for s in range(m):
        acc = 0.0
        for p in range(m):
            acc += B[s, p] * q[alpha[p]]
        xb[s] = -acc
    _combine_rows(Ct, xb, m, n, tmp)
    for r in range(n):
        b = basic[r]
        if b < n:
            qb[r] = q[b] + tmp[b]
    for s in range(m):
        qb[where[n + beta[s]]] = xb[s]


@njit(cache=True)
def _column(MT, alpha, beta, apos, m, B, Ct, basic, where, n, e, col, xb, tmp):
    """Column of M' for entering code ``e``, row order (eqs 5-6 or 7-8); xb = its beta part."""
    if e < n:
        p = apos[e]
        for s in range(m):
            xb[s] = B[s, p]
    else:
        j = e - n
        for p in range(m):
            tmp[p] = MT[j, alpha[p]]
        for s in range(m):
            xb[s] = -_dot(B, s, tmp, m)
    _combine_rows(Ct, xb, m, n, tmp)
    for r in range(n):
        b = basic[r]
        if b < n:
            col[r] = tmp[b] + (MT[e - n, b] if e >= n else 0.0)
    for s in range(m):
        col[where[n + beta[s]]] = xb[s]


@njit(cache=True)
def _fresh_q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp, old):
    """q' by eqs (2)-(3) after a refactorisation; entries that moved only at roundoff level
    keep their updated value, so degenerate zeros stay exact zeros (the lexicographic rule then
    sees the same degeneracy as before, as the tableau method does)."""
    for i in range(n):
        old[i] = qb[i]
    _q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp)
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(old[i]), abs(q[i]))
    for i in range(n):
        if abs(qb[i] - old[i]) <= DRIFT_TOL * scale:
            qb[i] = old[i]


@njit(cache=True)
def _column_residual(MT, Ct, alpha, apos, m, e, n, xb, acc, size):
    """Relative residual of the beta part of the entering column: ``A xb = rhs`` with
    ``A = Maug[alpha, beta]`` and rhs ``e_gamma`` (w enters) or ``-g^alpha`` (z enters).
    ``acc`` and ``size`` are work vectors of length >= m."""
    for p in range(m):
        rhs = (1.0 if apos[e] == p else 0.0) if e < n else -MT[e - n, alpha[p]]
        acc[p] = -rhs
        size[p] = abs(rhs)
    for s in range(m):
        x = xb[s]
        for p in range(m):
            t = Ct[s, alpha[p]] * x
            acc[p] += t
            size[p] += abs(t)
    worst = 0.0
    for p in range(m):
        if size[p] > 0.0:
            rel = abs(acc[p]) / size[p]
            if rel > worst:
                worst = rel
    return worst


@njit(cache=True)
def _dot(B, s, v, m):
    """sum_p B[s, p] v[p] with four partial sums (lets the compiler use SIMD lanes)."""
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    p = 0
    while p + 4 <= m:
        a0 += B[s, p] * v[p]
        a1 += B[s, p + 1] * v[p + 1]
        a2 += B[s, p + 2] * v[p + 2]
        a3 += B[s, p + 3] * v[p + 3]
        p += 4
    while p < m:
        a0 += B[s, p] * v[p]
        p += 1
    return (a0 + a1) + (a2 + a3)


@njit(cache=True)
def _row_times_B(Ct, B, m, i, out):
    """out[:m] = Maug[i, beta] @ B (row access of B only)."""
    for p in range(m):
        out[p] = 0.0
    for s in range(m):
        c = Ct[s, i]
        if c != 0.0:
            for p in range(m):
                out[p] += c * B[s, p]


@njit(cache=True)
def _wcol_entry(bpos, apos, m, B, Ct, basic, n, k, r):
    """Entry at row r of the column of the nonbasic w_k (for the lexicographic keys)."""
    p = apos[k]
    b = basic[r]
    if b >= n:  # a z row (z0 included): B[s, p] with s the beta position of that z
        return B[bpos[b - n], p]
    acc = 0.0
    for s in range(m):
        acc += Ct[s, b] * B[s, p]
    return acc


@njit(cache=True)
def lemke_revised_kernel(M, q, d, max_iter, piv_tol, tie_tol, record, refactor_every):
    """Revised Lemke; return (status, z, pivots, basic, ray_dz, ray_dz0, z0, refactors).

    ``record`` (int64, shape (k, 3)) receives (entering, leaving, row) of the first k pivots.
    """
    n = q.shape[0]
    nz = 2 * n
    # MT = [M, d]^T, so that a column of [M, d] is a contiguous row (blocked transpose)
    MT = np.empty((n + 1, n))
    blk = 32
    for i0 in range(0, n, blk):
        for j0 in range(0, n, blk):
            for i in range(i0, min(i0 + blk, n)):
                for j in range(j0, min(j0 + blk, n)):
                    MT[j, i] = M[i, j]
    for i in range(n):
        MT[n, i] = d[i]
    basic = np.arange(n)
    where = np.full(2 * n + 1, -1, dtype=np.int64)
    for i in range(n):
        where[i] = i
    alpha = np.empty(n, dtype=np.int64)
    beta = np.empty(n, dtype=np.int64)
    apos = np.full(n, -1, dtype=np.int64)
    bpos = np.full(n + 1, -1, dtype=np.int64)
    B = np.empty((n, n))
    Ct = np.empty((n, n))  # Ct[s, :] = Maug[:, beta[s]]
    qb = q.copy()
    col = np.empty(n)
    xb = np.empty(n)
    tmp = np.empty(n)
    w1 = np.empty(n)
    w2 = np.empty(n)
    ray_dz = np.zeros(n)
    z = np.zeros(n)
    refactors = 0

    best = 0.0
    for i in range(n):
        v = q[i] / d[i]
        if v < best:
            best = v
    if best >= 0.0:
        return TRIVIAL, z, 0, basic, ray_dz, 0.0, 0.0, refactors
    r = -1
    for i in range(n):
        if q[i] / d[i] <= best + tie_tol * abs(best):
            r = i
    # initial pivot: z0 enters, w_r leaves: A = [d_r]
    m = 1
    alpha[0] = r
    apos[r] = 0
    beta[0] = n
    bpos[n] = 0
    B[0, 0] = 1.0 / d[r]
    for i in range(n):
        Ct[0, i] = d[i]
    entering = nz
    leaving = r
    basic[r] = nz
    where[nz] = r
    where[r] = -1
    _q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp)
    pivots = 1
    since = 0
    if record.shape[0] > 0:
        record[0, 0] = entering
        record[0, 1] = leaving
        record[0, 2] = r
    cand = np.empty(n, dtype=np.int64)
    keys = np.empty(n)
    status = MAX_ITER
    while pivots < max_iter:
        entering = leaving + n if leaving < n else leaving - n
        _column(MT, alpha, beta, apos, m, B, Ct, basic, where, n, entering, col, xb, tmp)
        if pivots % CHECK_EVERY == 0 and _column_residual(MT, Ct, alpha, apos, m, entering,
                                                          n, xb, w1, w2) > RESID_TOL:
            # the updated inverse has drifted: refactorise before using the column
            if not _refactor(MT, alpha, beta, m, B):
                status = SINGULAR
                break
            _fresh_q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp, w2)
            refactors += 1
            since = 0
            _column(MT, alpha, beta, apos, m, B, Ct, basic, where, n, entering, col, xb, tmp)
        nc, z0_row, colmax = ratio_candidates(col, qb, basic, nz, piv_tol, tie_tol, cand)
        if nc == 0:
            status = RAY
            break
        if z0_row >= 0:
            r = z0_row
        elif nc == 1:
            r = cand[0]
        else:
            unit = lex_unit(col, cand, nc)
            for k in range(n):
                loc = where[k]
                for s in range(nc):
                    i = cand[s]
                    if loc >= 0:
                        key = 1.0 if loc == i else 0.0
                    else:
                        key = -_wcol_entry(bpos, apos, m, B, Ct, basic, n, k, i)
                    keys[s] = key / (-col[i])
                nc = keep_lex_min(keys, cand, nc, unit)
                if nc == 1:
                    break
            r = cand[0]
        leaving = basic[r]
        piv = col[r]
        # q' along the pivot: the entering variable rises to qr
        qr = -qb[r] / piv
        for i in range(n):
            if i != r:
                qb[i] += col[i] * qr
        qb[r] = qr
        # update B = inv(Maug[alpha, beta]) for the four cases
        if entering >= n and leaving < n:  # z_j in, w_i out: border
            j = entering - n
            i_out = leaving
            # Bu = -xb ; vB[p] = sum_s Maug[i, beta[s]] B[s, p]
            _row_times_B(Ct, B, m, i_out, w1)
            inv = 1.0 / piv
            for s in range(m):
                bu = -xb[s]
                f = bu * inv
                for p in range(m):
                    B[s, p] += f * w1[p]
                B[s, m] = -f
            for p in range(m):
                B[m, p] = -w1[p] * inv
            B[m, m] = inv
            alpha[m] = i_out
            apos[i_out] = m
            beta[m] = j
            bpos[j] = m
            for i in range(n):
                Ct[m, i] = MT[j, i]
            m += 1
        elif entering >= n:  # z_j in, z_l out: replace column
            j = entering - n
            l_out = leaving - n
            s0 = bpos[l_out]
            y0 = -xb[s0]
            for p in range(m):
                B[s0, p] /= y0
            for s in range(m):
                if s != s0:
                    f = -xb[s]
                    if f != 0.0:
                        for p in range(m):
                            B[s, p] -= f * B[s0, p]
            beta[s0] = j
            bpos[l_out] = -1
            bpos[j] = s0
            for i in range(n):
                Ct[s0, i] = MT[j, i]
        elif leaving < n:  # w_k in, w_i out: replace row
            k = entering
            i_out = leaving
            p0 = apos[k]
            _row_times_B(Ct, B, m, i_out, w1)
            x0 = w1[p0]
            for s in range(m):
                B[s, p0] /= x0
            w1[p0] = 0.0
            for s in range(m):
                bsp = B[s, p0]
                if bsp != 0.0:
                    for p in range(m):
                        B[s, p] -= w1[p] * bsp
            alpha[p0] = i_out
            apos[k] = -1
            apos[i_out] = p0
        else:  # w_k in, z_l out: remove row and column
            k = entering
            l_out = leaving - n
            p0 = apos[k]
            s0 = bpos[l_out]
            bsp = B[s0, p0]
            for p in range(m):
                w2[p] = B[s0, p] / bsp
            for s in range(m):
                if s != s0:
                    f = B[s, p0]
                    if f != 0.0:
                        for p in range(m):
                            B[s, p] -= f * w2[p]
            last = m - 1
            # move the last row into s0 and the last column into p0
            if s0 != last:
                for p in range(m):
                    B[s0, p] = B[last, p]
                beta[s0] = beta[last]
                bpos[beta[s0]] = s0
                for i in range(n):
                    Ct[s0, i] = Ct[last, i]
            if p0 != last:
                for s in range(m):
                    B[s, p0] = B[s, last]
                alpha[p0] = alpha[last]
                apos[alpha[p0]] = p0
            apos[k] = -1
            bpos[l_out] = -1
            m -= 1
        basic[r] = entering
        where[entering] = r
        where[leaving] = -1
        if pivots < record.shape[0]:
            record[pivots, 0] = entering
            record[pivots, 1] = leaving
            record[pivots, 2] = r
        pivots += 1
        since += 1
        if leaving == nz:
            status = OK
            break
        if since >= refactor_every or abs(piv) < SMALL_PIVOT * colmax:
            if not _refactor(MT, alpha, beta, m, B):
                status = SINGULAR
                break
            _fresh_q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp, w2)
            refactors += 1
            since = 0

    if status == OK:  # final values by eqs (2)-(3) (the caller polishes them by LU)
        _q_prime(MT, q, alpha, beta, m, B, Ct, basic, where, n, qb, xb, tmp)
    z0, dz0 = basic_solution(basic, qb, col, entering, status == RAY, z, ray_dz)
    return status, z, pivots, basic, ray_dz, dz0, z0, refactors
