# C-level interface of the tableau Lemke kernel and the helpers the other pivoting kernels share.
from libc.stdint cimport int64_t

cdef enum:
    LEMKE_OK = 0
    LEMKE_RAY = 1
    LEMKE_MAX_ITER = 2
    LEMKE_TRIVIAL = 3
    LEMKE_SINGULAR = 4
    LEMKE_NO_MEMORY = -1

cdef struct LemkeOut:
    int status
    int64_t pivots
    double z0
    double dz0
    int64_t refactors

cdef void pivot(double* T, double* qb, Py_ssize_t nrows, Py_ssize_t ncols, Py_ssize_t r,
                Py_ssize_t c, double* rowr) noexcept nogil
cdef Py_ssize_t initial_row(const double* q, const double* d, Py_ssize_t n,
                            double tie_tol) noexcept nogil
cdef Py_ssize_t ratio_candidates(const double* col, const double* qb, const int64_t* basic,
                                 Py_ssize_t n, int64_t nz, double piv_tol, double tie_tol,
                                 int64_t* cand, Py_ssize_t* z0_row,
                                 double* colmax) noexcept nogil
cdef double lex_unit(const double* col, const int64_t* cand, Py_ssize_t nc) noexcept nogil
cdef Py_ssize_t keep_lex_min(const double* keys, int64_t* cand, Py_ssize_t nc,
                             double unit) noexcept nogil
cdef void basic_solution(const int64_t* basic, const double* qb, const double* col,
                         int64_t entering, bint ray, Py_ssize_t n, double* z, double* ray_dz,
                         double* z0, double* dz0) noexcept nogil
cdef int lemke_tableau(const double* M, const double* q, const double* d, Py_ssize_t n,
                       int64_t max_iter, double piv_tol, double tie_tol, int64_t* record,
                       Py_ssize_t nrec, double* z, int64_t* basic, double* ray_dz,
                       LemkeOut* out) noexcept nogil
cdef double min_residual(const double* M, const double* q, const double* z,
                         Py_ssize_t n) noexcept nogil
cdef int polish(const double* M, const double* q, Py_ssize_t n, const double* z,
                const int64_t* basic, double* out) noexcept nogil
cdef double* _ones(Py_ssize_t n) noexcept nogil
cdef list basis_list(const int64_t* basic, Py_ssize_t n)
cdef int64_t default_pivot_limit(int64_t n) noexcept nogil
