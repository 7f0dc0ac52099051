"""Compiled kernels of projected Gauss-Seidel / SOR (numba, cached on disk).

One sweep updates ``z_i <- proj_[lo_i, up_i](z_i - omega * r_i / M_ii)`` for i = 0..n-1 in order,
with ``r_i = (M z + q)_i`` evaluated at the current (partly updated) z.  The stopping test is the
certificate's scaled error; during a sweep it is *estimated* from ``w_i ~ r_i + M_ii dz_i``, and
only when the estimate is below ``tol / 2`` is the exact error computed (one more product
``M z``), so the exact check costs about one sweep and runs rarely.

Status codes: 0 converged (exact scaled error <= tol), 1 iteration limit, 2 non-finite iterate.
"""

from __future__ import annotations

import numpy as np
from numba import njit

CONVERGED = 0
LIMIT = 1
DIVERGED = 2


@njit(cache=True)
def _err(z, w, lo, up, mu, qnorm):
    num = 0.0
    zmax = 0.0
    for i in range(z.shape[0]):
        r = min(mu * (z[i] - lo[i]), w[i])
        r2 = mu * (z[i] - up[i])
        if r2 > r:
            r = r2
        if abs(r) > num:
            num = abs(r)
        if abs(z[i]) > zmax:
            zmax = abs(z[i])
    if num == 0.0:
        return 0.0
    den = mu * zmax + qnorm
    if den <= 0.0:
        return np.inf
    return num / den


@njit(cache=True)
def _dense_w(M, q, z, w):
    n = q.shape[0]
    for i in range(n):
        s = q[i]
        for j in range(n):
            s += M[i, j] * z[j]
        w[i] = s


@njit(cache=True)
def _csr_w(indptr, indices, data, q, z, w):
    n = q.shape[0]
    for i in range(n):
        s = q[i]
        for k in range(indptr[i], indptr[i + 1]):
            s += data[k] * z[indices[k]]
        w[i] = s


@njit(cache=True)
def _update(i, r, z, diag, lo, up, omega, mu):
    """Update z_i; return (new z_i, estimated scaled residual component)."""
    zi = z[i]
    znew = zi - omega * r / diag[i]
    if znew < lo[i]:
        znew = lo[i]
    if znew > up[i]:
        znew = up[i]
    z[i] = znew
    wi = r + diag[i] * (znew - zi)
    rc = min(mu * (znew - lo[i]), wi)
    r2 = mu * (znew - up[i])
    if r2 > rc:
        rc = r2
    return znew, abs(rc)


@njit(cache=True)
def pgs_dense(M, q, diag, lo, up, z, omega, max_iter, tol, mu, qnorm):
    """PGS/PSOR on a dense M; ``z`` is updated in place. Returns (status, sweeps, error)."""
    n = q.shape[0]
    w = np.empty(n)
    gap = 1
    next_check = 1
    err = np.inf
    for it in range(1, max_iter + 1):
        est = 0.0
        zmax = 0.0
        for i in range(n):
            r = q[i]
            for j in range(n):
                r += M[i, j] * z[j]
            znew, rc = _update(i, r, z, diag, lo, up, omega, mu)
            if rc > est:
                est = rc
            if abs(znew) > zmax:
                zmax = abs(znew)
        if not np.isfinite(est) or not np.isfinite(zmax):
            return DIVERGED, it, np.inf
        if it >= next_check and est <= 0.5 * tol * (mu * zmax + qnorm):
            _dense_w(M, q, z, w)
            err = _err(z, w, lo, up, mu, qnorm)
            if err <= tol:
                return CONVERGED, it, err
            gap = min(2 * gap, 32)
            next_check = it + gap
    _dense_w(M, q, z, w)
    return LIMIT, max_iter, _err(z, w, lo, up, mu, qnorm)


@njit(cache=True)
def pgs_csr(indptr, indices, data, q, diag, lo, up, z, omega, max_iter, tol, mu, qnorm):
    """PGS/PSOR on a CSR matrix (the diagonal entry is included in the row product)."""
    n = q.shape[0]
    w = np.empty(n)
    gap = 1
    next_check = 1
    err = np.inf
    for it in range(1, max_iter + 1):
        est = 0.0
        zmax = 0.0
        for i in range(n):
            r = q[i]
            for k in range(indptr[i], indptr[i + 1]):
                r += data[k] * z[indices[k]]
            znew, rc = _update(i, r, z, diag, lo, up, omega, mu)
            if rc > est:
                est = rc
            if abs(znew) > zmax:
                zmax = abs(znew)
        if not np.isfinite(est) or not np.isfinite(zmax):
            return DIVERGED, it, np.inf
        if it >= next_check and est <= 0.5 * tol * (mu * zmax + qnorm):
            _csr_w(indptr, indices, data, q, z, w)
            err = _err(z, w, lo, up, mu, qnorm)
            if err <= tol:
                return CONVERGED, it, err
            gap = min(2 * gap, 32)
            next_check = it + gap
    _csr_w(indptr, indices, data, q, z, w)
    return LIMIT, max_iter, _err(z, w, lo, up, mu, qnorm)
