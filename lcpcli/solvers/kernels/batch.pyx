# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Batched kernels: one compiled call solves and certifies a stack of equal-size problems.

A stack is ``M`` of shape (K, n, n) and ``q`` of shape (K, n), row-major float64 (problem ``k``
is ``w = M[k] z + q[k]``, 0-based ``k``).  Each problem runs the same C code as the one-problem
kernels (:c:func:`lemke_tableau` and :c:func:`polish`, :c:func:`pgs_sweeps`) and its answer is
judged by :c:func:`certify_dense`, the project's one certificate.  The loop over problems runs
in OpenMP threads (``prange``; serial where the compiler has no OpenMP); every problem
allocates its own scratch, so threads share nothing but the read-only stack.

Per problem the kernels write ``z`` and ``w`` (K, n), ``code`` (K,) int8, ``iterations`` (K,)
int64 and ``error`` (K,) float64 (the certified error; ``inf`` when it could not be computed
here).  ``code`` is :data:`SOLVED` when the certificate passed at ``tol``, else :data:`RETRY`:
the kernel has no verdict and the caller runs the full one-problem pipeline (equilibration,
ray classification, Farkas proofs; :func:`lcpcli.api.solve`) on that problem.  A batched
kernel therefore never says ``no_solution`` and never says ``solved`` without the certificate.
"""

from cython.parallel cimport prange
from libc.math cimport INFINITY, NAN, fabs, ldexp
from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc

cimport numpy as cnp

from lcpcli.analysis._scaling cimport _balanced, _ruiz, _symmetric
from lcpcli.core._certificate cimport CertOut, certify_dense
from lcpcli.core.arrays cimport f64_ptr, inout
from lcpcli.solvers.kernels.lemke cimport (
    LEMKE_OK,
    LEMKE_TRIVIAL,
    LemkeOut,
    lemke_tableau,
    polish,
)
from lcpcli.solvers.kernels.pgs cimport PGS_CONVERGED, pgs_sweeps

cnp.import_array()

cdef enum:
    B_SOLVED = 0
    B_RETRY = 1

#: ``code`` of a problem whose answer passed the certificate.
SOLVED = B_SOLVED
#: ``code`` of a problem the kernel could not certify: run the full pipeline on it.
RETRY = B_RETRY


cdef inline bint _passed(const CertOut* c, double tol) noexcept nogil:
    return c.status == 0 and c.error <= tol


cdef int _balance(const double* M, const double* q, const double* d, Py_ssize_t n,
                  const int* eq, double* Ms, double* qs, double* ds,
                  long long* r, long long* c) noexcept nogil:
    """Equilibrate one problem as :func:`lcpcli.analysis.scaling.equilibrate` does (``D M D``
    for a symmetric M, two-sided otherwise; ``eq`` = (balanced, q_balanced, max_rounds)):
    fill ``Ms = D_r M D_c``, ``qs = D_r q`` and the covering vector ``ds`` (``D_r d``, or ones
    when ``d`` is NULL, as the pipeline leaves a default covering vector alone) and return 1,
    or return 0 when the problem is balanced already.  ``r``, ``c``: 4 n long longs."""
    cdef Py_ssize_t i, j
    # balanced already (one pass, as lcpcli.analysis.scaling.is_balanced): nothing to do, and
    # no symmetry test (it only chooses between D M D and two-sided scaling)
    if _balanced(n, M, n, q, eq[0], eq[1], r):
        return 0
    if not _ruiz(n, M, n, NULL, NULL, NULL, q, _symmetric(M, n), eq[0], eq[1], eq[2], r, c,
                 r + 2 * n, r + 3 * n):
        return 0
    for i in range(n):
        for j in range(n):
            Ms[i * n + j] = ldexp(M[i * n + j], <int>(r[i] + c[j]))
        qs[i] = ldexp(q[i], <int>r[i])
        ds[i] = 1.0 if d == NULL else ldexp(d[i], <int>r[i])
    return 1


cdef void _lemke_one(const double* M, const double* q, const double* d, Py_ssize_t n,
                     int64_t max_iter, double piv_tol, double tie_tol, double tol,
                     double polished, const int* eq, double* z, double* w, signed char* code,
                     int64_t* iters, double* err, double* res) noexcept nogil:
    """Lemke (tableau) and the certificate of one problem.  The problem is equilibrated first
    when it is not balanced (as the one-problem pipeline does; the answer is mapped back
    exactly and certified on the problem as given); the end basis is re-solved (polish) only
    when the tableau's answer is not certified at rounding level (``polished``: most answers
    are, and polishing them costs a fifth of the time)."""
    cdef double* work = <double*>malloc((10 * n + n * n + 1) * sizeof(double))
    cdef int64_t* basic = <int64_t*>malloc((n + 1) * sizeof(int64_t))
    cdef Py_ssize_t* iwork = <Py_ssize_t*>malloc((3 * n + 1) * sizeof(Py_ssize_t))
    cdef long long* rc_exp = <long long*>malloc((4 * n + 1) * sizeof(long long))
    cdef double* raw
    cdef double* ray
    cdef double* cwork
    cdef double* Ms
    cdef double* qs
    cdef double* ds
    cdef const double* Mu = M
    cdef const double* qu = q
    cdef const double* du = d
    cdef LemkeOut out
    cdef CertOut cert
    cdef Py_ssize_t i
    cdef int rc
    cdef bint scaled = False
    code[0] = B_RETRY
    iters[0] = 0
    err[0] = INFINITY
    res[0] = NAN
    if work == NULL or basic == NULL or iwork == NULL or rc_exp == NULL:
        free(work)
        free(basic)
        free(iwork)
        free(rc_exp)
        return
    raw = work
    ray = work + n
    cwork = work + 2 * n  # 5 n for the certificate
    qs = work + 7 * n
    ds = work + 8 * n
    Ms = work + 10 * n
    if eq != NULL and _balance(M, q, d, n, eq, Ms, qs, ds, rc_exp, rc_exp + n):
        scaled = True
        Mu, qu, du = Ms, qs, ds
    elif d == NULL:  # the default covering vector: all ones
        for i in range(n):
            ds[i] = 1.0
        du = ds
    rc = lemke_tableau(Mu, qu, du, n, max_iter, piv_tol, tie_tol, NULL, 0, raw, basic, ray,
                       &out)
    if rc == 0 and scaled:  # z = D_c z~ (exact)
        for i in range(n):
            raw[i] = ldexp(raw[i], <int>rc_exp[n + i])
    if rc == 0:
        iters[0] = out.pivots
        for i in range(n):
            z[i] = 0.0 if out.status == LEMKE_TRIVIAL or raw[i] < 0.0 else raw[i]
        certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, NULL, &cert)
        if out.status == LEMKE_OK and not (cert.status == 0 and cert.error <= polished):
            # not at rounding level (cancellation in the tableau updates, or a failure): the
            # end basis re-solved by LU with one refinement step (polish keeps the better of
            # that and the tableau's answer), then certified again
            rc = polish(M, q, n, raw, basic, z)
            if rc == 0:
                certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, NULL, &cert)
        if rc == 0:
            if cert.status == 0:
                err[0] = cert.error
            res[0] = cert.residual
            if (out.status == LEMKE_OK or out.status == LEMKE_TRIVIAL) and _passed(&cert, tol):
                code[0] = B_SOLVED
    free(work)
    free(basic)
    free(iwork)
    free(rc_exp)


cdef void _sor_one(const double* M, const double* q, const double* lo_in, const double* up_in,
                   Py_ssize_t n, double omega, int64_t max_iter, double tol, double* z,
                   double* w, signed char* code, int64_t* iters, double* err,
                   double* res) noexcept nogil:
    """Projected SOR from ``z`` (already inside the bounds), sweeping until the certificate
    passes (the sweep's own stopping test is normwise: the target is tightened tenfold until
    the componentwise certificate is met, as :mod:`lcpcli.solvers.methods.pgs` does)."""
    cdef double* work = <double*>malloc((8 * n + 1) * sizeof(double))
    cdef Py_ssize_t* iwork = <Py_ssize_t*>malloc((3 * n + 1) * sizeof(Py_ssize_t))
    cdef double* diag
    cdef double* lo
    cdef double* up
    cdef double* cwork
    cdef Py_ssize_t i, j
    cdef double mu = 0.0, qnorm = 0.0, rowsum, target = tol, e
    cdef int64_t sweeps = 0, done = 0
    cdef int status
    cdef CertOut cert
    code[0] = B_RETRY
    iters[0] = 0
    err[0] = INFINITY
    res[0] = NAN
    if work == NULL or iwork == NULL:
        free(work)
        free(iwork)
        return
    diag = work
    lo = work + n
    up = work + 2 * n
    cwork = work + 3 * n
    for i in range(n):
        lo[i] = lo_in[i] if lo_in != NULL else 0.0
        up[i] = up_in[i] if up_in != NULL else INFINITY
        diag[i] = M[i * n + i]
        if not (diag[i] > 0.0):
            if lo[i] < up[i]:  # the update divides by M_ii: the full pipeline says so
                free(work)
                free(iwork)
                return
            diag[i] = 1.0
        rowsum = 0.0
        for j in range(n):
            rowsum = rowsum + fabs(M[i * n + j])
        if rowsum > mu:
            mu = rowsum
        if fabs(q[i]) > qnorm:
            qnorm = fabs(q[i])
    if mu == 0.0:
        mu = 1.0
    while True:
        status = pgs_sweeps(M, NULL, NULL, NULL, q, diag, lo, up, z, n, omega,
                            max_iter - sweeps, target, mu, qnorm, &done, &e)
        sweeps = sweeps + done
        if status < 0:
            break
        if status != PGS_CONVERGED and sweeps < max_iter:
            break
        certify_dense(n, M, n, q, z, 0, lo_in, up_in, w, cwork, iwork, NULL, &cert)
        if cert.status == 0:
            err[0] = cert.error
            res[0] = cert.residual
        if _passed(&cert, tol):
            code[0] = B_SOLVED
            break
        if status != PGS_CONVERGED or sweeps >= max_iter or target < 1e-15:
            break
        target = target * 0.1
    iters[0] = sweeps
    free(work)
    free(iwork)


cdef bint _empty(_Stack a):
    """True (and the outputs filled) when there is nothing to solve: K = 0, or problems of size
    0 (solved by z = ())."""
    cdef Py_ssize_t k
    if a.K and a.n:
        return False
    for k in range(a.K):
        a.code[k] = B_SOLVED
        a.iters[k] = 0
        a.err[k] = 0.0
        a.residual[k] = 0.0
    return True


cdef class _Stack:
    """A stack's checked arrays (kept alive here) and their data pointers."""
    cdef cnp.ndarray Ma, qa, zo, wo, co, io, eo, ro
    cdef Py_ssize_t K, n
    cdef const double* M
    cdef const double* q
    cdef double* z
    cdef double* w
    cdef signed char* code
    cdef int64_t* iters
    cdef double* err
    cdef double* residual


cdef _Stack _checked(M, q, z, w, code, iters, err, residual, str name):
    """``M`` (K, n, n) and ``q`` (K, n) as float64 (views when they are), and the preallocated
    outputs (``inout``: no silent copies); ValueError on a wrong shape."""
    cdef _Stack a = _Stack()
    a.Ma = _stack(M, 3)
    a.qa = _stack(q, 2)
    a.K, a.n = cnp.PyArray_DIM(a.Ma, 0), cnp.PyArray_DIM(a.Ma, 1)
    if cnp.PyArray_DIM(a.Ma, 2) != a.n or cnp.PyArray_DIM(a.qa, 0) != a.K \
            or cnp.PyArray_DIM(a.qa, 1) != a.n:
        raise ValueError(f"{name}: M must be (K, n, n) and q (K, n)")
    a.zo = inout(z, cnp.NPY_FLOAT64, a.K, a.n)
    a.wo = inout(w, cnp.NPY_FLOAT64, a.K, a.n)
    a.co = inout(code, cnp.NPY_INT8, a.K, -1)
    a.io = inout(iters, cnp.NPY_INT64, a.K, -1)
    a.eo = inout(err, cnp.NPY_FLOAT64, a.K, -1)
    a.ro = inout(residual, cnp.NPY_FLOAT64, a.K, -1)
    a.M, a.q = f64_ptr(a.Ma), f64_ptr(a.qa)
    a.z, a.w, a.err, a.residual = f64_ptr(a.zo), f64_ptr(a.wo), f64_ptr(a.eo), f64_ptr(a.ro)
    a.code = <signed char*>cnp.PyArray_DATA(a.co)
    a.iters = <int64_t*>cnp.PyArray_DATA(a.io)
    return a


cdef cnp.ndarray _stack(object a, Py_ssize_t ndim):
    """``a`` as a C-contiguous float64 array of ``ndim`` dimensions (a view when it is one)."""
    return cnp.PyArray_FROMANY(a, cnp.NPY_FLOAT64, ndim, ndim,
                               cnp.NPY_ARRAY_C_CONTIGUOUS | cnp.NPY_ARRAY_ALIGNED)


def lemke_stack(M, q, d, int64_t max_iter, double piv_tol, double tie_tol, double tol,
                z, w, code, iters, err, residual, int threads, balance=None,
                double polished=0.0):
    """Lemke (tableau) on every problem of the stack ``M`` (K, n, n), ``q`` (K, n).

    ``d``: the covering vector (n,), or None for all ones.  Outputs (preallocated,
    C-contiguous): ``z``, ``w`` (K, n) float64, ``code`` (K,) int8, ``iters`` (K,) int64,
    ``err`` and ``residual`` (K,) float64 (the certificate's; inf / NaN where none); see the
    module docstring.  ``threads``: OpenMP threads (>= 1).
    ``balance``: None (no equilibration) or ``(balanced, q_balanced, max_rounds)`` of
    :mod:`lcpcli.analysis.scaling`: each problem that is not balanced is equilibrated first.
    ``polished``: the end basis is re-solved unless the certified error is at most this
    (:data:`lcpcli.solvers.tolerances.POLISHED`; 0: always).
    """
    cdef int eqv[3]
    cdef const int* eq = NULL
    if balance is not None:
        eqv[0], eqv[1], eqv[2] = balance
        eq = eqv
    cdef _Stack a = _checked(M, q, z, w, code, iters, err, residual, "lemke_stack")
    cdef Py_ssize_t K = a.K, n = a.n, nn = a.n * a.n, k
    cdef cnp.ndarray da
    cdef double* dp = NULL
    if d is not None:
        da = _stack(d, 1)
        if cnp.PyArray_DIM(da, 0) != n:
            raise ValueError("lemke_stack: the covering vector must have length n")
        dp = f64_ptr(da)
    if _empty(a):
        return
    for k in prange(K, nogil=True, schedule="dynamic", chunksize=16,
                    num_threads=threads if threads > 0 else 1):
        _lemke_one(a.M + k * nn, a.q + k * n, dp, n, max_iter, piv_tol, tie_tol, tol, polished,
                   eq, a.z + k * n, a.w + k * n, a.code + k, a.iters + k, a.err + k,
                   a.residual + k)


def sor_stack(M, q, lo, up, double omega, int64_t max_iter, double tol, z, w, code, iters,
              err, residual, int threads):
    """Projected SOR (``omega = 1``: Gauss-Seidel) on every problem of the stack.

    ``lo``/``up``: None (LCP: ``z >= 0``) or bounds of shape (K, n) (box LCP).  ``z`` (K, n)
    holds the start points (inside the bounds) and receives the answers; the other outputs
    as :func:`lemke_stack`.
    """
    cdef _Stack a = _checked(M, q, z, w, code, iters, err, residual, "sor_stack")
    cdef Py_ssize_t K = a.K, n = a.n, nn = a.n * a.n, k
    cdef cnp.ndarray la, ua
    cdef const double* lp = NULL
    cdef const double* up_ = NULL
    if (lo is None) != (up is None):
        raise ValueError("sor_stack: give both bounds or neither")
    if lo is not None:
        la = _stack(lo, 2)
        ua = _stack(up, 2)
        if cnp.PyArray_DIM(la, 0) != K or cnp.PyArray_DIM(la, 1) != n \
                or cnp.PyArray_DIM(ua, 0) != K or cnp.PyArray_DIM(ua, 1) != n:
            raise ValueError("sor_stack: bounds must be (K, n)")
        lp = f64_ptr(la)
        up_ = f64_ptr(ua)
    if _empty(a):
        return
    for k in prange(K, nogil=True, schedule="dynamic", chunksize=16,
                    num_threads=threads if threads > 0 else 1):
        _sor_one(a.M + k * nn, a.q + k * n, lp + k * n if lp != NULL else NULL,
                 up_ + k * n if up_ != NULL else NULL, n, omega, max_iter, tol, a.z + k * n,
                 a.w + k * n, a.code + k, a.iters + k, a.err + k, a.residual + k)

