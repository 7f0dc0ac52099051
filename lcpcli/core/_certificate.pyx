# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False, nonecheck=False
"""Compiled core of the certificate (the definition is in lcpcli/core/certificate.py).

Two passes over M: (1) w = M z + q and the row scales s_i = |q_i| + (|M| |z|)_i; (2) for the
columns that can move, kappa_j = max_i |M_ij| / s_i (what moving z_j changes, relative to each
row's scale), and the blocks of rows coupled through significant terms (union-find).  A third,
O(n) pass scores every complementary pair and every block.

The fast path works in plain double arithmetic and reports ``status = 2`` when a product or a
row scale leaves [2^-960, 2^960] (a row whose every term underflows to zero included: its
scale would read 0 and its ``w_i`` 0); the Python wrapper then rescales the problem exactly by powers
of two (the certificate does not change under row and column scaling) and calls again.
"""

from libc.math cimport fabs, isfinite, INFINITY, ldexp
from libc.stdlib cimport free, malloc

cimport numpy as cnp

from lcpcli.core.arrays cimport _as, f64, f64_ptr, inout

cnp.import_array()

cdef extern from "rowpass.h" nogil:
    void _rows_pass "lcpcli_rows_pass"(const double* M, Py_ssize_t ldm, const double* z,
                                       const double* q, Py_ssize_t n, double* w, double* a,
                                       double* s, double* rinv) noexcept
    void _col_maxes "lcpcli_col_maxes"(const double* M, Py_ssize_t ldm, const double* inv,
                                       Py_ssize_t n, double* kappa) noexcept
    void _block_error "lcpcli_block_error"(Py_ssize_t n, const double* q, const double* w,
                                           const double* a, const double* eps,
                                           const Py_ssize_t* anchor, const Py_ssize_t* root,
                                           double* g, double* gi, double* e, double* res,
                                           Py_ssize_t* worst) noexcept
    void _lcp_pairs "lcpcli_lcp_pairs"(Py_ssize_t n, const double* z, const double* w,
                                       const double* s, double* kappa, signed char* state,
                                       Py_ssize_t* anchor, double* acc) noexcept


cdef double THETA = 0.0009765625           # 2^-10: links rows through z_j where its share counts
cdef double BIG = ldexp(1.0, 960)
cdef double SMALL = ldexp(1.0, -960)


cdef inline Py_ssize_t _find(Py_ssize_t* parent, Py_ssize_t x) noexcept nogil:
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


cdef inline void _union(Py_ssize_t* parent, Py_ssize_t a, Py_ssize_t b) noexcept nogil:
    a = _find(parent, a)
    b = _find(parent, b)
    if a != b:
        if a < b:
            parent[b] = a
        else:
            parent[a] = b


cdef inline void _bounds(Py_ssize_t i, Py_ssize_t n_eq, const double* lo, const double* up,
                         double* l, double* u) noexcept nogil:
    if lo != NULL:
        l[0] = lo[i]
        u[0] = up[i]
    elif i < n_eq:
        l[0] = -INFINITY
        u[0] = INFINITY
    else:
        l[0] = 0.0
        u[0] = INFINITY


cdef inline double _rel(double v, double s) noexcept nogil:
    """v / s with 0 / 0 = 0 and v / 0 = inf."""
    if v == 0.0:
        return 0.0
    if s == 0.0:
        return INFINITY
    return v / s


cdef inline double _move(double x, double kappa) noexcept nogil:
    """What moving a variable by x changes, relative to the rows it appears in."""
    if x == 0.0:
        return 0.0
    return x * kappa


cdef int _finish(Py_ssize_t n, const double* q, const double* z, Py_ssize_t n_eq,
                 const double* lo, const double* up, const double* w, double* work,
                 Py_ssize_t* iwork, signed char* state, CertOut* out) noexcept nogil:
    """Pass 3: score the pairs, then the blocks (a, s, kappa filled; parent built).

    ``work`` holds a, s, kappa (then each pair's error over kappa), then 2 n scratch entries
    (each block's smallest anchor growth, by the block's root row; each row's own growth)."""
    cdef double* a = work
    cdef double* s = work + n
    cdef double* kappa = work + 2 * n
    cdef Py_ssize_t* parent = iwork
    cdef Py_ssize_t* anchor = iwork + 2 * n      # n entries: 1 when pair i is an equation
    cdef Py_ssize_t i, worst = -1
    cdef double l, u, zi, wi, si, best, x, err = 0.0, omega = 0.0
    cdef double growth = 1.0
    cdef signed char st
    cdef double cF, cL, cU
    cdef double resid = 0.0, bviol = 0.0, wviol = 0.0, comp = 0.0, eqres = 0.0, t
    cdef double acc[5]
    # (a) every pair's backward error and state; the diagnostics in the units of the data (the
    # pairs of the LCP part, l_i = 0 and u_i = inf, after this loop, without branches)
    for i in range(n if lo != NULL else n_eq):
        _bounds(i, n_eq, lo, up, &l, &u)
        zi = z[i]
        wi = w[i]
        si = s[i]
        # the three states' costs; ties go to the state that needs no move of z_i (the bound
        # state when z_i sits exactly on it, else 'between'), which the polish relies on
        cF = _rel(fabs(wi), si)
        x = 0.0
        if zi < l:
            x = l - zi
        elif zi > u:
            x = zi - u
        t = _move(x, kappa[i])
        if t > cF:
            cF = t
        cL = INFINITY
        if l > -INFINITY:
            cL = _rel(-wi, si) if wi < 0.0 else 0.0
            t = _move(fabs(zi - l), kappa[i])
            if t > cL:
                cL = t
        cU = INFINITY
        if u < INFINITY:
            cU = _rel(wi, si) if wi > 0.0 else 0.0
            t = _move(fabs(zi - u), kappa[i])
            if t > cU:
                cU = t
        if zi == l:
            best, st = cL, 0
            if cF < best:
                best, st = cF, 2
            if cU < best:
                best, st = cU, 1
        elif zi == u:
            best, st = cU, 1
            if cF < best:
                best, st = cF, 2
            if cL < best:
                best, st = cL, 0
        else:
            best, st = cF, 2
            if cL < best:
                best, st = cL, 0
            if cU < best:
                best, st = cU, 1
        if state != NULL:
            state[i] = st
        anchor[i] = st == 2
        kappa[i] = best        # kappa is not needed any more: keep eps_i there
        if best > omega:
            omega = best
        t = zi - l
        if wi < t:
            t = wi
        if zi - u > t:
            t = zi - u
        if fabs(t) > resid:
            resid = fabs(t)
        t = l - zi
        if zi - u > t:
            t = zi - u
        if t > bviol:
            bviol = t
        if l > -INFINITY and u == INFINITY:
            if -wi > wviol:
                wviol = -wi
            t = fabs((zi - l) * wi)
            if t > comp:
                comp = t
        elif l == -INFINITY and u < INFINITY:
            if wi > wviol:
                wviol = wi
            t = fabs((u - zi) * wi)
            if t > comp:
                comp = t
        elif l == -INFINITY and u == INFINITY:
            if fabs(wi) > eqres:
                eqres = fabs(wi)
        else:
            t = fabs(zi - l)
            if fabs(u - zi) < t:
                t = fabs(u - zi)
            t = t * fabs(wi)
            if t > comp:
                comp = t
    if lo == NULL and n_eq < n:
        acc[0], acc[1], acc[2], acc[3], acc[4] = omega, resid, bviol, wviol, comp
        _lcp_pairs(n - n_eq, z + n_eq, w + n_eq, s + n_eq, kappa + n_eq,
                   state + n_eq if state != NULL else NULL, anchor + n_eq, acc)
        omega, resid, bviol, wviol, comp = acc[0], acc[1], acc[2], acc[3], acc[4]
    # (b) each block's growth: the smallest growth among its equations with data (pairs scored
    # 'between' whose q_i != 0); an equation with q_i = 0 fixes no size (its g_i would be
    # a_i / |w_i|, rounding noise over rounding noise, so the verdict would depend on the order
    # in which w_i was summed); in a block that no such equation anchors, a data row is judged
    # by its own growth (its violation against its own data), a homogeneous row by none.
    # (c) the certified error.  Both in lcpcli_block_error (rowpass.h), on each row's root
    for i in range(n):
        parent[i] = _find(parent, i)
    # scratch: the last 2 n entries of work and the row scales s (not needed any more)
    _block_error(n, q, w, a, kappa, anchor, parent, work + 3 * n, work + 4 * n, s, acc, &worst)
    err, growth = acc[0], acc[1]
    out.error = err
    out.backward_error = omega
    out.growth = growth
    out.residual = resid
    out.bound_violation = bviol
    out.w_violation = wviol
    out.complementarity = comp
    out.equality_residual = eqres
    out.worst = worst
    out.status = 0
    return 0


cdef inline int _needs_move(double zj, Py_ssize_t j, Py_ssize_t n_eq, const double* lo,
                            const double* up) noexcept nogil:
    """Can some state of pair j ask z_j to move (then kappa_j is needed)?"""
    if lo != NULL:
        return not (zj == lo[j] and zj == up[j])
    if j < n_eq:
        return 0
    return zj != 0.0


cdef int _fail(CertOut* out, int status) noexcept nogil:
    out.error = INFINITY
    out.backward_error = INFINITY
    out.growth = INFINITY
    out.residual = INFINITY
    out.bound_violation = INFINITY
    out.w_violation = INFINITY
    out.complementarity = INFINITY
    out.equality_residual = INFINITY
    out.worst = -1
    out.status = status
    return status


cdef void _link(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* z,
                const double* rinv, const double* kappa, const Py_ssize_t* cols,
                Py_ssize_t nc, Py_ssize_t* parent, Py_ssize_t* sig) noexcept nogil:
    """Union rows i (nodes 0..n-1) and columns j (nodes n + j) wherever z_j != 0 counts in row
    i: ``|M_ij| / s_i >= 2^-10 kappa_j`` (invariant under scaling).  Once every column with
    z_j != 0 is in one set, a row joins it through its first such term and the rest of the row
    changes nothing (the partition is the same as linking every term).  Each row's terms that
    count are listed first (in ``sig``, nc entries of scratch), in column order, without a
    branch per entry: whether M_ij is 0 is data, and a branch on it is mispredicted about as
    often as not on a block of contacts."""
    cdef Py_ssize_t i, j, k, ri, rj, nz = 0, colsets, one = -1, cnt
    cdef bint joined
    cdef const double* row
    cdef double m, inv
    for k in range(nc):
        if z[cols[k]] != 0.0:
            nz += 1
    colsets = nz  # sets holding a column with z_j != 0 (each starts alone)
    for i in range(n):
        row = M + i * ldm
        inv = rinv[i]  # 1 / s_i, inf when s_i = 0
        if one >= 0:  # every such column is in the set rooted at `one` (a row before i): row
            for k in range(nc):  # i, alone so far, joins it through its first term that counts
                j = cols[k]      # (dense rows: the first one or two columns; no listing)
                m = fabs(row[j])
                if m > 0.0 and fabs(z[j]) > 0.0 and m * inv >= THETA * kappa[j]:
                    parent[i] = one
                    break
            continue
        cnt = 0
        for k in range(nc):
            j = cols[k]
            m = fabs(row[j])
            sig[cnt] = j
            # (M and z are finite here, or the row pass failed: m != 0 is m > 0, and the
            # tests need no NaN handling)
            cnt += (m > 0.0) & (fabs(z[j]) > 0.0) & (m * inv >= THETA * kappa[j])
        joined = False  # row i's set holds a column (rows before i never change again)
        for k in range(cnt):
            j = sig[k]
            ri = _find(parent, i)
            rj = _find(parent, n + j)
            if ri != rj:
                if joined:  # two sets that each hold such a column become one
                    colsets -= 1
                joined = True
                if ri < rj:
                    parent[rj] = ri
                else:
                    parent[ri] = rj
            if colsets == 1:
                one = _find(parent, i)
                break


cdef int certify_dense(Py_ssize_t n, const double* M, Py_ssize_t ldm, const double* q,
                       const double* z, Py_ssize_t n_eq, const double* lo, const double* up,
                       double* w, double* work, Py_ssize_t* iwork, signed char* state,
                       CertOut* out) noexcept nogil:
    cdef double* a = work
    cdef double* s = work + n
    cdef double* kappa = work + 2 * n
    cdef double* rinv = work + 3 * n  # 1 / s_i (the last 2 n entries are free until _finish)
    cdef Py_ssize_t* parent = iwork
    cdef Py_ssize_t* cols = iwork + 2 * n
    cdef Py_ssize_t i, j, k, nc = 0
    cdef const double* row
    cdef double wi, ai, t, m, inv
    cdef bint nonfinite = False, outside = False, bad = False, zero = False
    # the range of z, and (pass 2) the columns that may move: one test per problem at the
    # end, not a branch per entry (whether z_j = 0 is data)
    for j in range(n):
        nonfinite |= not isfinite(z[j])
        outside |= (z[j] != 0.0) & ((fabs(z[j]) < SMALL) | (fabs(z[j]) > BIG))
        cols[nc] = j
        nc += (z[j] != 0.0) | _needs_move(z[j], j, n_eq, lo, up)
    if nonfinite or outside:  # the first such z_j says which
        for j in range(n):
            if not isfinite(z[j]):
                return _fail(out, 1)
            if z[j] != 0.0 and not (SMALL <= fabs(z[j]) <= BIG):
                return _fail(out, 2)
    # pass 1: w, |M||z|, s; 1 / s_i (inf when s_i = 0) for kappa and the links
    _rows_pass(M, ldm, z, q, n, w, a, s, rinv)
    for i in range(n):
        wi = w[i]
        ai = a[i]
        bad |= ((not isfinite(wi)) | (not isfinite(ai)) | (s[i] > BIG)
                | ((0.0 < s[i]) & (s[i] < SMALL)))
        zero |= s[i] == 0.0
    if bad or zero:  # the rows in order, as the tests read
        for i in range(n):
            if not (isfinite(w[i]) and isfinite(a[i])) or s[i] > BIG or 0.0 < s[i] < SMALL:
                return _fail(out, 2)
            if s[i] == 0.0:  # every term underflowed to zero (2.8e-250 x 1e-137), or none
                row = M + i * ldm
                for j in range(n):
                    if row[j] != 0.0 and z[j] != 0.0:
                        return _fail(out, 2)
    # pass 2: kappa for the columns that may move, blocks through significant terms.  kappa_j
    # of a column that may not move (z_j = 0 and no state asks it to move) is never used: it
    # only ever multiplies a move of 0, and links nothing
    if nc == 0:
        for i in range(n):
            parent[i] = i
        return _finish(n, q, z, n_eq, lo, up, w, work, iwork, state, out)
    # most columns, or a small problem: a contiguous max over whole rows (vectorised)
    if 2 * nc >= n or n <= 64:
        _col_maxes(M, ldm, rinv, n, kappa)
    else:
        for j in range(n):
            kappa[j] = 0.0
        for i in range(n):
            row = M + i * ldm
            inv = rinv[i]
            for k in range(nc):  # no branch on the data: an entry 0 gives t = 0 (or 0 x inf
                j = cols[k]      # = NaN), which never exceeds kappa_j >= 0
                t = fabs(row[j]) * inv
                kappa[j] = t if t > kappa[j] else kappa[j]
    for i in range(2 * n):
        parent[i] = i
    # scratch for _link: the last n entries of work (free until _finish)
    _link(n, M, ldm, z, rinv, kappa, cols, nc, parent, <Py_ssize_t*>(work + 4 * n))
    for k in range(nc):
        j = cols[k]
        if kappa[j] == 0.0:      # a zero column: moving z_j is never negligible
            kappa[j] = INFINITY
    return _finish(n, q, z, n_eq, lo, up, w, work, iwork, state, out)


ctypedef fused index_t:
    int
    long long


cdef int certify_csr(Py_ssize_t n, const double* data, const index_t* indices,
                     const index_t* indptr, const double* q, const double* z, Py_ssize_t n_eq,
                     const double* lo, const double* up, double* w, double* work,
                     Py_ssize_t* iwork, signed char* state, CertOut* out) noexcept nogil:
    cdef double* a = work
    cdef double* s = work + n
    cdef double* kappa = work + 2 * n
    cdef Py_ssize_t* parent = iwork
    cdef Py_ssize_t* movable = iwork + 2 * n
    cdef Py_ssize_t i, j, p
    cdef double wi, ai, t, m, inv
    for j in range(n):
        if not isfinite(z[j]):
            return _fail(out, 1)
        if z[j] != 0.0 and not (SMALL <= fabs(z[j]) <= BIG):
            return _fail(out, 2)
    for i in range(n):
        wi = 0.0
        ai = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            t = data[p] * z[indices[p]]
            wi = wi + t
            ai = ai + fabs(t)
        wi = wi + q[i]  # terms first, then q, as certify_dense: terms that cancel exactly
        w[i] = wi       # must not swallow q_i (w = 0 where the exact w is q_i < 0)
        a[i] = ai
        s[i] = ai + fabs(q[i])
        if not (isfinite(wi) and isfinite(ai)) or s[i] > BIG or 0.0 < s[i] < SMALL:
            return _fail(out, 2)
        if s[i] == 0.0:  # every term underflowed to zero, or none exists
            for p in range(indptr[i], indptr[i + 1]):
                if data[p] != 0.0 and z[indices[p]] != 0.0:
                    return _fail(out, 2)
    for j in range(n):
        movable[j] = _needs_move(z[j], j, n_eq, lo, up) or z[j] != 0.0
        kappa[j] = 0.0
    for i in range(2 * n):
        parent[i] = i
    for i in range(n):
        inv = INFINITY if s[i] == 0.0 else 1.0 / s[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if movable[j]:
                m = fabs(data[p])
                if m != 0.0:
                    t = m * inv
                    if t > kappa[j]:
                        kappa[j] = t
    for i in range(n):
        inv = INFINITY if s[i] == 0.0 else 1.0 / s[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            m = fabs(data[p])
            if m != 0.0 and z[j] != 0.0 and m * inv >= THETA * kappa[j]:
                _union(parent, i, n + j)
    for j in range(n):
        if movable[j] and kappa[j] == 0.0:
            kappa[j] = INFINITY
    return _finish(n, q, z, n_eq, lo, up, w, work, iwork, state, out)


def certify_arrays(M, q, z, Py_ssize_t n_eq, lo, up, w, state=None):
    """Certify z; M is a C-contiguous float64 array or a (data, indices, indptr) CSR triple.

    ``lo``/``up`` are float64 arrays or None (then the first ``n_eq`` variables are free and the
    others bounded below by 0).  Fills ``w`` (and ``state``, if given: 0 at lower bound, 1 at
    upper bound, 2 between with w = 0, the state that pair's score came from) and returns
    ``(status, error, backward_error, growth, residual, bound_violation, w_violation,
    complementarity, equality_residual, worst)``.  Arguments go through numpy's C API (a flag
    check and a pointer: typed memoryviews would cost a microsecond each on the small-solve
    path); inputs of another dtype or layout are converted, ``w`` and ``state`` must be
    writeable C-contiguous arrays of float64 and int8.
    """
    cdef cnp.ndarray qa = f64(q, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(qa, 0)
    cdef cnp.ndarray za = f64(z, n, -1)
    cdef cnp.ndarray wa = inout(w, cnp.NPY_FLOAT64, n, -1)
    cdef cnp.ndarray sa, loa, upa, Ma, da, ia, pa
    cdef CertOut out
    cdef const double* plo = NULL
    cdef const double* pup = NULL
    cdef signed char* pst = NULL
    cdef double* work
    cdef Py_ssize_t* iwork
    cdef bint is_csr = isinstance(M, tuple)
    cdef int itype = 0
    if n == 0:
        return (0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1)
    if lo is not None:
        loa = f64(lo, n, -1)
        upa = f64(up, n, -1)
        plo = f64_ptr(loa)
        pup = f64_ptr(upa)
    if state is not None:
        sa = inout(state, cnp.NPY_INT8, n, -1)
        pst = <signed char*> cnp.PyArray_DATA(sa)
    if is_csr:
        da = f64(M[0], -1, -1)
        pa = M[2]
        itype = cnp.PyArray_TYPE(<cnp.ndarray> M[1]) if cnp.PyArray_Check(M[1]) else 0
        if itype == cnp.NPY_INT32:
            ia = _as(M[1], cnp.NPY_INT32, -1, -1)
            pa = _as(M[2], cnp.NPY_INT32, n + 1, -1)
        else:
            itype = cnp.NPY_INT64
            ia = _as(M[1], cnp.NPY_INT64, -1, -1)
            pa = _as(M[2], cnp.NPY_INT64, n + 1, -1)
    else:
        Ma = f64(M, n, n)
    work = <double*> malloc(5 * n * sizeof(double))
    iwork = <Py_ssize_t*> malloc(3 * n * sizeof(Py_ssize_t))
    if work == NULL or iwork == NULL:
        free(work)
        free(iwork)
        raise MemoryError(f"certificate workspace for n = {n}")
    with nogil:
        if not is_csr:
            certify_dense(n, f64_ptr(Ma), n, f64_ptr(qa), f64_ptr(za), n_eq, plo, pup,
                          f64_ptr(wa), work, iwork, pst, &out)
        elif itype == cnp.NPY_INT32:
            certify_csr(n, f64_ptr(da), <const int*> cnp.PyArray_DATA(ia),
                        <const int*> cnp.PyArray_DATA(pa), f64_ptr(qa), f64_ptr(za), n_eq,
                        plo, pup, f64_ptr(wa), work, iwork, pst, &out)
        else:
            certify_csr(n, f64_ptr(da), <const long long*> cnp.PyArray_DATA(ia),
                        <const long long*> cnp.PyArray_DATA(pa), f64_ptr(qa), f64_ptr(za),
                        n_eq, plo, pup, f64_ptr(wa), work, iwork, pst, &out)
    free(work)
    free(iwork)
    return (out.status, out.error, out.backward_error, out.growth, out.residual,
            out.bound_violation, out.w_violation, out.complementarity, out.equality_residual,
            out.worst)
