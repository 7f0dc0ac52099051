# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled helper of :mod:`lcpcli.contact.islands`: the dense diagonal blocks of a
block-diagonal CSR matrix, written in one pass over its entries (no permuted copy of the
matrix, no slicing per block)."""

from cython.parallel cimport prange
from libc.stdint cimport int64_t
from libc.string cimport memset

from lcpcli.core.arrays cimport _as, f64, f64_ptr, i64, i64_ptr, inout

cimport numpy as cnp

cnp.import_array()

#: Doubles per piece of the buffer a thread zeroes (2 MiB: one huge page).
cdef Py_ssize_t CHUNK = 1 << 18

ctypedef fused index_t:
    int
    long long


cdef int _scatter_row(Py_ssize_t i, const double* data, const index_t* indices,
                      const index_t* indptr, const int64_t* row_start,
                      const int64_t* col_local, const int64_t* block, const int64_t* sizes,
                      double* out) noexcept nogil:
    """Row ``i``'s entries into its block row (zeroed first when ``sizes`` is given: the
    blocks' sizes); 1 at the first entry in another block."""
    cdef Py_ssize_t p, j
    cdef int64_t start = row_start[i]
    cdef int64_t b = block[i]
    if sizes != NULL:
        memset(out + start, 0, sizes[b] * sizeof(double))
    for p in range(indptr[i], indptr[i + 1]):
        j = indices[p]
        if block[j] != b:
            return 1
        out[start + col_local[j]] += data[p]
    return 0


cdef bint _scatter(Py_ssize_t n, const double* data, const index_t* indices,
                   const index_t* indptr, const int64_t* row_start, const int64_t* col_local,
                   const int64_t* block, const int64_t* sizes, double* out, Py_ssize_t size,
                   int threads, bint fresh) noexcept nogil:
    cdef Py_ssize_t i, c
    cdef Py_ssize_t bad = 0
    if threads <= 1:
        for i in range(n):
            if _scatter_row(i, data, indices, indptr, row_start, col_local, block, sizes, out):
                return False
        return True
    if fresh:
        # first the buffer's pages, each thread its own contiguous part (threads that fault in
        # the same huge pages wait on each other: slower than one thread)
        for c in prange((size + CHUNK - 1) // CHUNK, num_threads=threads, schedule="static"):
            memset(out + c * CHUNK, 0,
                   (CHUNK if size - c * CHUNK > CHUNK else size - c * CHUNK) * sizeof(double))
    # the rows in parallel: each row writes only its own block row (row_start[i] onwards)
    for i in prange(n, num_threads=threads, schedule="static"):
        bad += _scatter_row(i, data, indices, indptr, row_start, col_local, block, sizes, out)
    return bad == 0


def scatter_blocks(data, indices, indptr, row_start, col_local, block, out,
                   int threads=1, sizes=None, bint fresh=True):
    """Add every entry ``(i, j, v)`` of the CSR matrix (``data``, ``indices``, ``indptr``;
    0-based, int32 or int64 indices) into ``out[row_start[i] + col_local[j]]`` (``out``: a
    writeable float64 array zeroed by the caller; duplicate entries add up, as a CSR matrix
    reads them).  ``block[i]`` is the diagonal block of row/column ``i`` (``row_start``,
    ``col_local``, ``block``: int64, one per row); returns False, with ``out`` partly written,
    at the first entry whose row and column lie in different blocks (the matrix is not block
    diagonal in them).  ``sizes`` (int64, one per block): each row first zeroes its block row
    (``sizes[block[i]]`` entries), so ``out`` may hold anything when every row of every block
    is a row of the matrix.  ``threads`` > 1: the rows split between that many OpenMP threads
    (each row writes only its own block row), ``out`` zeroed first when ``fresh`` (memory not
    touched yet), each thread its own contiguous part (its first touch).  The CSR arrays are
    taken as scipy makes them (indices within the rows, ``indptr`` nondecreasing up to the
    length of ``data``): an internal helper, not a reader of outside data."""
    cdef cnp.ndarray d = f64(data, -1, -1)
    cdef cnp.ndarray o = inout(out, cnp.NPY_FLOAT64, -1, -1)
    cdef cnp.ndarray rs = i64(row_start, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(rs, 0)
    cdef cnp.ndarray cl = i64(col_local, n, -1)
    cdef cnp.ndarray bl = i64(block, n, -1)
    cdef cnp.ndarray ia, pa, sz
    cdef const int64_t* psz = NULL
    cdef bint ok
    cdef int typ = cnp.PyArray_TYPE(<cnp.ndarray>indices) if cnp.PyArray_Check(indices) \
        else cnp.NPY_INT64
    if typ == cnp.NPY_INT32:
        ia = _as(indices, cnp.NPY_INT32, -1, -1)
        pa = _as(indptr, cnp.NPY_INT32, n + 1, -1)
    else:
        ia = _as(indices, cnp.NPY_INT64, -1, -1)
        pa = _as(indptr, cnp.NPY_INT64, n + 1, -1)
    if cnp.PyArray_DIM(ia, 0) != cnp.PyArray_DIM(d, 0):
        raise ValueError("scatter_blocks: data and indices differ in length")
    if sizes is not None:
        sz = i64(sizes, -1, -1)
        psz = i64_ptr(sz)
    with nogil:
        if typ == cnp.NPY_INT32:
            ok = _scatter(n, f64_ptr(d), <const int*>cnp.PyArray_DATA(ia),
                          <const int*>cnp.PyArray_DATA(pa), i64_ptr(rs), i64_ptr(cl),
                          i64_ptr(bl), psz, f64_ptr(o), cnp.PyArray_SIZE(o), threads, fresh)
        else:
            ok = _scatter(n, f64_ptr(d), <const long long*>cnp.PyArray_DATA(ia),
                          <const long long*>cnp.PyArray_DATA(pa), i64_ptr(rs), i64_ptr(cl),
                          i64_ptr(bl), psz, f64_ptr(o), cnp.PyArray_SIZE(o), threads, fresh)
    return ok
