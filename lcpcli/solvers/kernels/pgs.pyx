# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled kernels of projected Gauss-Seidel / SOR (Cython, ``nogil``).

One sweep updates ``z_i <- proj_[lo_i, up_i](z_i - omega * r_i / M_ii)`` for i = 0..n-1 in order,
with ``r_i = (M z + q)_i`` evaluated at the current (partly updated) z.  The stopping test is a
normwise scaled error ``||mid(mu (z - lo), mu (z - up), w)||_inf / (mu ||z||_inf + ||q||_inf)``
(the caller tightens ``tol`` until the componentwise certificate passes); during a sweep it is
*estimated* from ``w_i ~ r_i + M_ii dz_i``, and
only when the estimate is below ``tol / 2`` is the exact error computed (one more product
``M z``), so the exact check costs about one sweep and runs rarely.

Status codes: 0 converged (exact normwise error <= tol), 1 iteration limit, 2 non-finite iterate.

C level: :c:func:`pgs_sweeps` runs either storage (dense row-major, or CSR when ``indptr`` is
not NULL) on raw buffers without the GIL.
"""

from libc.math cimport INFINITY, fabs, isfinite
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc

cimport numpy as cnp

from lcpcli.core.arrays cimport (
    f64,
    f64_ptr,
    i64,
    i64_ptr,
    inout,
)

cnp.import_array()

CONVERGED = PGS_CONVERGED
LIMIT = PGS_LIMIT
DIVERGED = PGS_DIVERGED


cdef double _scaled_error(const double* z, const double* w, const double* lo,
                         const double* up, Py_ssize_t n, double mu,
                         double qnorm) noexcept nogil:
    cdef Py_ssize_t i
    cdef double r, r2, num = 0.0, zmax = 0.0, den
    for i in range(n):
        r = mu * (z[i] - lo[i])
        if w[i] < r:
            r = w[i]
        r2 = mu * (z[i] - up[i])
        if r2 > r:
            r = r2
        if fabs(r) > num:
            num = fabs(r)
        if fabs(z[i]) > zmax:
            zmax = fabs(z[i])
    if num == 0.0:
        return 0.0
    den = mu * zmax + qnorm
    if den <= 0.0:
        return INFINITY
    return num / den


cdef inline double _row(const double* M, const int64_t* indptr, const int64_t* indices,
                        const double* data, const double* q, const double* z, Py_ssize_t n,
                        Py_ssize_t i) noexcept nogil:
    """``(M z + q)_i`` for dense (``indptr`` NULL) or CSR storage."""
    cdef double s = q[i]
    cdef Py_ssize_t j
    cdef int64_t k
    cdef const double* Mi
    if indptr == NULL:
        Mi = M + i * n
        for j in range(n):
            s += Mi[j] * z[j]
    else:
        for k in range(indptr[i], indptr[i + 1]):
            s += data[k] * z[indices[k]]
    return s


cdef int pgs_sweeps(const double* M, const int64_t* indptr, const int64_t* indices,
                    const double* data, const double* q, const double* diag, const double* lo,
                    const double* up, double* z, Py_ssize_t n, double omega, int64_t max_iter,
                    double tol, double mu, double qnorm, int64_t* sweeps,
                    double* err_out) noexcept nogil:
    """PGS/PSOR; ``z`` is updated in place.  Returns the status (-1: out of memory)."""
    cdef Py_ssize_t i
    cdef int64_t it, gap = 1, next_check = 1
    cdef double est, zmax, r, zi, znew, wi, rc, r2, err
    cdef double* w = <double*>malloc((n + 1) * sizeof(double))
    if w == NULL:
        return -1
    for it in range(1, max_iter + 1):
        est = 0.0
        zmax = 0.0
        for i in range(n):
            r = _row(M, indptr, indices, data, q, z, n, i)
            # update z_i; estimate its scaled residual component
            zi = z[i]
            znew = zi - omega * r / diag[i]
            if znew < lo[i]:
                znew = lo[i]
            if znew > up[i]:
                znew = up[i]
            z[i] = znew
            wi = r + diag[i] * (znew - zi)
            rc = mu * (znew - lo[i])
            if wi < rc:
                rc = wi
            r2 = mu * (znew - up[i])
            if r2 > rc:
                rc = r2
            if fabs(rc) > est:
                est = fabs(rc)
            if fabs(znew) > zmax:
                zmax = fabs(znew)
        if not isfinite(est) or not isfinite(zmax):
            sweeps[0] = it
            err_out[0] = INFINITY
            free(w)
            return PGS_DIVERGED
        if it >= next_check and est <= 0.5 * tol * (mu * zmax + qnorm):
            for i in range(n):
                w[i] = _row(M, indptr, indices, data, q, z, n, i)
            err = _scaled_error(z, w, lo, up, n, mu, qnorm)
            if err <= tol:
                sweeps[0] = it
                err_out[0] = err
                free(w)
                return PGS_CONVERGED
            gap = min(2 * gap, 32)
            next_check = it + gap
    for i in range(n):
        w[i] = _row(M, indptr, indices, data, q, z, n, i)
    sweeps[0] = max_iter
    err_out[0] = _scaled_error(z, w, lo, up, n, mu, qnorm)
    free(w)
    return PGS_LIMIT


def pgs_dense(M, q, diag, lo, up, z, double omega, int64_t max_iter, double tol, double mu,
              double qnorm):
    """PGS/PSOR on a dense M; ``z`` (float64, C-contiguous) is updated in place.  Returns
    (status, sweeps, error)."""
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray Ma = f64(M, n, n)
    return _run(f64_ptr(Ma), NULL, NULL, NULL, n, q, diag, lo, up, z, omega, max_iter, tol,
                mu, qnorm)


def pgs_csr(indptr, indices, data, q, diag, lo, up, z, double omega, int64_t max_iter,
            double tol, double mu, double qnorm):
    """PGS/PSOR on a CSR matrix (the diagonal entry is included in the row product)."""
    cdef Py_ssize_t n = len(q)
    cdef cnp.ndarray ip = i64(indptr, n + 1, -1)
    cdef int64_t nnz = i64_ptr(ip)[n]
    cdef cnp.ndarray ix = i64(indices, -1, -1)
    cdef cnp.ndarray dv = f64(data, -1, -1)
    if cnp.PyArray_DIM(ix, 0) < nnz or cnp.PyArray_DIM(dv, 0) < nnz:
        raise ValueError("pgs_csr: inconsistent CSR arrays")
    return _run(NULL, i64_ptr(ip), i64_ptr(ix), f64_ptr(dv), n, q, diag, lo, up, z, omega,
                max_iter, tol, mu, qnorm)


cdef object _run(const double* M, const int64_t* indptr, const int64_t* indices,
                 const double* data, Py_ssize_t n, q, diag, lo, up, z, double omega,
                 int64_t max_iter, double tol, double mu, double qnorm):
    cdef cnp.ndarray qa = f64(q, n, -1)
    cdef cnp.ndarray dg = f64(diag, n, -1)
    cdef cnp.ndarray la = f64(lo, n, -1)
    cdef cnp.ndarray ua = f64(up, n, -1)
    cdef cnp.ndarray za = inout(z, cnp.NPY_FLOAT64, n, -1)
    cdef int64_t sweeps = 0
    cdef double err = 0.0
    cdef int status
    if n == 0:
        return PGS_CONVERGED, 1, 0.0
    with nogil:
        status = pgs_sweeps(M, indptr, indices, data, f64_ptr(qa), f64_ptr(dg), f64_ptr(la),
                            f64_ptr(ua), f64_ptr(za), n, omega, max_iter, tol, mu, qnorm,
                            &sweeps, &err)
    if status < 0:
        raise MemoryError()
    return status, sweeps, err
