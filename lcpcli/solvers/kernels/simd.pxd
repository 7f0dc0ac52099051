# The kernels' vector loops (simd.h: an AVX2 and a baseline clone, picked by the CPU at load)
# and their allocator of large work arrays (huge pages on Linux).
cdef extern from "simd.h" nogil:
    void axpy "lcpcli_axpy"(double* y, const double* x, double a, Py_ssize_t n) noexcept
    void axpy_scaled "lcpcli_axpy_scaled"(double* y, const double* x, double a, double b,
                                          Py_ssize_t n) noexcept
    double dot4 "lcpcli_dot4"(const double* x, const double* y, Py_ssize_t n) noexcept
    void* big_alloc "lcpcli_alloc"(size_t size) noexcept
