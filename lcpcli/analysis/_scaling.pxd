# C-level interface of the equilibration (Ruiz on binary exponents), for kernels that balance
# each problem of a stack inside one compiled call.  See _scaling.pyx.

cdef int _ruiz(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* data,
               const Py_ssize_t* indices, const Py_ssize_t* indptr, const double* q,
               bint symmetric, int balanced, int q_balanced, int max_rounds,
               long long* r, long long* c, long long* rmax, long long* cmax) noexcept nogil
cdef bint _symmetric(const double* M, Py_ssize_t n) noexcept nogil
cdef bint _balanced(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* q,
                    int balanced, int q_balanced, long long* work) noexcept nogil
