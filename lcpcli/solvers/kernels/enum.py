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

CANDIDATE = 5
#: Relative threshold of a pivot against the largest entry of its row and column.
PIVOT_THRESHOLD = 1e-6
#: Loose relative tolerance of the leaf test (candidates are re-checked strictly).
LOOSE_RTOL = 1e-6
#: A tableau entry beyond this multiple of the base scale triggers the direct path.
GROWTH_LIMIT = 1e8


@njit(cache=True)
def _ppt_pivot(Ts, qs, Td, qd, d, n, base):
    """Principal pivot of (Ts, qs) on index d into (Td, qd), columns 0..d-1 only.

    Returns False (nothing usable written) when the pivot fails the threshold or growth test.
    """
    p = Ts[d, d]
    big = 0.0
    for i in range(n):
        a = abs(Ts[i, d])
        if a > big:
            big = a
    for j in range(d):
        a = abs(Ts[d, j])
        if a > big:
            big = a
    if p == 0.0 or abs(p) < PIVOT_THRESHOLD * big:
        return False
    inv = 1.0 / p
    qdp = qs[d] * inv
    limit = GROWTH_LIMIT * base
    for i in range(n):
        if i == d:
            continue
        f = Ts[i, d] * inv
        qd[i] = qs[i] - f * qs[d]
        for j in range(d):
            v = Ts[i, j] - f * Ts[d, j]
            if abs(v) > limit:
                return False
            Td[i, j] = v
    for j in range(d):
        Td[d, j] = -Ts[d, j] * inv
    qd[d] = -qdp
    return True


@njit(cache=True)
def _leaf(qv, code, n, mu, qnorm, loose):
    zmax = 0.0
    for i in range(n):
        if (code >> i) & 1:
            a = abs(qv[i])
            if a > zmax:
                zmax = a
    tau = loose * (mu * zmax + qnorm)
    for i in range(n):
        v = qv[i] * mu if (code >> i) & 1 else qv[i]
        if v < -tau:
            return INFEASIBLE
    return CANDIDATE


@njit(cache=True)
def _ppt_block(M, q, start, k, out, off, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
               prune_tol, base):
    """Classify the aligned block ``start .. start + 2^k - 1`` into ``out[off:off + 2^k]``."""
    n = q.shape[0]
    idx = np.empty(n, dtype=np.int64)
    A = np.empty((n, n))
    b = np.empty(n)
    z = np.empty(n)
    T = np.empty((k + 1, n, n))
    Q = np.empty((k + 1, n))
    tmpT = np.empty((n, n))
    tmpQ = np.empty(n)
    # root: pivot (M, q) on the fixed high bits of start, highest first
    for i in range(n):
        Q[0, i] = q[i]
        for j in range(n):
            T[0, i, j] = M[i, j]
    ok = True
    for d in range(n - 1, k - 1, -1):
        if (start >> d) & 1:
            if not _ppt_pivot(T[0], Q[0], tmpT, tmpQ, d, n, base):
                ok = False
                break
            for i in range(n):
                Q[0, i] = tmpQ[i]
                for j in range(d):
                    T[0, i, j] = tmpT[i, j]
    if not ok:
        for t in range(1 << k):
            out[off + t] = _one_cone(M, q, start + t, pos_mask, neg_mask, piv_tol, feas_rel,
                                     mu, qnorm, prune_tol, idx, A, b, z)
        return
    slot = np.zeros(k + 1, dtype=np.int64)
    choice = np.full(k + 1, -1, dtype=np.int64)
    low = 0
    level = 0
    while level >= 0:
        if level == k:
            out[off + low] = _leaf(Q[slot[level]], start + low, n, mu, qnorm, LOOSE_RTOL)
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
        low |= 1 << d
        s = slot[level]
        if _ppt_pivot(T[s], Q[s], T[level + 1], Q[level + 1], d, n, base):
            slot[level + 1] = level + 1
            level += 1
        else:  # direct path for the whole subtree of this z-choice
            for t in range(1 << d):
                out[off + low + t] = _one_cone(M, q, start + low + t, pos_mask, neg_mask,
                                               piv_tol, feas_rel, mu, qnorm, prune_tol, idx,
                                               A, b, z)


@njit(cache=True, parallel=True)
def _ppt_parallel(M, q, start, k, sub, out, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                  prune_tol, base):
    ntasks = 1 << (k - sub)
    for task in prange(ntasks):
        _ppt_block(M, q, start + (task << sub), sub, out, task << sub, pos_mask, neg_mask,
                   piv_tol, feas_rel, mu, qnorm, prune_tol, base)


#: Sub-block size (bits) of one parallel task of the fast path.
TASK_BITS = 12


def classify_chunk_fast(M, q, start, count, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                        prune_tol, out):
    """Like :func:`classify_chunk`, by depth-first principal pivoting where it is safe.

    ``count`` must be a power of two and ``start`` a multiple of it; the statuses are those of
    :func:`classify_chunk` except that feasible cones come back as CANDIDATE (re-check them
    with :func:`classify_chunk` on that single code).
    """
    k = count.bit_length() - 1
    if count != 1 << k or start % count:
        raise ValueError("classify_chunk_fast needs an aligned power-of-two block")
    base = max(float(np.max(np.abs(M))), 1.0 / max(float(np.max(np.abs(M))), 1e-300), 1.0)
    sub = min(k, TASK_BITS)
    if k == sub:
        _ppt_block(M, q, start, k, out, 0, pos_mask, neg_mask, piv_tol, feas_rel, mu, qnorm,
                   prune_tol, base)
    else:
        _ppt_parallel(M, q, start, k, sub, out, pos_mask, neg_mask, piv_tol, feas_rel, mu,
                      qnorm, prune_tol, base)
