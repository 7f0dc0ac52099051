# Small dense linear algebra for the kernels (row-major, nogil), with LAPACK for large sizes.
from libc.stdint cimport int64_t

cdef int lu_factor(double* a, Py_ssize_t m, int* ipiv) noexcept nogil
cdef void lu_solve(const double* lu, Py_ssize_t m, const int* ipiv, double* b) noexcept nogil
cdef int invert(const double* a, Py_ssize_t m, double* out, double* work, int* ipiv) noexcept nogil
cdef int solve_refined(const double* a, Py_ssize_t m, double* x, double* lu, double* r,
                       int* ipiv) noexcept nogil
cdef Py_ssize_t lapack_min() noexcept nogil
cdef int ensure_lapack(Py_ssize_t m) except -1
