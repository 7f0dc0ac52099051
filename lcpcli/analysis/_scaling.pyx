# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""Compiled core of :mod:`lcpcli.analysis.scaling`: Ruiz's iteration on binary exponents.

Integer arithmetic only (``ilogb``): the factors are powers of two, so nothing is rounded, and a
problem that is balanced already costs one pass over its nonzeros.
"""

from libc.math cimport INFINITY, ilogb
from libc.stdint cimport uint64_t
from libc.string cimport memcpy
from libc.stdlib cimport free, malloc

cimport numpy as cnp

from lcpcli.core.arrays cimport _as, f64, f64_ptr

cnp.import_array()

cdef long long FLOOR = -(1 << 40)
cdef int EXP_HIGH = 0x7ff00000  # the exponent field of a double, in its high 32 bits
cdef enum:
    FAST_MAX_N = 1024  # the fast balance pass keeps one int per column on the stack


cdef bint _little_endian() noexcept nogil:
    """Whether a double's high 32 bits are its second word in memory."""
    cdef double one = 1.0
    cdef int words[2]
    memcpy(words, &one, 8)
    return words[1] == 0x3ff00000


cdef bint LITTLE_ENDIAN = _little_endian()


cdef inline long long _exp(double x) noexcept nogil:
    """e with |x| in [2^(e-1), 2^e) (frexp's exponent); x != 0, finite.

    Read from the IEEE-754 exponent bits (a shift and a mask: ilogb is a library call per
    entry, a third of a small solve's time); subnormals go through ilogb."""
    cdef uint64_t bits
    memcpy(&bits, &x, 8)
    cdef long long field = <long long> ((bits >> 52) & 0x7ff)
    if field == 0:
        return <long long> ilogb(x) + 1
    return field - 1022


cdef inline void _maxima(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* data,
                         const Py_ssize_t* indices, const Py_ssize_t* indptr,
                         const long long* r, const long long* c, long long* rmax,
                         long long* cmax) noexcept nogil:
    """Row and column maxima of the exponents of ``D_r M D_c`` over the nonzeros (FLOOR for
    a row or column without one)."""
    cdef Py_ssize_t i, j, p
    cdef long long e
    cdef bint dense = M != NULL
    for i in range(n):
        rmax[i] = FLOOR
        cmax[i] = FLOOR
    for i in range(n):
        if dense:
            for j in range(n):
                if M[i * ldm + j] != 0.0:
                    e = _exp(M[i * ldm + j]) + r[i] + c[j]
                    if e > rmax[i]:
                        rmax[i] = e
                    if e > cmax[j]:
                        cmax[j] = e
        else:
            for p in range(indptr[i], indptr[i + 1]):
                if data[p] != 0.0:
                    j = indices[p]
                    e = _exp(data[p]) + r[i] + c[j]
                    if e > rmax[i]:
                        rmax[i] = e
                    if e > cmax[j]:
                        cmax[j] = e


cdef inline bint _first_maxima(Py_ssize_t n, const double* M, Py_ssize_t ldm,
                               long long* rmax, long long* cmax) noexcept nogil:
    """:func:`_maxima` of the unscaled dense M (``r = c = 0``), the balance test's pass, for
    n <= FAST_MAX_N: the largest exponent field in a row or column is the exponent of its
    largest entry.  The fields are read as the high 32 bits of each double (masked, they are
    non-negative ints, whose maximum the compiler vectorises: 3x faster than the general
    loop).  Returns 0, so that the general loop decides, when n is larger, the platform is not
    little-endian, or a row or column has no normal number (all zeros, or its largest entry
    subnormal: its exponent field is 0)."""
    cdef Py_ssize_t i, j
    cdef int bits, best
    cdef int col[FAST_MAX_N]
    cdef const char* row
    if n > FAST_MAX_N or not LITTLE_ENDIAN:
        return 0
    for j in range(n):
        col[j] = 0
    for i in range(n):
        row = <const char*> (M + i * ldm)
        best = 0
        for j in range(n):
            memcpy(&bits, row + 8 * j + 4, 4)  # the high word (no type punning)
            bits = bits & EXP_HIGH
            best = bits if bits > best else best
            col[j] = bits if bits > col[j] else col[j]
        if best == 0:
            return 0
        rmax[i] = <long long> (best >> 20) - 1022
    for j in range(n):
        if col[j] == 0:
            return 0
        cmax[j] = <long long> (col[j] >> 20) - 1022
    return 1


cdef inline bint _round_balanced(Py_ssize_t n, const double* M, Py_ssize_t ldm,
                                 const double* data, const Py_ssize_t* indices,
                                 const Py_ssize_t* indptr, const long long* r,
                                 const long long* c, long long* rmax, long long* cmax,
                                 int balanced, int rnd) noexcept nogil:
    """One round's test of :c:func:`_ruiz`: the row and column maxima of the exponents of
    ``D_r M D_c`` (zero rows and columns count as 1) are within ``2^balanced`` of each other
    and the largest row maximum within ``2^balanced`` of 1.  Fills rmax, cmax."""
    cdef Py_ssize_t i
    cdef long long lo = 1 << 40, hi = -(1 << 40), clo = 1 << 40, chi = -(1 << 40)
    if rnd == 0 and M != NULL and _first_maxima(n, M, ldm, rmax, cmax):
        pass  # the exponent maxima of the unscaled matrix, read from the bits
    else:
        _maxima(n, M, ldm, data, indices, indptr, r, c, rmax, cmax)
    for i in range(n):
        if rmax[i] == FLOOR:
            rmax[i] = 1
        if cmax[i] == FLOOR:
            cmax[i] = 1
        if rmax[i] < lo:
            lo = rmax[i]
        if rmax[i] > hi:
            hi = rmax[i]
        if cmax[i] < clo:
            clo = cmax[i]
        if cmax[i] > chi:
            chi = cmax[i]
    return hi - lo <= balanced and chi - clo <= balanced and -balanced <= hi - 1 <= balanced


cdef inline long long _q_shift(Py_ssize_t n, const double* q, const long long* r) noexcept nogil:
    """The exponent ``k`` of the common factor that brings the largest entry of ``D_r q`` to
    ``[1/2, 1)`` (0 when q = 0)."""
    cdef Py_ssize_t i
    cdef long long e, qexp = FLOOR
    for i in range(n):
        if q[i] != 0.0:
            e = _exp(q[i]) + r[i]
            if e > qexp:
                qexp = e
    return 0 if qexp == FLOOR else -qexp + 1


cdef int _ruiz(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* data,
               const Py_ssize_t* indices, const Py_ssize_t* indptr, const double* q,
               bint symmetric, int balanced, int q_balanced, int max_rounds,
               long long* r, long long* c, long long* rmax, long long* cmax) noexcept nogil:
    """Fill r, c; return 1 when a scaling is needed, 0 when the problem is balanced."""
    cdef Py_ssize_t i, j, k
    cdef long long d
    cdef int rnd, needed
    for i in range(n):
        r[i] = 0
        c[i] = 0
    for rnd in range(max_rounds):
        if _round_balanced(n, M, ldm, data, indices, indptr, r, c, rmax, cmax, balanced, rnd):
            break
        if symmetric:
            for i in range(n):
                d = rmax[i] if rmax[i] > cmax[i] else cmax[i]
                d = _floordiv2(1 - d)
                r[i] += d
                c[i] += d
        else:
            for i in range(n):
                r[i] -= _floordiv2(rmax[i] - 1)
            # column maxima after the row step (the row maxima it also fills are not used)
            _maxima(n, M, ldm, data, indices, indptr, r, c, rmax, cmax)
            for j in range(n):
                if cmax[j] == FLOOR:
                    cmax[j] = 1
                c[j] -= _floordiv2(cmax[j] - 1)
    # a common factor normalising q (M unchanged: rows x 2^k, columns x 2^-k)
    k = _q_shift(n, q, r)
    needed = 0
    for i in range(n):
        if r[i] != 0 or c[i] != 0:
            needed = 1
            break
    if not needed and -q_balanced <= k <= q_balanced:
        return 0
    for i in range(n):
        r[i] += k
        c[i] -= k
    return 1


cdef inline long long _floordiv2(long long x) noexcept nogil:
    """Floor division by 2 for negative numbers too (Python's //)."""
    if x >= 0:
        return x // 2
    return -((-x + 1) // 2)


def ruiz_exponents(M, q, bint symmetric, int balanced, int q_balanced, int max_rounds):
    """``(row, col)`` exponent arrays (int64) of the balancing scaling, or None if balanced.

    ``M``: C-contiguous float64 (n, n) array, or a ``(data, indices, indptr)`` CSR triple with
    ``intp`` index arrays.  See :func:`lcpcli.analysis.scaling.equilibrate`.  Arguments go
    through numpy's C API (no typed memoryviews: a microsecond each on small problems).
    """
    cdef cnp.ndarray qa = f64(q, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(qa, 0)
    cdef cnp.ndarray Ma, da, ia, pa
    cdef cnp.ndarray ra, ca
    cdef long long* rmax
    cdef long long* cmax
    cdef const double* pM = NULL
    cdef const double* pd = NULL
    cdef const Py_ssize_t* pi = NULL
    cdef const Py_ssize_t* pp = NULL
    cdef int needed
    if n == 0:
        return None
    if isinstance(M, tuple):
        da = f64(M[0], -1, -1)
        ia = _as(M[1], cnp.NPY_INTP, -1, -1)
        pa = _as(M[2], cnp.NPY_INTP, n + 1, -1)
        pd = f64_ptr(da)
        pi = <const Py_ssize_t*> cnp.PyArray_DATA(ia)
        pp = <const Py_ssize_t*> cnp.PyArray_DATA(pa)
    else:
        Ma = f64(M, n, n)
        pM = f64_ptr(Ma)
    cdef cnp.npy_intp dims = n
    ra = cnp.PyArray_EMPTY(1, &dims, cnp.NPY_INT64, 0)
    ca = cnp.PyArray_EMPTY(1, &dims, cnp.NPY_INT64, 0)
    rmax = <long long*> malloc(n * sizeof(long long))
    cmax = <long long*> malloc(n * sizeof(long long))
    if rmax == NULL or cmax == NULL:
        free(rmax)
        free(cmax)
        raise MemoryError(f"scaling workspace for n = {n}")
    with nogil:
        needed = _ruiz(n, pM, n, pd, pi, pp, f64_ptr(qa), symmetric, balanced, q_balanced,
                       max_rounds, <long long*> cnp.PyArray_DATA(ra),
                       <long long*> cnp.PyArray_DATA(ca), rmax, cmax)
    free(rmax)
    free(cmax)
    return (ra, ca) if needed else None


def is_symmetric_dense(M):
    """Exact symmetry of a square float64 array (early exit)."""
    cdef cnp.ndarray Ma = f64(M, -1, -1) if not cnp.PyArray_Check(M) else <cnp.ndarray> M
    cdef Py_ssize_t n
    cdef bint sym
    if cnp.PyArray_NDIM(Ma) != 2 or cnp.PyArray_DIM(Ma, 0) != cnp.PyArray_DIM(Ma, 1):
        raise ValueError("a square matrix is needed")
    n = cnp.PyArray_DIM(Ma, 0)
    Ma = f64(Ma, n, n)
    with nogil:
        sym = _symmetric(f64_ptr(Ma) if n else NULL, n)
    return bool(sym)


cdef bint _symmetric(const double* M, Py_ssize_t n) noexcept nogil:
    cdef Py_ssize_t i, j
    for i in range(n):
        for j in range(i):
            if M[i * n + j] != M[j * n + i]:
                return False
    return True


def dense_minima(M, q):
    """``(min_i M_ii, min_i q_i)`` of a dense float64 (n, n) ``M`` and ``q`` in one call (inf
    for n = 0; NaN propagates): the first facts ``auto`` looks at, without two numpy
    reductions (about a microsecond each on a small problem)."""
    cdef cnp.ndarray qa = f64(q, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(qa, 0)
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef const double* pM = f64_ptr(Ma)
    cdef const double* pq = f64_ptr(qa)
    cdef double dmin = INFINITY, qmin = INFINITY, v
    cdef Py_ssize_t i
    with nogil:
        for i in range(n):
            v = pM[i * n + i]
            if v < dmin or v != v:
                dmin = v
            v = pq[i]
            if v < qmin or v != v:
                qmin = v
    return dmin, qmin


cdef bint _balanced(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* q,
                    int balanced, int q_balanced, long long* work) noexcept nogil:
    """The equilibration's balance test, the one definition (one pass of :c:func:`_ruiz`):
    True when :func:`lcpcli.analysis.scaling.equilibrate` leaves the dense problem alone.
    ``work``: 4 n long longs."""
    # _ruiz's first round with r = c = 0: a failed test always ends in a scaling (the row or
    # column step it leads to changes an exponent), a passed one leaves q's common factor
    # to decide; tests/solvers/test_scaling.py checks this against _ruiz itself
    cdef Py_ssize_t i
    cdef long long k
    for i in range(2 * n):
        work[i] = 0
    if not _round_balanced(n, M, ldm, NULL, NULL, NULL, work, work + n, work + 2 * n,
                           work + 3 * n, balanced, 0):
        return False
    k = _q_shift(n, q, work)
    return -q_balanced <= k <= q_balanced


def balanced_dense(M, q, int balanced, int q_balanced):
    """:c:func:`_balanced` for a dense float64 (n, n) ``M`` (what
    :func:`lcpcli.analysis.scaling.is_balanced` calls: one compiled call)."""
    cdef cnp.ndarray qa = f64(q, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(qa, 0)
    if n == 0:
        return True
    cdef cnp.ndarray Ma = f64(M, n, n)
    cdef long long small[256]
    cdef long long* work = &small[0]
    cdef bint out
    if n > 64:
        work = <long long*> malloc(4 * n * sizeof(long long))
        if work == NULL:
            raise MemoryError(f"scaling workspace for n = {n}")
    with nogil:
        out = _balanced(n, f64_ptr(Ma), n, f64_ptr(qa), balanced, q_balanced, work)
    if n > 64:
        free(work)
    return bool(out)
