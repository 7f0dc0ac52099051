"""Compiled kernel of the tableau Lemke method (numba, cached on disk).

The tableau is the *condensed* principal-pivoting tableau of ``w = q + M z + d z0``:
row ``r`` expresses the basic variable ``basic[r]`` as ``qb[r] + T[r, :] @ x_N`` in terms of the
``n + 1`` nonbasic variables ``nonbasic[:]``.  Each pivot is a rank-one update, O(n^2).

Variable codes: ``0..n-1`` are ``w_1..w_n``, ``n..2n-1`` are ``z_1..z_n``, ``2n`` is ``z0``.

Anti-cycling: the lexicographic minimum-ratio rule, i.e. the rule for the perturbed right-hand
side ``q + (eps, eps^2, ..., eps^n)``; the lexicographic key of row ``i`` is row ``i`` of the basis
inverse, read off the tableau (``d qb / d q_k`` is ``e_r`` when ``w_k`` is basic in row ``r`` and
``-T[:, col(w_k)]`` when ``w_k`` is nonbasic).  When ``z0`` ties for leaving it leaves (that
pivot ends the method with a solution).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# status codes returned by the kernel
OK = 0
RAY = 1
MAX_ITER = 2
TRIVIAL = 3  # q >= 0: z = 0 without pivoting


@njit(cache=True)
def _pivot(T, qb, r, c):
    n, m = T.shape
    p = T[r, c]
    inv = 1.0 / p
    rowr = np.empty(m)
    for j in range(m):
        rowr[j] = -T[r, j] * inv
    rowr[c] = inv
    qr = -qb[r] * inv
    for i in range(n):
        if i == r:
            continue
        f = T[i, c]
        if f != 0.0:
            qb[i] += f * qr
            for j in range(m):
                T[i, j] += f * rowr[j]
            T[i, c] = f * inv
    for j in range(m):
        T[r, j] = rowr[j]
    qb[r] = qr


@njit(cache=True)
def _lex_key(T, basic, where, i, k, n):
    """Entry k of row i of the basis inverse (d qb_i / d q_k)."""
    loc = where[k]
    if loc >= 0:
        return 1.0 if loc == i else 0.0
    return -T[i, -loc - 1]


@njit(cache=True)
def ratio_candidates(col, qb, basic, nz, piv_tol, tie_tol, cand):
    """The minimum-ratio test on the entering column ``col`` (basic = qb + col * t).

    Rows with ``col[i] < -piv_tol * max|col|`` block; ``qb`` entries below ``1e-13 max(qb)`` count
    as zero; ratios within ``tie_tol`` (relative) of the minimum tie.  Fills ``cand[:nc]`` with
    the tied rows and returns ``(nc, z0_row, max|col|)``: ``nc = 0`` means no blocking row (a
    ray), ``z0_row >= 0`` is the row of the artificial variable (code ``nz``) when it ties.
    """
    n = qb.shape[0]
    colmax = 0.0
    qmax = 0.0
    for i in range(n):
        a = abs(col[i])
        if a > colmax:
            colmax = a
        if qb[i] > qmax:
            qmax = qb[i]
    ptol = piv_tol * colmax
    ztol = 1e-13 * qmax
    tmin = np.inf
    for i in range(n):
        a = col[i]
        if a < -ptol:
            v = qb[i] if qb[i] > ztol else 0.0
            t = v / (-a)
            if t < tmin:
                tmin = t
    nc = 0
    z0_row = -1
    if tmin == np.inf:
        return nc, z0_row, colmax
    for i in range(n):
        a = col[i]
        if a < -ptol:
            v = qb[i] if qb[i] > ztol else 0.0
            t = v / (-a)
            if t <= tmin + tie_tol * tmin:
                cand[nc] = i
                nc += 1
                if basic[i] == nz:
                    z0_row = i
    return nc, z0_row, colmax


@njit(cache=True)
def lex_unit(col, cand, nc):
    """Scale of an identity entry of the basis inverse over the tied rows: 1 / largest pivot."""
    amax = 0.0
    for s in range(nc):
        a = -col[cand[s]]
        if a > amax:
            amax = a
    return 1.0 / amax


@njit(cache=True)
def keep_lex_min(keys, cand, nc, unit):
    """Keep the candidates whose key is the minimum, within roundoff; return their count.

    Entries equal in exact arithmetic may differ by roundoff, so the comparison carries a
    tolerance with a floor at ``unit``, the scale of an identity entry.
    """
    kmin = np.inf
    kmax = 0.0
    for s in range(nc):
        v = keys[s]
        if v < kmin:
            kmin = v
        if abs(v) > kmax:
            kmax = abs(v)
    m = 0
    for s in range(nc):
        if keys[s] <= kmin + 1e-10 * max(kmax, unit):
            cand[m] = cand[s]
            m += 1
    return m


@njit(cache=True)
def lemke_kernel(M, q, d, max_iter, piv_tol, tie_tol, record):
    """Run Lemke's method; return (status, z, pivots, basic, ray_dz, ray_dz0, z0).

    ``record`` (int64, shape (k, 3)) receives (entering, leaving, row) of the first k pivots.
    """
    n = q.shape[0]
    nz = 2 * n  # code of z0
    T = np.empty((n, n + 1))
    for i in range(n):
        for j in range(n):
            T[i, j] = M[i, j]
        T[i, n] = d[i]
    qb = q.copy()
    basic = np.arange(n)
    nonbasic = np.empty(n + 1, dtype=np.int64)
    for j in range(n + 1):
        nonbasic[j] = n + j
    where = np.empty(2 * n + 1, dtype=np.int64)  # r >= 0 if basic in row r, -(c+1) if nonbasic
    for i in range(n):
        where[i] = i
    for j in range(n + 1):
        where[n + j] = -(j + 1)
    ray_dz = np.zeros(n)
    z = np.zeros(n)

    # initial pivot: z0 enters, the row with the most negative q_i / d_i leaves
    best = 0.0
    for i in range(n):
        v = q[i] / d[i]
        if v < best:
            best = v
    if best >= 0.0:
        return TRIVIAL, z, 0, basic, ray_dz, 0.0, 0.0
    r = -1
    for i in range(n):  # ties: the largest index (the lexicographic rule for q + eps-vector)
        if q[i] / d[i] <= best + tie_tol * abs(best):
            r = i
    entering = nz
    c = n
    leaving = basic[r]
    _pivot(T, qb, r, c)
    basic[r] = entering
    nonbasic[c] = leaving
    where[entering] = r
    where[leaving] = -(c + 1)
    pivots = 1
    if record.shape[0] > 0:
        record[0, 0] = entering
        record[0, 1] = leaving
        record[0, 2] = r
    cand = np.empty(n, dtype=np.int64)
    keys = np.empty(n)
    status = MAX_ITER
    while pivots < max_iter:
        # complement of the variable that just left enters
        entering = leaving + n if leaving < n else leaving - n
        c = -where[entering] - 1
        col = T[:, c]
        nc, z0_row, _ = ratio_candidates(col, qb, basic, nz, piv_tol, tie_tol, cand)
        if nc == 0:
            status = RAY
            break
        if z0_row >= 0:
            r = z0_row
        elif nc == 1:
            r = cand[0]
        else:
            # lexicographic minimum over rows of the basis inverse divided by the pivot element
            unit = lex_unit(col, cand, nc)
            for k in range(n):
                for s in range(nc):
                    i = cand[s]
                    keys[s] = _lex_key(T, basic, where, i, k, n) / (-col[i])
                nc = keep_lex_min(keys, cand, nc, unit)
                if nc == 1:
                    break
            r = cand[0]
        leaving = basic[r]
        _pivot(T, qb, r, c)
        basic[r] = entering
        nonbasic[c] = leaving
        where[entering] = r
        where[leaving] = -(c + 1)
        if pivots < record.shape[0]:
            record[pivots, 0] = entering
            record[pivots, 1] = leaving
            record[pivots, 2] = r
        pivots += 1
        if leaving == nz:
            status = OK
            break

    z0, dz0 = basic_solution(basic, qb, T[:, c], entering, status == RAY, z, ray_dz)
    return status, z, pivots, basic, ray_dz, dz0, z0


@njit(cache=True)
def basic_solution(basic, qb, col, entering, ray, z, ray_dz):
    """Read z (and, on a ray, its direction) off the final basis; return (z0, dz0).

    ``col`` is the entering column: on a ray the entering variable grows at rate 1 and the
    basic variables at ``col``.  Codes as in the module docstring (``z0`` is ``2n``).
    """
    n = qb.shape[0]
    nz = 2 * n
    z0 = 0.0
    dz0 = 0.0
    for i in range(n):
        b = basic[i]
        if n <= b < nz:
            z[b - n] = qb[i]
        elif b == nz:
            z0 = qb[i]
    if ray:
        if n <= entering < nz:
            ray_dz[entering - n] = 1.0
        for i in range(n):
            b = basic[i]
            if n <= b < nz:
                ray_dz[b - n] = col[i]
            elif b == nz:
                dz0 = col[i]
    return z0, dz0


@njit(cache=True)
def _min_residual(M, q, z):
    n = q.shape[0]
    worst = 0.0
    for i in range(n):
        w = q[i]
        for j in range(n):
            w += M[i, j] * z[j]
        v = abs(min(z[i], w))
        if v > worst:
            worst = v
    return worst


@njit(cache=True)
def polish_kernel(M, q, z, basic):
    """Re-solve the final basis ``M[b, b] z_b = -q_b`` by LU with one refinement step.

    Returns the better (by ``||min(z, Mz + q)||_inf``) of the tableau answer and the re-solve.
    """
    n = q.shape[0]
    zt = np.maximum(z, 0.0)
    m = 0
    for i in range(n):
        if n <= basic[i] < 2 * n:
            m += 1
    if m == 0:
        return zt
    b = np.empty(m, dtype=np.int64)
    k = 0
    for i in range(n):
        if n <= basic[i] < 2 * n:
            b[k] = basic[i] - n
            k += 1
    b.sort()
    A = np.empty((m, m))
    rhs = np.empty(m)
    for i in range(m):
        rhs[i] = -q[b[i]]
        for j in range(m):
            A[i, j] = M[b[i], b[j]]
    zb = np.linalg.solve(A, rhs)
    res = rhs - A @ zb
    zb = zb + np.linalg.solve(A, res)
    zc = np.zeros(n)
    for i in range(m):
        zc[b[i]] = max(zb[i], 0.0)
    for i in range(n):
        if not np.isfinite(zc[i]):
            return zt
    if _min_residual(M, q, zc) <= _min_residual(M, q, zt):
        return zc
    return zt
