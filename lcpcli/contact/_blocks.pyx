# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled helper of :mod:`lcpcli.contact.islands`: the dense diagonal blocks of a
block-diagonal CSR matrix, written in one pass over its entries (no permuted copy of the
matrix, no slicing per block)."""

from libc.stdint cimport int64_t

from lcpcli.core.arrays cimport _as, f64, f64_ptr, i64, i64_ptr, inout

cimport numpy as cnp

cnp.import_array()

ctypedef fused index_t:
    int
    long long


cdef bint _scatter(Py_ssize_t n, const double* data, const index_t* indices,
                   const index_t* indptr, const int64_t* row_start, const int64_t* col_local,
                   const int64_t* block, double* out) noexcept nogil:
    cdef Py_ssize_t i, p, j
    cdef int64_t start, b
    for i in range(n):
        start = row_start[i]
        b = block[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if block[j] != b:
                return False
            out[start + col_local[j]] += data[p]
    return True


def scatter_blocks(data, indices, indptr, row_start, col_local, block, out):
    """Add every entry ``(i, j, v)`` of the CSR matrix (``data``, ``indices``, ``indptr``;
    0-based, int32 or int64 indices) into ``out[row_start[i] + col_local[j]]`` (``out``: a
    writeable float64 array zeroed by the caller; duplicate entries add up, as a CSR matrix
    reads them).  ``block[i]`` is the diagonal block of row/column ``i`` (``row_start``,
    ``col_local``, ``block``: int64, one per row); returns False, with ``out`` partly written,
    at the first entry whose row and column lie in different blocks (the matrix is not block
    diagonal in them).  The CSR arrays are taken as scipy makes them (indices within the rows,
    ``indptr`` nondecreasing up to the length of ``data``): an internal helper, not a reader
    of outside data."""
    cdef cnp.ndarray d = f64(data, -1, -1)
    cdef cnp.ndarray o = inout(out, cnp.NPY_FLOAT64, -1, -1)
    cdef cnp.ndarray rs = i64(row_start, -1, -1)
    cdef Py_ssize_t n = cnp.PyArray_DIM(rs, 0)
    cdef cnp.ndarray cl = i64(col_local, n, -1)
    cdef cnp.ndarray bl = i64(block, n, -1)
    cdef cnp.ndarray ia, pa
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
    with nogil:
        if typ == cnp.NPY_INT32:
            ok = _scatter(n, f64_ptr(d), <const int*>cnp.PyArray_DATA(ia),
                          <const int*>cnp.PyArray_DATA(pa), i64_ptr(rs), i64_ptr(cl),
                          i64_ptr(bl), f64_ptr(o))
        else:
            ok = _scatter(n, f64_ptr(d), <const long long*>cnp.PyArray_DATA(ia),
                          <const long long*>cnp.PyArray_DATA(pa), i64_ptr(rs), i64_ptr(cl),
                          i64_ptr(bl), f64_ptr(o))
    return ok
