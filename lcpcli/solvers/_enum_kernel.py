"""Compiled kernel of the enumeration method (numba, cached on disk, parallel over cones).

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
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

INFEASIBLE = 0
FEASIBLE = 1
SINGULAR_CONSISTENT = 2
PRUNED = 3
SINGULAR_EMPTY = 4

#: Cones handled by one parallel task (scratch arrays are allocated once per block).
BLOCK = 512


@njit(cache=True)
def _complete_pivot_consistent(A, b, k, piv_tol, cons_tol):
    """Gaussian elimination with complete pivoting on the k x k block of A (overwritten).

    Returns True when ``A x = b`` is consistent (remaining right-hand side below cons_tol).
    """
    for p in range(k):
        best = 0.0
        bi = p
        bj = p
        for i in range(p, k):
            for j in range(p, k):
                a = abs(A[i, j])
                if a > best:
                    best = a
                    bi = i
                    bj = j
        if best <= piv_tol:
            for i in range(p, k):  # noqa: SIM110 (numba: plain loop)
                if abs(b[i]) > cons_tol:
                    return False
            return True
        if bi != p:
            for j in range(k):
                t = A[p, j]
                A[p, j] = A[bi, j]
                A[bi, j] = t
            t = b[p]
            b[p] = b[bi]
            b[bi] = t
        if bj != p:
            for i in range(k):
                t = A[i, p]
                A[i, p] = A[i, bj]
                A[i, bj] = t
        piv = A[p, p]
        for i in range(p + 1, k):
            f = A[i, p] / piv
            if f != 0.0:
                for j in range(p + 1, k):
                    A[i, j] -= f * A[p, j]
                b[i] -= f * b[p]
    return True


@njit(cache=True)
def _one_cone(M, q, code, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm, prune_tol,
              idx, A, b, z):
    n = q.shape[0]
    # ---- cheap sign tests (exact zero/sign patterns of M, q beyond the tolerance)
    for i in range(n):
        if q[i] < -prune_tol and (code & pos_mask[i]) == 0:
            return PRUNED
        if q[i] > prune_tol and ((code >> i) & 1) == 1 and (code & neg_mask[i]) == 0:
            return PRUNED
    k = 0
    for j in range(n):
        if (code >> j) & 1:
            idx[k] = j
            k += 1
    if k == 0:
        for i in range(n):
            if q[i] < -feas_rel * qnorm:
                return INFEASIBLE
        return FEASIBLE
    for r in range(k):
        b[r] = -q[idx[r]]
        for c in range(k):
            A[r, c] = M[idx[r], idx[c]]
    # ---- LU with partial pivoting, applied to b on the fly
    singular = False
    for p in range(k):
        best = abs(A[p, p])
        bi = p
        for i in range(p + 1, k):
            a = abs(A[i, p])
            if a > best:
                best = a
                bi = i
        if best <= piv_tol:
            singular = True
            break
        if bi != p:
            for j in range(p, k):
                t = A[p, j]
                A[p, j] = A[bi, j]
                A[bi, j] = t
            t = b[p]
            b[p] = b[bi]
            b[bi] = t
        piv = A[p, p]
        for i in range(p + 1, k):
            f = A[i, p] / piv
            if f != 0.0:
                for j in range(p + 1, k):
                    A[i, j] -= f * A[p, j]
                b[i] -= f * b[p]
    if singular:
        bmax = 0.0
        for r in range(k):
            b[r] = -q[idx[r]]
            bmax = max(bmax, abs(b[r]))
            for c in range(k):
                A[r, c] = M[idx[r], idx[c]]
        cons_tol = 1e-9 * (bmax + piv_tol) * k
        if _complete_pivot_consistent(A, b, k, piv_tol, cons_tol):
            return SINGULAR_CONSISTENT
        return SINGULAR_EMPTY
    # ---- back substitution
    zmax = 0.0
    for p in range(k - 1, -1, -1):
        s = b[p]
        for j in range(p + 1, k):
            s -= A[p, j] * z[j]
        z[p] = s / A[p, p]
        zmax = max(zmax, abs(z[p]))
    tau = feas_rel * (mu * zmax + qnorm)
    for p in range(k):
        if mu * z[p] < -tau:
            return INFEASIBLE
    for i in range(n):
        if (code >> i) & 1:
            continue
        s = q[i]
        for p in range(k):
            s += M[i, idx[p]] * z[p]
        if s < -tau:
            return INFEASIBLE
    return FEASIBLE


@njit(cache=True)
def _classify_range(M, q, start, lo, hi, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                    prune_tol, out):
    n = q.shape[0]
    idx = np.empty(n, dtype=np.int64)
    A = np.empty((n, n))
    b = np.empty(n)
    z = np.empty(n)
    for t in range(lo, hi):
        out[t] = _one_cone(M, q, start + t, pos_mask, neg_mask, piv_tol, feas_rel, mu,
                           qnorm, prune_tol, idx, A, b, z)


@njit(cache=True, parallel=True)
def _classify_parallel(M, q, start, count, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                       prune_tol, out):
    nblocks = (count + BLOCK - 1) // BLOCK
    for blk in prange(nblocks):
        lo = blk * BLOCK
        hi = min(count, lo + BLOCK)
        _classify_range(M, q, start, lo, hi, pos_mask, neg_mask, piv_tol, feas_rel, mu,
                        qnorm, prune_tol, out)


#: Below this many cones one thread does the work (thread start-up costs milliseconds).
SERIAL_BELOW = 8192


def classify_chunk(M, q, start, count, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                   prune_tol, out):
    """Status of the cones ``start .. start + count - 1`` into ``out[0:count]`` (uint8)."""
    if count < SERIAL_BELOW:
        _classify_range(M, q, start, 0, count, pos_mask, neg_mask, piv_tol, feas_rel, mu,
                        qnorm, prune_tol, out)
    else:
        _classify_parallel(M, q, start, count, pos_mask, neg_mask, piv_tol, feas_rel, mu,
                           qnorm, prune_tol, out)
