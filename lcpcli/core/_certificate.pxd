# C-level entry of the certificate, for kernels that certify inside one compiled call.
# See _certificate.pyx for the definition; the Python entry is lcpcli.core.certificate.certify.

cdef struct CertOut:
    double error            # the certified error (componentwise backward error x block growth)
    double backward_error   # omega: componentwise backward error of the pairs
    double growth           # growth of the block that holds the worst row (>= 1)
    double residual         # ||mid(z - l, z - u, w)||_inf, in the units of the data
    double bound_violation
    double w_violation
    double complementarity
    double equality_residual
    Py_ssize_t worst        # 0-based index of the pair that decides `error` (-1 when n = 0)
    int status              # 0 ok, 1 non-finite z or w, 2 out of range: rescale and retry

# Dense M (row-major, row stride ldm).  lo/up may be NULL: then the first n_eq variables are
# free and the rest are bounded below by 0 (LCP / MLCP).  w (n) receives M z + q.
# work: 5 n doubles; iwork: 3 n Py_ssize_t; state (n, may be NULL) receives each pair's
# state (0 at lower, 1 at upper, 2 between with w = 0).  Returns out.status.
cdef int certify_dense(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* q,
                       const double* z, Py_ssize_t n_eq, const double* lo, const double* up,
                       double* w, double* work, Py_ssize_t* iwork, signed char* state,
                       CertOut* out) noexcept nogil
