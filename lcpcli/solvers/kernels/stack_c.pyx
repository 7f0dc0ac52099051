# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""The single-source stacked kernels (``src/lcp_stack.h``) compiled for the CPU.

``src/lcp_stack.h`` is the one C text of the batched Lemke and projected SOR kernels and of
their certificate; :mod:`lcpcli.solvers.backends.cuda` compiles the same text for a CUDA device
(NVRTC).  This module runs it on the CPU (OpenMP threads over the problems) so that the test
suite, which never has a GPU, checks the device's code against :func:`lcpcli.solve_many` on
every run.  It is also the ``"c"`` batch backend (:mod:`lcpcli.solvers.backends`).

Outputs and codes are those of :mod:`lcpcli.solvers.kernels.batch` (``code`` 0: certified,
1: hand the problem to the CPU path).
"""

from cython.parallel cimport prange
from libc.stdlib cimport free, malloc

cimport numpy as cnp

cnp.import_array()

import numpy as np


cdef extern from "src/lcp_stack.h" nogil:
    long long LCP_LEMKE_DWORK(long long n)
    long long LCP_LEMKE_IWORK(long long n)
    long long LCP_SOR_DWORK(long long n)
    long long LCP_SOR_IWORK(long long n)
    long long LCP_TAB_DWORK(long long n)
    long long LCP_TAB_IWORK(long long n)
    void lcp_lemke_one(long long n, const double* M, const double* q, const double* d,
                       long long max_iter, double piv_tol, double tie_tol, double tol,
                       double polished, int balanced, int q_balanced, int max_rounds,
                       double* tw, long long* ti, double* rw, long long* ri, double* cw,
                       long long* ci, double* z, double* w, signed char* code,
                       long long* iters, double* err, double* res, long long lane,
                       long long lanes, int warp, int stage)
    long long LCP_HOT_DWORK(long long n)
    long long LCP_HOT_IWORK(long long n)
    long long LCP_FAST_SLOTS(long long n)
    long long LCP_COLD_SLOTS(long long n)
    long long LCP_FAST_SLOTS_FOR(long long n, long long per)
    long long LCP_COLD_SLOTS_FOR(long long n, long long per)
    void lcp_lemke_group(long long n, const double* M, const double* q, const double* d,
                         long long max_iter, double piv_tol, double tie_tol, double tol,
                         double polished, int balanced, int q_balanced, int max_rounds,
                         int stage, double* sh, double* cold, double* z, double* w,
                         signed char* code, long long* iters, double* err, double* res,
                         long long lane, long long lanes)
    void lcp_sor_one(long long n, const double* M, const double* q, const double* lo_in,
                     const double* up_in, double omega, long long max_iter, double tol,
                     double* work, long long* iwork, double* z, double* w, signed char* code,
                     long long* iters, double* err, double* res)


cdef extern from "src/lcp_stack.h" nogil:
    ctypedef struct lcp_cert:
        double error
        double residual
        int status
    int lcp_certify(long long n, const double* M, const double* q, const double* z,
                    const double* lo, const double* up, double* w, double* work,
                    long long* iwork, lcp_cert* out)
    int lcp_certify_warp(long long n, const double* M, const double* q, const double* z,
                         const double* lo, const double* up, double* w, double* work,
                         long long* iwork, lcp_cert* out, long long lane, long long lanes)


def certify(M, q, z, lo=None, up=None, bint warp=False):
    """``(status, error, residual)`` of the single-source certificate of ``z`` for one problem
    (``lo``/``up``: a box, or None for an LCP); ``warp``: the warp kernel's version (one lane).
    For tests: the definition is :mod:`lcpcli.core.certificate`'s."""
    cdef cnp.ndarray Ma = np.ascontiguousarray(M, dtype=np.float64)
    cdef cnp.ndarray qa = np.ascontiguousarray(q, dtype=np.float64)
    cdef cnp.ndarray za = np.ascontiguousarray(z, dtype=np.float64)
    cdef Py_ssize_t n = qa.shape[0]
    cdef cnp.ndarray wa = np.zeros(n)
    cdef cnp.ndarray work = np.zeros(5 * n + 1)
    cdef cnp.ndarray iwork = np.zeros(3 * n + 1, dtype=np.int64)
    cdef cnp.ndarray la = None, ua = None
    cdef const double* pl = NULL
    cdef const double* pu = NULL
    cdef lcp_cert out
    if Ma.shape[0] != n or Ma.shape[1] != n or za.shape[0] != n:
        raise ValueError("stack_c.certify: M must be (n, n), q and z (n,)")
    if lo is not None:
        la = np.ascontiguousarray(lo, dtype=np.float64)
        ua = np.ascontiguousarray(up, dtype=np.float64)
        pl = <const double*>cnp.PyArray_DATA(la)
        pu = <const double*>cnp.PyArray_DATA(ua)
    if warp:
        lcp_certify_warp(n, <const double*>cnp.PyArray_DATA(Ma),
                         <const double*>cnp.PyArray_DATA(qa), <const double*>cnp.PyArray_DATA(za),
                         pl, pu, <double*>cnp.PyArray_DATA(wa), <double*>cnp.PyArray_DATA(work),
                         <long long*>cnp.PyArray_DATA(iwork), &out, 0, 1)
    else:
        lcp_certify(n, <const double*>cnp.PyArray_DATA(Ma), <const double*>cnp.PyArray_DATA(qa),
                    <const double*>cnp.PyArray_DATA(za), pl, pu, <double*>cnp.PyArray_DATA(wa),
                    <double*>cnp.PyArray_DATA(work), <long long*>cnp.PyArray_DATA(iwork), &out)
    return out.status, out.error, out.residual


def workspace(str kernel, long long n):
    """(doubles, long longs) of workspace one problem of size ``n`` needs in ``kernel``
    (``"lemke"`` or ``"sor"``; ``"tableau"``: the part of Lemke's that the warp kernel keeps
    in shared memory): the device backend allocates this per thread or warp."""
    if kernel == "lemke":
        return int(LCP_LEMKE_DWORK(n)), int(LCP_LEMKE_IWORK(n))
    if kernel == "tableau":
        return int(LCP_TAB_DWORK(n)), int(LCP_TAB_IWORK(n))
    return int(LCP_SOR_DWORK(n)), int(LCP_SOR_IWORK(n))


def group_slots(long long n):
    """(fast, cold): the 8-byte slots of the device warp kernel's workspace per group for size
    ``n`` (its 32-bit indices two to a slot); the fast part goes to shared memory when it
    fits."""
    return int(LCP_FAST_SLOTS_FOR(n, 2)), int(LCP_COLD_SLOTS_FOR(n, 2))


cdef cnp.ndarray _out(object a, int typenum, Py_ssize_t size, str label):
    if not (cnp.PyArray_Check(a) and cnp.PyArray_TYPE(<cnp.ndarray>a) == typenum
            and cnp.PyArray_IS_C_CONTIGUOUS(<cnp.ndarray>a)
            and cnp.PyArray_ISWRITEABLE(<cnp.ndarray>a) and cnp.PyArray_SIZE(a) == size):
        raise ValueError(f"stack_c: {label} must be a writeable C-contiguous array of "
                         f"{size} entries of its dtype")
    return <cnp.ndarray>a


def lemke_stack(M, q, d, long long max_iter, double piv_tol, double tie_tol, double tol,
                double polished, balance, z, w, code, iters, err, residual, int threads,
                bint warp=False, bint stage=True):
    """Lemke and the certificate on every problem of ``M`` (K, n, n), ``q`` (K, n).

    ``d``: covering vector (n,) or None (ones); ``balance``: None (no balance test) or
    ``(balanced, q_balanced, max_rounds)``: a problem that is not balanced is equilibrated
    first (:mod:`lcpcli.analysis.scaling`).  ``polished``: answers certified above this error
    have their end basis re-solved (as the CPU kernel).
    ``warp``: run the warp kernel's body (``lcp_lemke_group``, one lane here: the device
    kernel's arithmetic, label-propagation blocks in the certificate) instead of the thread
    one; ``stage``: the certificate reading M, q, z, w from the group's fast workspace, a
    speed choice of ``backends.cuda.WARP_TABLE``).
    Outputs as :func:`lcpcli.solvers.kernels.batch.lemke_stack`."""
    cdef cnp.ndarray Ma = np.ascontiguousarray(M, dtype=np.float64)
    cdef cnp.ndarray qa = np.ascontiguousarray(q, dtype=np.float64)
    cdef Py_ssize_t K = qa.shape[0], n = qa.shape[1], k
    if Ma.ndim != 3 or Ma.shape[0] != K or Ma.shape[1] != n or Ma.shape[2] != n:
        raise ValueError("stack_c: M must be (K, n, n) and q (K, n)")
    cdef cnp.ndarray da = None
    cdef const double* dp = NULL
    if d is not None:
        da = np.ascontiguousarray(d, dtype=np.float64)
        if da.shape[0] != n:
            raise ValueError("stack_c: the covering vector must have length n")
        dp = <const double*>cnp.PyArray_DATA(da)
    cdef int bal = -1, qbal = 0, rounds = 0
    if balance is not None:
        bal, qbal, rounds = balance
    cdef double* pz = <double*>cnp.PyArray_DATA(_out(z, cnp.NPY_FLOAT64, K * n, "z"))
    cdef double* pw = <double*>cnp.PyArray_DATA(_out(w, cnp.NPY_FLOAT64, K * n, "w"))
    cdef signed char* pc = <signed char*>cnp.PyArray_DATA(_out(code, cnp.NPY_INT8, K, "code"))
    cdef long long* pi = <long long*>cnp.PyArray_DATA(_out(iters, cnp.NPY_INT64, K, "iters"))
    cdef double* pe = <double*>cnp.PyArray_DATA(_out(err, cnp.NPY_FLOAT64, K, "err"))
    cdef double* pr = <double*>cnp.PyArray_DATA(_out(residual, cnp.NPY_FLOAT64, K, "residual"))
    cdef const double* pM = <const double*>cnp.PyArray_DATA(Ma)
    cdef const double* pq = <const double*>cnp.PyArray_DATA(qa)
    cdef long long dw = LCP_LEMKE_DWORK(n), iw = LCP_LEMKE_IWORK(n)
    cdef long long tdw = LCP_TAB_DWORK(n), tiw = LCP_TAB_IWORK(n)
    cdef long long hdw = LCP_HOT_DWORK(n), hiw = LCP_HOT_IWORK(n)
    cdef int st = stage
    cdef long long fast = LCP_FAST_SLOTS(n), cold = LCP_COLD_SLOTS(n)
    cdef int wp = warp
    cdef double* work
    cdef long long* iwork
    if n == 0:
        code[...] = 0
        iters[...] = 0
        err[...] = 0.0
        residual[...] = 0.0
        return
    for k in prange(K, nogil=True, schedule="dynamic", chunksize=16,
                    num_threads=threads if threads > 0 else 1):
        work = <double*>malloc((fast + cold if wp else dw) * sizeof(double))
        iwork = NULL if wp else <long long*>malloc(iw * sizeof(long long))
        if work != NULL and wp:
            lcp_lemke_group(n, pM + k * n * n, pq + k * n, dp, max_iter, piv_tol, tie_tol, tol,
                            polished, bal, qbal, rounds, st, work, work + fast, pz + k * n,
                            pw + k * n, pc + k, pi + k, pe + k, pr + k, 0, 1)
        elif work != NULL and iwork != NULL:
            lcp_lemke_one(n, pM + k * n * n, pq + k * n, dp, max_iter, piv_tol, tie_tol, tol,
                          polished, bal, qbal, rounds, work, iwork, work + tdw, iwork + tiw,
                          work + tdw + hdw, iwork + tiw + hiw, pz + k * n, pw + k * n, pc + k,
                          pi + k, pe + k, pr + k, 0, 1, 0, 0)
        else:
            pc[k] = 1
        free(work)
        free(iwork)


def sor_stack(M, q, lo, up, double omega, long long max_iter, double tol, z, w, code, iters,
              err, residual, int threads):
    """Projected SOR (``omega = 1``: Gauss-Seidel) and the certificate on every problem;
    ``lo``/``up``: None or (K, n) bounds; ``z`` (K, n) holds the start points.  As
    :func:`lcpcli.solvers.kernels.batch.sor_stack`."""
    cdef cnp.ndarray Ma = np.ascontiguousarray(M, dtype=np.float64)
    cdef cnp.ndarray qa = np.ascontiguousarray(q, dtype=np.float64)
    cdef Py_ssize_t K = qa.shape[0], n = qa.shape[1], k
    if Ma.ndim != 3 or Ma.shape[0] != K or Ma.shape[1] != n or Ma.shape[2] != n:
        raise ValueError("stack_c: M must be (K, n, n) and q (K, n)")
    if (lo is None) != (up is None):
        raise ValueError("stack_c: give both bounds or neither")
    cdef cnp.ndarray la = None, ua = None
    cdef const double* pl = NULL
    cdef const double* pu = NULL
    if lo is not None:
        la = np.ascontiguousarray(np.broadcast_to(lo, (K, n)), dtype=np.float64)
        ua = np.ascontiguousarray(np.broadcast_to(up, (K, n)), dtype=np.float64)
        pl = <const double*>cnp.PyArray_DATA(la)
        pu = <const double*>cnp.PyArray_DATA(ua)
    cdef double* pz = <double*>cnp.PyArray_DATA(_out(z, cnp.NPY_FLOAT64, K * n, "z"))
    cdef double* pw = <double*>cnp.PyArray_DATA(_out(w, cnp.NPY_FLOAT64, K * n, "w"))
    cdef signed char* pc = <signed char*>cnp.PyArray_DATA(_out(code, cnp.NPY_INT8, K, "code"))
    cdef long long* pi = <long long*>cnp.PyArray_DATA(_out(iters, cnp.NPY_INT64, K, "iters"))
    cdef double* pe = <double*>cnp.PyArray_DATA(_out(err, cnp.NPY_FLOAT64, K, "err"))
    cdef double* pr = <double*>cnp.PyArray_DATA(_out(residual, cnp.NPY_FLOAT64, K, "residual"))
    cdef const double* pM = <const double*>cnp.PyArray_DATA(Ma)
    cdef const double* pq = <const double*>cnp.PyArray_DATA(qa)
    cdef long long dw = LCP_SOR_DWORK(n), iw = LCP_SOR_IWORK(n)
    cdef double* work
    cdef long long* iwork
    if n == 0:
        code[...] = 0
        iters[...] = 0
        err[...] = 0.0
        residual[...] = 0.0
        return
    for k in prange(K, nogil=True, schedule="dynamic", chunksize=16,
                    num_threads=threads if threads > 0 else 1):
        work = <double*>malloc(dw * sizeof(double))
        iwork = <long long*>malloc(iw * sizeof(long long))
        if work != NULL and iwork != NULL:
            lcp_sor_one(n, pM + k * n * n, pq + k * n, pl + k * n if pl != NULL else NULL,
                        pu + k * n if pu != NULL else NULL, omega, max_iter, tol, work, iwork,
                        pz + k * n, pw + k * n, pc + k, pi + k, pe + k, pr + k)
        else:
            pc[k] = 1
        free(work)
        free(iwork)
