# C-level interface of the projected Gauss-Seidel / SOR kernel (for the batched driver).
from libc.stdint cimport int64_t

cdef enum:
    PGS_CONVERGED = 0
    PGS_LIMIT = 1
    PGS_DIVERGED = 2

cdef int pgs_sweeps(const double* M, const int64_t* indptr, const int64_t* indices,
                    const double* data, const double* q, const double* diag, const double* lo,
                    const double* up, double* z, Py_ssize_t n, double omega, int64_t max_iter,
                    double tol, double mu, double qnorm, int64_t* sweeps,
                    double* err_out) noexcept nogil
