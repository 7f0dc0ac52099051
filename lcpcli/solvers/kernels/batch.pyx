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
from lcpcli.solvers.kernels.simd cimport axpy

from lcpcli.core.tolerances import TINY_Z as _TINY_Z

cnp.import_array()

cdef extern from *:
    """
    /* ask for the next problem's M (n x n doubles) while this one is solved */
    static inline void lcpcli_prefetch_block(const double *p, Py_ssize_t count)
    {
    #if defined(__GNUC__)
        for (Py_ssize_t i = 0; i < count; i += 8)
            __builtin_prefetch(p + i, 0, 3);
    #else
        (void)p;
        (void)count;
    #endif
    }

    /* _basic_solution's elimination: LU with diagonal pivoting of the m x m row-major block A
     * (the first largest remaining diagonal entry pivots, rows and columns swapped with idx),
     * stopping when no remaining diagonal entry exceeds 1e-13 big.  Scalar loops (the rows are
     * short: vectorising them cost more in checks than it saved).  lcpcli_lu_step: step k;
     * returns 0 (nothing done) when the rest of the block is singular, else 1 */
    #if defined(__GNUC__) && !defined(__clang__)
    #define LCPCLI_LU_ATTR __attribute__((optimize("no-tree-vectorize"), always_inline))
    #else
    #define LCPCLI_LU_ATTR
    #endif
    static inline LCPCLI_LU_ATTR int lcpcli_lu_step(double *A, Py_ssize_t m, double big,
                                                    Py_ssize_t *idx, Py_ssize_t k)
    {
        Py_ssize_t i, j, p = k;
        double d = fabs(A[k * m + k]);
        for (i = k + 1; i < m; i++) {
            double t = fabs(A[i * m + i]);
            int better = t > d;
            p = better ? i : p;
            d = better ? t : d;
        }
        if (!(d > 1e-13 * big))
            return 0;
        if (p != k) {
            double *rk = A + k * m, *rp = A + p * m, t;
            Py_ssize_t ti;
            for (j = 0; j < m; j++) {
                t = rk[j];
                rk[j] = rp[j];
                rp[j] = t;
            }
            for (i = 0; i < m; i++) {
                t = A[i * m + k];
                A[i * m + k] = A[i * m + p];
                A[i * m + p] = t;
            }
            ti = idx[k];
            idx[k] = idx[p];
            idx[p] = ti;
        }
        const double *rk = A + k * m;
        double pivot = rk[k];
        for (i = k + 1; i < m; i++) {
            double *ri = A + i * m;
            double l = ri[k] / pivot;
            ri[k] = l;
            for (j = k + 1; j < m; j++)
                ri[j] = ri[j] - l * rk[j];
        }
        return 1;
    }

    /* the elimination of one block: returns the pivots taken */
    #if defined(__GNUC__) && !defined(__clang__)
    __attribute__((optimize("no-tree-vectorize")))
    #endif
    static Py_ssize_t lcpcli_diag_lu(double *A, Py_ssize_t m, double big, Py_ssize_t *idx)
    {
        Py_ssize_t k = 0;
        while (k < m && lcpcli_lu_step(A, m, big, idx, k))
            k++;
        return k;
    }

    /* the eliminations of two independent blocks, step by step in turn: each is a chain of
     * dependent divisions and updates, and the processor overlaps the two chains (the same
     * operations on each block as lcpcli_diag_lu); the pivots taken in k[0], k[1] */
    #if defined(__GNUC__) && !defined(__clang__)
    __attribute__((optimize("no-tree-vectorize")))
    #endif
    static void lcpcli_diag_lu2(double *A0, Py_ssize_t m0, double big0, Py_ssize_t *idx0,
                                double *A1, Py_ssize_t m1, double big1, Py_ssize_t *idx1,
                                Py_ssize_t *k)
    {
        int live0 = m0 > 0, live1 = m1 > 0;
        k[0] = 0;
        k[1] = 0;
        while (live0 | live1) {
            if (live0) {
                live0 = lcpcli_lu_step(A0, m0, big0, idx0, k[0]);
                k[0] += live0;
                live0 &= k[0] < m0;
            }
            if (live1) {
                live1 = lcpcli_lu_step(A1, m1, big1, idx1, k[1]);
                k[1] += live1;
                live1 &= k[1] < m1;
            }
        }
    }

    /* b <- U^-1 L^-1 b for the factors of lcpcli_diag_lu (unit lower L, then U), the sums in
     * order j = 0, 1, ... as the elimination would form them; scalar loops */
    #if defined(__GNUC__) && !defined(__clang__)
    __attribute__((optimize("no-tree-vectorize")))
    #endif
    static void lcpcli_lu_solve(const double *A, Py_ssize_t m, double *b)
    {
        Py_ssize_t i, j;
        for (i = 0; i < m; i++) {
            double t = b[i];
            for (j = 0; j < i; j++)
                t = t - A[i * m + j] * b[j];
            b[i] = t;
        }
        for (i = m - 1; i >= 0; i--) {
            double t = b[i];
            for (j = i + 1; j < m; j++)
                t = t - A[i * m + j] * b[j];
            b[i] = t / A[i * m + i];
        }
    }

    /* max_i |x_i| (0 when count = 0), four running maxima (a maximum does not depend on the
     * order; one running maximum was a chain through every entry) */
    static double lcpcli_absmax(const double *x, Py_ssize_t count)
    {
        double b[4] = {0.0, 0.0, 0.0, 0.0}, t;
        Py_ssize_t i = 0;
        for (; i + 4 <= count; i += 4)
            for (int l = 0; l < 4; l++) {
                t = fabs(x[i + l]);
                b[l] = t > b[l] ? t : b[l];
            }
        for (; i < count; i++) {
            t = fabs(x[i]);
            b[0] = t > b[0] ? t : b[0];
        }
        b[0] = b[1] > b[0] ? b[1] : b[0];
        b[2] = b[3] > b[2] ? b[3] : b[2];
        return b[2] > b[0] ? b[2] : b[0];
    }

    /* lcpcli_lu_solve of two independent systems, row by row in turn (the processor overlaps
     * the two chains of dependent divisions and sums; the same operations on each) */
    #if defined(__GNUC__) && !defined(__clang__)
    __attribute__((optimize("no-tree-vectorize")))
    #endif
    static void lcpcli_lu_solve2(const double *A0, Py_ssize_t m0, double *b0,
                                 const double *A1, Py_ssize_t m1, double *b1)
    {
        Py_ssize_t i, j, mm = m0 > m1 ? m0 : m1;
        for (i = 0; i < mm; i++) {
            if (i < m0) {
                double t = b0[i];
                for (j = 0; j < i; j++)
                    t = t - A0[i * m0 + j] * b0[j];
                b0[i] = t;
            }
            if (i < m1) {
                double t = b1[i];
                for (j = 0; j < i; j++)
                    t = t - A1[i * m1 + j] * b1[j];
                b1[i] = t;
            }
        }
        for (i = mm - 1; i >= 0; i--) {
            if (i < m0) {
                double t = b0[i];
                for (j = i + 1; j < m0; j++)
                    t = t - A0[i * m0 + j] * b0[j];
                b0[i] = t / A0[i * m0 + i];
            }
            if (i < m1) {
                double t = b1[i];
                for (j = i + 1; j < m1; j++)
                    t = t - A1[i * m1 + j] * b1[j];
                b1[i] = t / A1[i * m1 + i];
            }
        }
    }
    """
    void _prefetch "lcpcli_prefetch_block"(const double* p, Py_ssize_t count) noexcept nogil
    double _absmax "lcpcli_absmax"(const double* x, Py_ssize_t count) noexcept nogil
    void _lu_solve_c "lcpcli_lu_solve"(const double* A, Py_ssize_t m, double* b) noexcept nogil
    void _lu_solve2 "lcpcli_lu_solve2"(const double* A0, Py_ssize_t m0, double* b0,
                                       const double* A1, Py_ssize_t m1, double* b1) noexcept nogil
    Py_ssize_t _diag_lu "lcpcli_diag_lu"(double* A, Py_ssize_t m, double big,
                                         Py_ssize_t* idx) noexcept nogil
    void _diag_lu2 "lcpcli_diag_lu2"(double* A0, Py_ssize_t m0, double big0, Py_ssize_t* idx0,
                                     double* A1, Py_ssize_t m1, double big1, Py_ssize_t* idx1,
                                     Py_ssize_t* k) noexcept nogil

cdef enum:
    B_SOLVED = 0
    B_RETRY = 1

#: ``code`` of a problem whose answer passed the certificate.
SOLVED = B_SOLVED
#: ``code`` of a problem the kernel could not certify: run the full pipeline on it.
RETRY = B_RETRY


cdef inline bint _passed(const CertOut* c, double tol) noexcept nogil:
    return c.status == 0 and c.error <= tol


cdef enum:
    C_FIELDS = 9

#: Numbers in a row of a stack's ``cert`` output: a certificate's fields in the order of
#: :class:`lcpcli.core.certificate.Certificate` (``worst`` as a float), read back by
#: :func:`lcpcli.core.certificate.from_row`.
CERT_FIELDS = C_FIELDS


cdef inline double* _row(double* cert, Py_ssize_t k) noexcept nogil:
    """Problem k's row of a stack's ``cert`` output (NULL when none was asked for)."""
    return NULL if cert == NULL else cert + k * C_FIELDS


cdef inline signed char* _prow(signed char* pivots, Py_ssize_t k,
                               Py_ssize_t n) noexcept nogil:
    """Problem k's row of a stack's ``pivot_basis`` output (NULL when none was asked for)."""
    return NULL if pivots == NULL else pivots + k * n


cdef inline void _keep_basis(const signed char* F, Py_ssize_t n, signed char* prow) noexcept nogil:
    """A certified answer's pivoting basis (``F``: 1 where z_i is basic) into its row of
    ``pivot_basis`` (``prow`` not NULL)."""
    cdef Py_ssize_t i
    if prow != NULL:
        for i in range(n):
            prow[i] = 1 if F[i] != 0 else 0


cdef inline void _keep(const CertOut* c, double* err, double* res, double* row) noexcept nogil:
    """A certified answer's numbers: its error and residual, and (``row`` not NULL) the whole
    certificate as a row of ``cert`` (:data:`CERT_FIELDS`)."""
    err[0] = c.error
    res[0] = c.residual
    if row != NULL:
        row[0] = c.error
        row[1] = c.backward_error
        row[2] = c.growth
        row[3] = c.residual
        row[4] = c.bound_violation
        row[5] = c.w_violation
        row[6] = c.complementarity
        row[7] = c.equality_residual
        row[8] = <double>c.worst


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


# entries of z at rounding level (:func:`_zero_tiny`): lcpcli.core.tolerances.TINY_Z
cdef double TINY_Z = _TINY_Z


cdef bint _zero_tiny(double* z, Py_ssize_t n) noexcept nogil:
    """Set the entries of ``z`` at rounding level (``0 < |z_i| <= TINY_Z ||z||_inf``: degenerate
    basic z's, which a tableau leaves exactly 0; a row made only of such terms would read
    ``w_i / s_i ~ 1``) to exactly 0; returns whether there were any."""
    cdef Py_ssize_t i
    cdef double t = 0.0
    cdef bint tiny = False
    for i in range(n):
        if fabs(z[i]) > t:
            t = fabs(z[i])
    for i in range(n):
        if z[i] != 0.0 and fabs(z[i]) <= TINY_Z * t:
            z[i] = 0.0
            tiny = True
    return tiny


cdef void _lemke_one(const double* M, const double* q, const double* d, Py_ssize_t n,
                     int64_t max_iter, double piv_tol, double tie_tol, double tol,
                     double polished, const int* eq, double* z, double* w, signed char* code,
                     int64_t* iters, double* err, double* res,
                     signed char* state=NULL, double* crow=NULL,
                     signed char* prow=NULL) noexcept nogil:
    """Lemke (tableau) and the certificate of one problem (``state``, when not NULL, receives
    each pair's state as the certificate scores the answer; ``crow``, when not NULL, the
    certificate of a certified answer: :func:`_keep`; ``prow``, its complementary basis: 1 where
    z_i is basic in the tableau's final basis).  The problem is equilibrated first
    when it is not balanced (as the one-problem pipeline does; the answer is mapped back
    exactly and certified on the problem as given); the end basis is re-solved (polish) only
    when the tableau's answer is not certified at rounding level (``polished``: most answers
    are, and polishing them costs a fifth of the time); an answer still not certified is tried
    once more with its entries at rounding level set to 0 (:func:`_zero_tiny`)."""
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
        certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, state, &cert)
        if out.status == LEMKE_OK and not (cert.status == 0 and cert.error <= polished):
            # not at rounding level (cancellation in the tableau updates, or a failure): the
            # end basis re-solved by LU with one refinement step (polish keeps the better of
            # that and the tableau's answer), then certified again
            rc = polish(M, q, n, raw, basic, z)
            if rc == 0:
                certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, state, &cert)
        if rc == 0 and out.status == LEMKE_OK and not _passed(&cert, tol) and _zero_tiny(z, n):
            # degenerate basic z's left at rounding level (contact LCPs): as the warm start
            # does (:func:`_certify_basic`), with them set to 0
            certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, state, &cert)
        if rc == 0:
            if cert.status == 0:
                err[0] = cert.error
            res[0] = cert.residual
            if (out.status == LEMKE_OK or out.status == LEMKE_TRIVIAL) and _passed(&cert, tol):
                code[0] = B_SOLVED
                _keep(&cert, err, res, crow)
                if prow != NULL:  # z_i basic: code n + i in the tableau's basis (q >= 0: none)
                    for i in range(n):
                        prow[i] = 0
                    if out.status == LEMKE_OK:
                        for i in range(n):
                            if n <= basic[i] < 2 * n:
                                prow[basic[i] - n] = 1
    free(work)
    free(basic)
    free(iwork)
    free(rc_exp)


cdef enum:
    # problems up to this size take the warm start's scratch on the C stack (no malloc)
    STACK_N = 16


#: Block pivots without a new lowest count of infeasible pairs before the warm start's
#: least-index single pivots (Júdice & Pires' p; lcpcli.solvers.methods.bpp.BLOCK_TRIES).
cdef int W_BLOCK_TRIES = 3
#: A basic value is infeasible below -W_NEG_TOL times its scale (bpp.NEG_TOL).
cdef double W_NEG_TOL = 1e-12


cdef int _basic_solution(const double* M, const double* q, Py_ssize_t n,
                         signed char* F, double* A, Py_ssize_t* idx, Py_ssize_t* piv,
                         double* r, double* z) noexcept nogil:
    """The basic solution of basis ``F`` (1: z_i basic): ``M_FF z_F = -q_F`` by LU with
    diagonal pivoting (the largest diagonal entry of the remaining Schur complement pivots, a
    symmetric permutation kept in ``idx``; the factors stay in ``A`` for :func:`_refine`), ``z``
    0 off F.  A basis whose block is singular is *repaired* as simplex codes repair theirs:
    when no remaining diagonal entry exceeds 1e-13 times the block's largest entry, the pairs
    not yet pivoted leave F (their w_i becomes basic), so the block solved is the nonsingular
    principal block found so far (contact LCPs, whose redundant contacts make M singular, need
    this).  Returns the size of the solved block.  ``A``: n*n, ``idx``, ``piv``: n,
    ``r``: n."""
    cdef double big
    cdef Py_ssize_t m = _basic_gather(M, n, F, A, idx, piv, z, &big)
    if m == 0:
        return 0
    return _basic_finish(q, n, F, A, idx, piv, r, z, m, _diag_lu(A, m, big, idx))


cdef int _basic_solution2(const double* M0, const double* q0, signed char* F0, double* A0,
                          Py_ssize_t* idx0, Py_ssize_t* piv0, double* r0, double* z0,
                          const double* M1, const double* q1, signed char* F1, double* A1,
                          Py_ssize_t* idx1, Py_ssize_t* piv1, double* r1, double* z1,
                          Py_ssize_t n, Py_ssize_t* m) noexcept nogil:
    """:func:`_basic_solution` of two problems of size ``n``, their eliminations and their
    solves in turn (lcpcli_diag_lu2, lcpcli_lu_solve2: the processor overlaps the two chains of
    dependent operations); the sizes of the solved blocks in ``m[0]``, ``m[1]``."""
    cdef double big0, big1
    cdef Py_ssize_t k[2]
    cdef Py_ssize_t m0 = _basic_gather(M0, n, F0, A0, idx0, piv0, z0, &big0)
    cdef Py_ssize_t m1 = _basic_gather(M1, n, F1, A1, idx1, piv1, z1, &big1)
    cdef Py_ssize_t i
    _diag_lu2(A0, m0, big0, idx0, A1, m1, big1, idx1, k)
    m[0] = _basic_rhs(q0, F0, A0, idx0, r0, m0, k[0])
    m[1] = _basic_rhs(q1, F1, A1, idx1, r1, m1, k[1])
    _lu_solve2(A0, m[0], r0, A1, m[1], r1)  # (piv is the identity: no interchanges)
    for i in range(m[0]):
        z0[idx0[i]] = r0[i]
    for i in range(m[1]):
        z1[idx1[i]] = r1[i]
    return 0


cdef Py_ssize_t _basic_gather(const double* M, Py_ssize_t n, const signed char* F, double* A,
                              Py_ssize_t* idx, Py_ssize_t* piv, double* z,
                              double* big) noexcept nogil:
    """:func:`_basic_solution`'s first part: z = 0, the basic pairs in ``idx``, the block
    ``M_FF`` in ``A`` (stride m) and its largest |entry| in ``big``; returns m."""
    cdef Py_ssize_t i, j, m = 0
    cdef const double* row
    for i in range(n):  # (no branch on the basis: which pairs are basic is data)
        z[i] = 0.0
        idx[m] = i
        m += F[i] != 0
    for i in range(m):
        row = M + idx[i] * n
        for j in range(m):
            A[i * m + j] = row[idx[j]]
    big[0] = _absmax(A, m * m)
    for i in range(m):
        piv[i] = i
    return m


cdef Py_ssize_t _basic_finish(const double* q, Py_ssize_t n, signed char* F, double* A,
                              const Py_ssize_t* idx, const Py_ssize_t* piv, double* r,
                              double* z, Py_ssize_t m, Py_ssize_t k) noexcept nogil:
    """:func:`_basic_solution`'s last part, after ``k`` pivots of the elimination
    (:func:`_basic_rhs`, then the solve); returns the size of the solved block."""
    cdef Py_ssize_t i
    m = _basic_rhs(q, F, A, idx, r, m, k)
    _lu_solve(A, piv, m, r)
    for i in range(m):
        z[idx[i]] = r[i]
    return m


cdef Py_ssize_t _basic_rhs(const double* q, signed char* F, double* A, const Py_ssize_t* idx,
                           double* r, Py_ssize_t m, Py_ssize_t k) noexcept nogil:
    """After ``k`` pivots of the elimination of the m x m block: the repair (the pairs left
    unpivoted leave F), the factors of the solved block compacted, ``r = -q_F``; returns the
    size of the solved block."""
    cdef Py_ssize_t i, j
    for i in range(k, m):  # repair: the pairs left unpivoted leave the basis
        F[idx[i]] = 0
    if k < m:  # the repaired block: the leading k x k factors (stride m) compacted
        for i in range(k):
            for j in range(k):
                A[i * k + j] = A[i * m + j]
        m = k
    for i in range(m):
        r[i] = -q[idx[i]]
    return m


cdef void _refine(const double* M, const double* q, Py_ssize_t n, const double* A,
                  const Py_ssize_t* idx, const Py_ssize_t* piv, Py_ssize_t m, double* r,
                  double* z) noexcept nogil:
    """One step of iterative refinement of the basic solution of :func:`_basic_solution`."""
    cdef Py_ssize_t i, j
    cdef double t
    for i in range(m):
        t = q[idx[i]]
        for j in range(m):
            t = t + M[idx[i] * n + idx[j]] * z[idx[j]]
        r[i] = -t
    _lu_solve(A, piv, m, r)
    for i in range(m):
        z[idx[i]] = z[idx[i]] + r[i]


cdef void _lu_solve(const double* A, const Py_ssize_t* piv, Py_ssize_t m,
                    double* b) noexcept nogil:
    """``b <- (LU)^-1 P b`` for the factors of :func:`_basic_solution` (lcpcli_lu_solve)."""
    cdef Py_ssize_t i
    cdef double t
    for i in range(m):
        if piv[i] != i:
            t = b[i]
            b[i] = b[piv[i]]
            b[piv[i]] = t
    _lu_solve_c(A, m, b)


cdef int _bpp_one(const double* M, const double* q, Py_ssize_t n, const signed char* F0,
                  int64_t max_iter, double tol, double* z, double* w, signed char* state,
                  int64_t* iters, double* err, double* res,
                  double* crow=NULL, signed char* prow=NULL) noexcept nogil:
    """Block principal pivoting from the basis ``F0`` (as lcpcli.solvers.methods.bpp: block
    pivots while the count of infeasible pairs falls, Murty's least-index single pivot after
    W_BLOCK_TRIES without progress), judged by the certificate (:func:`_bpp_run`).  Returns 1
    when an answer passed (z, w, state, iters, err, res filled), 0 otherwise (singular block,
    iteration limit, an answer that stays uncertified: the caller solves cold)."""
    cdef double swork[STACK_N * STACK_N + 8 * STACK_N + 1]
    cdef Py_ssize_t siwork[5 * STACK_N + 1]
    cdef signed char sF[STACK_N + 1]
    cdef bint heap = n > STACK_N  # small problems: scratch on the C stack, no malloc
    cdef double* work = <double*>malloc((n * n + 8 * n + 1) * sizeof(double)) if heap else swork
    cdef Py_ssize_t* iwork = (<Py_ssize_t*>malloc((5 * n + 1) * sizeof(Py_ssize_t)) if heap
                              else siwork)
    cdef signed char* F = <signed char*>malloc(n + 1) if heap else sF
    cdef Py_ssize_t i
    cdef int ok = 0
    if work != NULL and iwork != NULL and F != NULL:
        for i in range(n):
            F[i] = 1 if F0[i] else 0
        ok = _bpp_run(M, q, n, max_iter, tol, z, w, state, iters, err, res, work, iwork, F,
                      -1, crow, prow)
    if heap:
        free(work)
        free(iwork)
        free(F)
    return ok


cdef int _bpp_pair(const double* M0, const double* q0, const signed char* B0, double* z0,
                   double* w0, signed char* st0, int64_t* it0, double* err0, double* res0,
                   const double* M1, const double* q1, const signed char* B1, double* z1,
                   double* w1, signed char* st1, int64_t* it1, double* err1, double* res1,
                   Py_ssize_t n, int64_t max_iter0, int64_t max_iter1, double tol,
                   double* crow0=NULL, double* crow1=NULL, signed char* prow0=NULL,
                   signed char* prow1=NULL) noexcept nogil:
    """:func:`_bpp_one` on two problems of size ``n <= STACK_N``, their first basic solutions
    computed together (:func:`_basic_solution2`); returns bit 0 / bit 1 set when problem 0 / 1
    passed."""
    cdef double work0[STACK_N * STACK_N + 8 * STACK_N + 1]
    cdef double work1[STACK_N * STACK_N + 8 * STACK_N + 1]
    cdef Py_ssize_t iwork0[5 * STACK_N + 1]
    cdef Py_ssize_t iwork1[5 * STACK_N + 1]
    cdef signed char F0[STACK_N + 1]
    cdef signed char F1[STACK_N + 1]
    cdef Py_ssize_t m[2]
    cdef Py_ssize_t i
    for i in range(n):
        F0[i] = 1 if B0[i] else 0
        F1[i] = 1 if B1[i] else 0
    _basic_solution2(M0, q0, F0, work0, iwork0 + 3 * n, iwork0 + 4 * n, work0 + n * n, z0,
                     M1, q1, F1, work1, iwork1 + 3 * n, iwork1 + 4 * n, work1 + n * n, z1,
                     n, m)
    return (_bpp_run(M0, q0, n, max_iter0, tol, z0, w0, st0, it0, err0, res0, work0, iwork0,
                     F0, m[0], crow0, prow0)
            | (_bpp_run(M1, q1, n, max_iter1, tol, z1, w1, st1, it1, err1, res1, work1, iwork1,
                        F1, m[1], crow1, prow1) << 1))


cdef inline int64_t _bpp_iters(const double* M, Py_ssize_t n, int64_t warm_iter) noexcept nogil:
    """The block principal pivoting iterations a warm start may take on ``M``: ``warm_iter``,
    or only the given basis's own basic solution (at most 1) when a diagonal entry is not
    positive: M is then no P-matrix (contact LCPs: the friction slack rows) and Júdice-Pires'
    block pivots carry no guarantee; Lemke from the basis takes over at once."""
    cdef Py_ssize_t i
    for i in range(n):
        if not (M[i * n + i] > 0.0):
            return warm_iter if warm_iter < 1 else 1
    return warm_iter


cdef int _bpp_run(const double* M, const double* q, Py_ssize_t n, int64_t max_iter,
                  double tol, double* z, double* w, signed char* state, int64_t* iters,
                  double* err, double* res, double* work, Py_ssize_t* iwork, signed char* F,
                  Py_ssize_t first_m, double* crow=NULL,
                  signed char* prow=NULL) noexcept nogil:
    """The iterations of :func:`_bpp_one` from the basis ``F`` (modified), in the scratch
    ``work`` (n*n + 8 n doubles: the block's factors, then r, then the certificate's 5 n) and
    ``iwork`` (5 n: the certificate's 3 n, idx, piv).  ``first_m >= 0``: the first basic
    solution is in place already (:func:`_basic_solution`'s outputs, its size ``first_m``).
    A basic solution with ``z_F >= 0`` goes to the certificate first (a basis that is still
    right ends there, with no pass of its own over M); one that fails it is refined once and
    certified again, and its infeasible pairs are read from the certificate's ``w`` and row
    scales."""
    cdef double* A = work
    cdef double* r = work + n * n
    cdef double* cwork = work + n * n + n  # 5 n for the certificate: a, then the row scales s
    cdef double* scale = cwork + n
    cdef Py_ssize_t* idx = iwork + 3 * n
    cdef Py_ssize_t* piv = iwork + 4 * n
    cdef Py_ssize_t i, j, m, count, best = n + 1, first
    cdef int tries = W_BLOCK_TRIES, ok = 0
    cdef int64_t it
    cdef double zmax, t, sc
    cdef bint nonneg, have_w
    cdef CertOut cert
    it = 0
    while it < max_iter:
        it += 1
        if it == 1 and first_m >= 0:
            m = first_m
        else:
            m = _basic_solution(M, q, n, F, A, idx, piv, r, z)
        if m < 0:
            break
        zmax = 1.0  # (selects and flags: which z_i are basic, or large, is data)
        for i in range(n):
            t = fabs(z[i])
            zmax = t if t > zmax else zmax
        t = -W_NEG_TOL * zmax
        nonneg = True
        for i in range(n):
            nonneg &= not (F[i] != 0) & (z[i] < t)
        have_w = False
        if nonneg and (n <= STACK_N or not _plainly_infeasible(M, q, n, F, m, idx, z, tol)):
            if _certify_basic(M, q, n, m, A, idx, piv, r, tol, z, w, cwork, iwork, state,
                              &cert):
                ok = 1
                iters[0] = it
                _keep(&cert, err, res, crow)
                _keep_basis(F, n, prow)
                break
            have_w = cert.status == 0  # w and the row scales of this z are in place
        count = 0
        first = -1
        for i in range(n):  # infeasible pairs: marked in r (1.0) for the flip
            r[i] = 0.0
            if F[i]:
                if z[i] < -W_NEG_TOL * zmax:
                    r[i] = 1.0
            else:
                if have_w:
                    t, sc = w[i], scale[i]
                else:
                    t = q[i]
                    sc = fabs(q[i])
                    for j in range(n):
                        t = t + M[i * n + j] * z[j]
                        sc = sc + fabs(M[i * n + j] * z[j])
                if t < -W_NEG_TOL * sc:
                    r[i] = 1.0
            if r[i] != 0.0:
                count += 1
                if first < 0:
                    first = i
        if count == 0:  # every basic variable nonnegative, but no certified answer
            break
        if count < best:
            best = count
            tries = W_BLOCK_TRIES
        elif tries > 0:
            tries -= 1
        else:  # Murty's least-index rule: one pivot (finite on P-matrices)
            F[first] = 1 - F[first]
            continue
        for i in range(n):
            if r[i] != 0.0:
                F[i] = 1 - F[i]
    return ok


cdef bint _plainly_infeasible(const double* M, const double* q, Py_ssize_t n,
                             const signed char* F, Py_ssize_t m, const Py_ssize_t* idx,
                             const double* z, double tol) noexcept nogil:
    """Is a nonbasic pair of the basic solution ``z`` (``z_i = 0``, ``i`` not in ``F``)
    infeasible by more than twice ``tol`` of its row's scale, its ``w_i`` and scale summed
    over the basic ``z_j`` above rounding level (``> TINY_Z ||z||``: the ones
    :func:`_zero_tiny` keeps)?  Such a pair scores ``eps_i = |w_i| / s_i > tol``
    (docs/certificate.md: ``z_i = 0`` needs ``w_i >= 0``), so the certificate is not
    computed: O((n - m) m) here against a certificate's passes over all of M, on the many
    warm bases that are wrong (a choice of speed only: the pivoting goes on, and only a
    certified answer counts).  Asked above n = STACK_N only: on small problems the
    certificate costs about as much and most warm bases are right."""
    cdef Py_ssize_t i, a, j
    cdef double zmax = 0.0, t, sc, term, small
    for a in range(m):
        t = fabs(z[idx[a]])
        zmax = t if t > zmax else zmax
    small = TINY_Z * zmax
    for i in range(n):
        if F[i] != 0:
            continue
        t = q[i]
        sc = fabs(q[i])
        for a in range(m):
            j = idx[a]
            if fabs(z[j]) > small:
                term = M[i * n + j] * z[j]
                t = t + term
                sc = sc + fabs(term)
        if t < -2.0 * tol * sc:
            return True
    return False


cdef int _certify_basic(const double* M, const double* q, Py_ssize_t n, Py_ssize_t m,
                        const double* A, const Py_ssize_t* idx, const Py_ssize_t* piv,
                        double* r, double tol, double* z, double* w, double* cwork,
                        Py_ssize_t* iwork, signed char* state, CertOut* cert) noexcept nogil:
    """Certify the basic solution ``z`` of :func:`_basic_solution` (its factors in ``A``): as
    solved; then with its entries at rounding level set to exactly 0 (:func:`_zero_tiny`); then
    refined once; then refined and with those entries set to 0.  A step that leaves ``z`` as it
    was (no entry at rounding level) is not certified again.  Returns 1 when one passed."""
    cdef int step
    for step in range(4):
        if step == 1 or step == 3:
            if not _zero_tiny(z, n):
                continue
        elif step == 2:
            if m == 0:
                return 0
            _refine(M, q, n, A, idx, piv, m, r, z)
        _onto_bounds(z, n)
        certify_dense(n, M, n, q, z, 0, NULL, NULL, w, cwork, iwork, state, cert)
        if _passed(cert, tol):
            return 1
    return 0


cdef inline void _onto_bounds(double* z, Py_ssize_t n) noexcept nogil:
    """A basic ``z_i`` the factorisation left below 0 (rounding, e.g. -1e-16) moved onto its
    bound, as the dispatcher does for one problem (:meth:`lcpcli.core.problem.Problem.inside`)
    before the certificate, which judges that move anyway."""
    cdef Py_ssize_t i
    for i in range(n):
        if z[i] < 0.0:
            z[i] = 0.0


cdef int _ppt_lemke_one(const double* M, const double* q, Py_ssize_t n,
                        const signed char* F0, int64_t max_iter, double piv_tol,
                        double tie_tol, double tol, double* z, double* w, signed char* state,
                        int64_t* iters, double* err, double* res,
                        double* crow=NULL, signed char* prow=NULL) noexcept nogil:
    """Lemke with the covering ray started from the basis ``F0`` (lcpcli.solvers.methods.
    lemke_warm's method, compiled): the principal pivot transform of (q, M) on F
    (Cottle-Pang-Stone section 2.3: ``M'_FF = M_FF^-1``, ``M'_FG = -M_FF^-1 M_FG``,
    ``M'_GF = M_GF M_FF^-1``, ``M'_GG = M_GG - M_GF M_FF^-1 M_FG``, ``q'_F = -M_FF^-1 q_F``,
    ``q'_G = q_G - M_GF M_FF^-1 q_F``) turns the basis F into the all-w basis and the covering
    vector ``B e`` into ``e``, so cold Lemke (:c:func:`lemke_tableau`) on (q', M') is Lemke
    from F; its final basis, mapped back (``z_i`` basic for i in F when ``w'_i`` is, for i
    not in F when ``z'_i`` is), is solved on (q, M) afresh and certified
    (:func:`_certify_basic`).  A singular ``M_FF`` is repaired first (:func:`_basic_solution`).
    Returns 1 when an answer passed (z, w, state, iters, err, res filled), else 0."""
    cdef double* work = <double*>malloc((3 * n * n + 12 * n + 4) * sizeof(double))
    cdef Py_ssize_t* iwork = <Py_ssize_t*>malloc((7 * n + 4) * sizeof(Py_ssize_t))
    cdef int64_t* basic = <int64_t*>malloc((n + 1) * sizeof(int64_t))
    cdef signed char* F = <signed char*>malloc(n + 1)
    cdef double* X
    cdef double* A
    cdef double* Mp
    cdef double* qp
    cdef double* r
    cdef double* zt
    cdef double* ray
    cdef double* d
    cdef double* col
    cdef double* cwork
    cdef Py_ssize_t* idx
    cdef Py_ssize_t* piv
    cdef Py_ssize_t* pos
    cdef Py_ssize_t i, j, a, m, p
    cdef double t
    cdef int ok = 0, rc
    cdef LemkeOut out
    cdef CertOut cert
    if work == NULL or iwork == NULL or basic == NULL or F == NULL:
        free(work)
        free(iwork)
        free(basic)
        free(F)
        return 0
    A = work
    Mp = A + n * n
    qp = Mp + n * n
    r = qp + n
    zt = r + n
    ray = zt + n
    d = ray + n
    col = d + n
    cwork = col + n  # 5 n
    X = cwork + 5 * n  # n * n
    idx = iwork + 3 * n  # the certificate takes the first 3 n
    piv = idx + n
    pos = piv + n
    for i in range(n):
        F[i] = 1 if F0[i] else 0
        d[i] = 1.0
    m = _basic_solution(M, q, n, F, A, idx, piv, r, z)  # F repaired when M_FF is singular
    for i in range(n):
        pos[i] = -1
    for a in range(m):
        pos[idx[a]] = a
    # X = M_FF^-1 [columns j of F: e_pos(j); others: M_Fj] (m x n, row-major; the rows of the
    # factors are swept with vector axpys), the columns not in F negated: the rows of M' in F
    for a in range(m):
        for j in range(n):
            p = pos[j]
            X[a * n + j] = (1.0 if p == a else 0.0) if p >= 0 else M[idx[a] * n + j]
    for i in range(m):  # L (unit lower) then U, as _lu_solve does for one column
        for j in range(i):
            axpy(X + i * n, X + j * n, -A[i * m + j], n)
    for i in range(m - 1, -1, -1):
        for j in range(i + 1, m):
            axpy(X + i * n, X + j * n, -A[i * m + j], n)
        t = A[i * m + i]
        for j in range(n):
            X[i * n + j] = X[i * n + j] / t
    for a in range(m):
        for j in range(n):
            if pos[j] < 0:
                X[a * n + j] = -X[a * n + j]
        for j in range(n):
            Mp[idx[a] * n + j] = X[a * n + j]
    for i in range(n):  # rows not in F: M_iG (0 on F) + M_iF X
        if pos[i] >= 0:
            continue
        for j in range(n):
            Mp[i * n + j] = 0.0 if pos[j] >= 0 else M[i * n + j]
        for a in range(m):
            t = M[i * n + idx[a]]
            if t != 0.0:
                axpy(Mp + i * n, X + a * n, t, n)
    for i in range(n):  # q'_F = z_F (the basic solution), q'_G = w_G
        if pos[i] >= 0:
            qp[i] = z[i]
        else:
            t = q[i]
            for a in range(m):
                t = t + M[i * n + idx[a]] * z[idx[a]]
            qp[i] = t
    rc = lemke_tableau(Mp, qp, d, n, max_iter, piv_tol, tie_tol, NULL, 0, zt, basic, ray, &out)
    if rc == 0 and (out.status == LEMKE_OK or out.status == LEMKE_TRIVIAL):
        # the original basis: z_i basic for i in F when w'_i is, else when z'_i is
        for i in range(n):
            col[i] = 0.0  # marks of basic w' (col) and z' (ray)
            ray[i] = 0.0
        if out.status == LEMKE_OK:
            for a in range(n):
                if basic[a] < n:
                    col[basic[a]] = 1.0
                elif basic[a] < 2 * n:
                    ray[basic[a] - n] = 1.0
        else:  # q' >= 0: the all-w' basis
            for i in range(n):
                col[i] = 1.0
        for i in range(n):
            F[i] = 1 if (F[i] and col[i] != 0.0) or (not F[i] and ray[i] != 0.0) else 0
        m = _basic_solution(M, q, n, F, A, idx, piv, r, z)
        if _certify_basic(M, q, n, m, A, idx, piv, r, tol, z, w, cwork, iwork, state, &cert):
            ok = 1
            iters[0] = out.pivots + 1
            _keep(&cert, err, res, crow)
            _keep_basis(F, n, prow)
    free(work)
    free(iwork)
    free(basic)
    free(F)
    return ok


cdef void _sor_one(const double* M, const double* q, const double* lo_in, const double* up_in,
                   Py_ssize_t n, double omega, int64_t max_iter, double tol, double* z,
                   double* w, signed char* code, int64_t* iters, double* err,
                   double* res, double* crow=NULL) noexcept nogil:
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
            _keep(&cert, err, res, crow)
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
    cdef cnp.ndarray Ma, qa, zo, wo, co, io, eo, ro, cto, pvo
    cdef Py_ssize_t K, n
    cdef const double* M
    cdef const double* q
    cdef double* z
    cdef double* w
    cdef signed char* code
    cdef int64_t* iters
    cdef double* err
    cdef double* residual
    cdef double* cert  # NULL: no certificate rows asked for
    cdef signed char* pv  # NULL: no pivoting bases asked for


cdef _Stack _checked(M, q, z, w, code, iters, err, residual, str name, cert=None,
                     pivot_basis=None):
    """``M`` (K, n, n) and ``q`` (K, n) as float64 (views when they are), and the preallocated
    outputs (``inout``: no silent copies; ``cert``: None or (K, :data:`CERT_FIELDS`) float64,
    each certified answer's certificate, the rest left as they are; ``pivot_basis``: None or
    (K, n) int8, each certified answer's complementary basis, 1 where z_i is basic); ValueError
    on a wrong shape."""
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
    a.cert = NULL
    if cert is not None:
        a.cto = inout(cert, cnp.NPY_FLOAT64, a.K, C_FIELDS)
        a.cert = f64_ptr(a.cto)
    a.pv = NULL
    if pivot_basis is not None:
        a.pvo = inout(pivot_basis, cnp.NPY_INT8, a.K, a.n)
        a.pv = <signed char*>cnp.PyArray_DATA(a.pvo)
    return a


cdef cnp.ndarray _stack(object a, Py_ssize_t ndim):
    """``a`` as a C-contiguous float64 array of ``ndim`` dimensions (a view when it is one)."""
    return cnp.PyArray_FROMANY(a, cnp.NPY_FLOAT64, ndim, ndim,
                               cnp.NPY_ARRAY_C_CONTIGUOUS | cnp.NPY_ARRAY_ALIGNED)


cdef const int* _balance_args(object balance, int* eqv) except? NULL:
    """``eqv`` filled from ``balance`` ((balanced, q_balanced, max_rounds)) and returned, or
    NULL when ``balance`` is None (no equilibration)."""
    if balance is None:
        return NULL
    eqv[0], eqv[1], eqv[2] = balance
    return eqv


cdef cnp.ndarray _covering(object d, Py_ssize_t n, str label):
    """The covering vector as a float64 array of length ``n`` (None: ones, not stored)."""
    if d is None:
        return None
    cdef cnp.ndarray da = _stack(d, 1)
    if cnp.PyArray_DIM(da, 0) != n:
        raise ValueError(f"{label}: the covering vector must have length n")
    return da


def lemke_stack(M, q, d, int64_t max_iter, double piv_tol, double tie_tol, double tol,
                z, w, code, iters, err, residual, int threads, balance=None,
                double polished=0.0, cert=None, pivot_basis=None):
    """Lemke (tableau) on every problem of the stack ``M`` (K, n, n), ``q`` (K, n).

    ``d``: the covering vector (n,), or None for all ones.  Outputs (preallocated,
    C-contiguous): ``z``, ``w`` (K, n) float64, ``code`` (K,) int8, ``iters`` (K,) int64,
    ``err`` and ``residual`` (K,) float64 (the certificate's; inf / NaN where none); see the
    module docstring.  ``threads``: OpenMP threads (>= 1).
    ``balance``: None (no equilibration) or ``(balanced, q_balanced, max_rounds)`` of
    :mod:`lcpcli.analysis.scaling`: each problem that is not balanced is equilibrated first.
    ``polished``: the end basis is re-solved unless the certified error is at most this
    (:data:`lcpcli.core.tolerances.POLISHED`; 0: always).  ``cert``: None, or (K,
    :data:`CERT_FIELDS`) float64 receiving each certified answer's certificate (:func:`_keep`);
    ``pivot_basis``: None, or (K, n) int8 receiving each certified answer's complementary basis
    (1: z_i basic, 0: w_i basic; rows of the others left as they are).
    """
    cdef int eqv[3]
    cdef const int* eq = _balance_args(balance, eqv)
    cdef _Stack a = _checked(M, q, z, w, code, iters, err, residual, "lemke_stack", cert,
                             pivot_basis)
    cdef Py_ssize_t K = a.K, n = a.n, nn = a.n * a.n, k
    cdef cnp.ndarray da = _covering(d, n, "lemke_stack")
    cdef double* dp = NULL if da is None else f64_ptr(da)
    if _empty(a):
        return
    for k in prange(K, nogil=True, schedule="dynamic", chunksize=16,
                    num_threads=threads if threads > 0 else 1):
        _lemke_one(a.M + k * nn, a.q + k * n, dp, n, max_iter, piv_tol, tie_tol, tol, polished,
                   eq, a.z + k * n, a.w + k * n, a.code + k, a.iters + k, a.err + k,
                   a.residual + k, NULL, _row(a.cert, k), _prow(a.pv, k, n))


def lemke_warm_stack(M, q, d, basis, int64_t max_iter, int64_t warm_iter,
                     int64_t warm_pivots, double piv_tol, double tie_tol, double tol, z, w,
                     code, iters, err, residual, state, warm, int threads, balance=None,
                     double polished=0.0, cert=None, pivot_basis=None):
    """Warm-started stack: problem k starts from its basis ``basis[k]`` ((K, n) int8, 1: z_i
    basic; a row whose first entry is negative has none): block principal pivoting for at most
    ``warm_iter`` iterations (:func:`_bpp_one`: one factorisation of ``M_FF`` when the basis is
    still right; 1 on a matrix with a diagonal entry that is not positive, :func:`_bpp_iters`),
    then Lemke with the covering ray from that basis for at most
    ``warm_pivots`` pivots (:func:`_ppt_lemke_one`); an answer that passes the certificate is
    kept (``warm[k]`` = 1), any other ending runs Lemke cold on it in the same call
    (:func:`lemke_stack`'s arguments and outputs).  ``state`` ((K, n) int8) receives each
    certified answer's basis (the certificate's pair states) for the next step.  Problems go
    in pairs: two problems of n <= STACK_N that both have a basis start together
    (:func:`_bpp_pair`: their first basic solutions factored and solved in turn, the same
    numbers as one by one).  ``cert``, ``pivot_basis``: as :func:`lemke_stack`'s.
    """
    cdef int eqv[3]
    cdef const int* eq = _balance_args(balance, eqv)
    cdef _Stack a = _checked(M, q, z, w, code, iters, err, residual, "lemke_warm_stack",
                             cert, pivot_basis)
    cdef Py_ssize_t K = a.K, n = a.n, nn = a.n * a.n, k
    cdef cnp.ndarray da = _covering(d, n, "lemke_warm_stack")
    cdef double* dp = NULL if da is None else f64_ptr(da)
    cdef cnp.ndarray ba = inout(basis, cnp.NPY_INT8, K, n)
    cdef cnp.ndarray sa = inout(state, cnp.NPY_INT8, K, n)
    cdef cnp.ndarray wa = inout(warm, cnp.NPY_INT8, K, -1)
    cdef signed char* bp = <signed char*>cnp.PyArray_DATA(ba)
    cdef signed char* sp = <signed char*>cnp.PyArray_DATA(sa)
    cdef signed char* wp = <signed char*>cnp.PyArray_DATA(wa)
    cdef Py_ssize_t kk
    cdef int ok
    if _empty(a):
        return
    for kk in prange((K + 1) // 2, nogil=True, schedule="dynamic", chunksize=32,
                     num_threads=threads if threads > 0 else 1):
        # problems in pairs: two small problems that both have a basis start together
        k = 2 * kk
        if k + 2 < K:
            _prefetch(a.M + (k + 2) * nn, 2 * nn if k + 3 < K else nn)
        ok = 0
        if k + 1 < K and n <= STACK_N and bp[k * n] >= 0 and bp[(k + 1) * n] >= 0:
            ok = _bpp_pair(a.M + k * nn, a.q + k * n, bp + k * n, a.z + k * n, a.w + k * n,
                           sp + k * n, a.iters + k, a.err + k, a.residual + k,
                           a.M + (k + 1) * nn, a.q + (k + 1) * n, bp + (k + 1) * n,
                           a.z + (k + 1) * n, a.w + (k + 1) * n, sp + (k + 1) * n,
                           a.iters + k + 1, a.err + k + 1, a.residual + k + 1, n,
                           _bpp_iters(a.M + k * nn, n, warm_iter),
                           _bpp_iters(a.M + (k + 1) * nn, n, warm_iter), tol, _row(a.cert, k),
                           _row(a.cert, k + 1), _prow(a.pv, k, n), _prow(a.pv, k + 1, n))
        else:
            if bp[k * n] >= 0:
                ok = _bpp_one(a.M + k * nn, a.q + k * n, n, bp + k * n,
                              _bpp_iters(a.M + k * nn, n, warm_iter), tol,
                              a.z + k * n, a.w + k * n, sp + k * n, a.iters + k, a.err + k,
                              a.residual + k, _row(a.cert, k), _prow(a.pv, k, n))
            if k + 1 < K and bp[(k + 1) * n] >= 0:
                ok = ok | (_bpp_one(a.M + (k + 1) * nn, a.q + (k + 1) * n, n,
                                    bp + (k + 1) * n,
                                    _bpp_iters(a.M + (k + 1) * nn, n, warm_iter), tol,
                                    a.z + (k + 1) * n,
                                    a.w + (k + 1) * n, sp + (k + 1) * n, a.iters + k + 1,
                                    a.err + k + 1, a.residual + k + 1, _row(a.cert, k + 1),
                                    _prow(a.pv, k + 1, n)) << 1)
        _warm_rest(a, k, ok & 1, n, nn, bp, sp, wp, dp, eq, max_iter, warm_pivots, piv_tol,
                   tie_tol, tol, polished)
        if k + 1 < K:
            _warm_rest(a, k + 1, ok >> 1, n, nn, bp, sp, wp, dp, eq, max_iter, warm_pivots,
                       piv_tol, tie_tol, tol, polished)


cdef inline void _warm_rest(_Stack a, Py_ssize_t k, int bpp_ok, Py_ssize_t n, Py_ssize_t nn,
                            const signed char* bp, signed char* sp, signed char* wp,
                            const double* dp, const int* eq, int64_t max_iter,
                            int64_t warm_pivots, double piv_tol, double tie_tol, double tol,
                            double polished) noexcept nogil:
    """Problem k of :func:`lemke_warm_stack` after its block principal pivoting (``bpp_ok``:
    passed): else Lemke from its basis, else cold Lemke."""
    wp[k] = 0
    if bpp_ok or (bp[k * n] >= 0 and _ppt_lemke_one(
            a.M + k * nn, a.q + k * n, n, bp + k * n, warm_pivots, piv_tol, tie_tol, tol,
            a.z + k * n, a.w + k * n, sp + k * n, a.iters + k, a.err + k, a.residual + k,
            _row(a.cert, k), _prow(a.pv, k, n))):
        wp[k] = 1
        a.code[k] = B_SOLVED
    else:
        _lemke_one(a.M + k * nn, a.q + k * n, dp, n, max_iter, piv_tol, tie_tol, tol,
                   polished, eq, a.z + k * n, a.w + k * n, a.code + k, a.iters + k,
                   a.err + k, a.residual + k, sp + k * n, _row(a.cert, k), _prow(a.pv, k, n))


def sor_stack(M, q, lo, up, double omega, int64_t max_iter, double tol, z, w, code, iters,
              err, residual, int threads, cert=None):
    """Projected SOR (``omega = 1``: Gauss-Seidel) on every problem of the stack.

    ``lo``/``up``: None (LCP: ``z >= 0``) or bounds of shape (K, n) (box LCP).  ``z`` (K, n)
    holds the start points (inside the bounds) and receives the answers; the other outputs
    (and ``cert``) as :func:`lemke_stack`.
    """
    cdef _Stack a = _checked(M, q, z, w, code, iters, err, residual, "sor_stack", cert)
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
                 a.w + k * n, a.code + k, a.iters + k, a.err + k, a.residual + k, _row(a.cert, k))

