# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Compiled helper of :mod:`lcpcli.contact.islands`: the dense diagonal blocks of a
block-diagonal CSR matrix, written in one pass over its entries (no permuted copy of the
matrix, no slicing per block)."""

ctypedef fused index_t:
    int
    long long


def scatter_blocks(const double[::1] data, const index_t[::1] indices,
                   const index_t[::1] indptr, const long long[::1] row_start,
                   const long long[::1] col_local, const long long[::1] block,
                   double[::1] out):
    """Add every entry ``(i, j, v)`` of the CSR matrix (``data``, ``indices``, ``indptr``;
    0-based) into ``out[row_start[i] + col_local[j]]`` (``out`` zeroed by the caller:
    duplicate entries add up, as a CSR matrix reads them).  ``block[i]`` is the diagonal block
    of row/column ``i``; returns False, with ``out`` partly written, at the first entry whose
    row and column lie in different blocks (the matrix is not block diagonal in them)."""
    cdef Py_ssize_t n = indptr.shape[0] - 1, i, p, j
    cdef long long start, b
    cdef bint ok = True
    with nogil:
        for i in range(n):
            start = row_start[i]
            b = block[i]
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                if block[j] != b:
                    ok = False
                    break
                out[start + col_local[j]] += data[p]
            if not ok:
                break
    return ok
