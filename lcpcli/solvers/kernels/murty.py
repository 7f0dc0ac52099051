"""Compiled kernel of Murty's least-index principal pivoting method (numba, cached on disk).

The condensed principal-pivoting tableau of ``w = M z + q`` (as in :mod:`._lemke_kernel`, without
the artificial column): row ``i`` always holds one variable of the pair ``(w_i, z_i)`` as
``qb[i] + T[i, :] @ x_N``, and its complement is the nonbasic variable of column ``i``, so a
principal pivot on ``(i, i)`` exchanges ``w_i`` and ``z_i`` (O(n^2), rank-one update).

Variable codes: ``0..n-1`` are ``w_1..w_n``, ``n..2n-1`` are ``z_1..z_n``.

Status codes: 0 solved (all basic values >= 0), 1 pivot limit, 2 non-positive pivot (the matrix is
not a P-matrix: a principal pivot transform of a P-matrix has a positive diagonal).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lcpcli.solvers.kernels.lemke import _pivot

OK = 0
LIMIT = 1
BAD_PIVOT = 2


@njit(cache=True)
def murty_kernel(M, q, max_iter, piv_tol, neg_tol, basic):
    """Run the least-index rule from the complementary basis ``basic`` (codes, updated in place).

    Returns (status, z, pivots, failing row).
    """
    n = q.shape[0]
    T = M.copy()
    qb = q.copy()
    # pivot the starting basis in (principal pivots on the rows whose z is basic)
    for i in range(n):
        if basic[i] >= n:
            basic[i] = i
            if abs(T[i, i]) <= piv_tol:
                z = np.zeros(n)
                return BAD_PIVOT, z, 0, i
            _pivot(T, qb, i, i)
            basic[i] = n + i
    qscale = 0.0
    for i in range(n):
        if abs(q[i]) > qscale:
            qscale = abs(q[i])
    pivots = 0
    status = LIMIT
    bad = -1
    while pivots < max_iter:
        r = -1
        for i in range(n):
            if qb[i] < -neg_tol * qscale:
                r = i
                break
        if r < 0:
            status = OK
            break
        p = T[r, r]
        scale = 0.0
        for j in range(n):
            if abs(T[r, j]) > scale:
                scale = abs(T[r, j])
        if not p > piv_tol * max(scale, 1e-300):
            status = BAD_PIVOT
            bad = r
            break
        _pivot(T, qb, r, r)
        basic[r] = n + r if basic[r] < n else r
        pivots += 1
    z = np.zeros(n)
    for i in range(n):
        if basic[i] >= n:
            z[i] = max(qb[i], 0.0)
    return status, z, pivots, bad
