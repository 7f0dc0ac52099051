# cython: language_level=3, boundscheck=False, wraparound=False
"""Compiled finiteness test for the data rule of :mod:`lcpcli.core.problem`: one pass over the
entries, no temporary array (``numpy.all(numpy.isfinite(a))`` makes one and costs about a
microsecond on a 10 x 10 matrix, more than the small solve's kernel)."""

from libc.math cimport isfinite

cimport numpy as cnp

import numpy as np

cnp.import_array()


def all_finite(a):
    """True when every entry of the array ``a`` is finite (no NaN, no Inf); ``a`` is read in
    place when it is a C-contiguous float64 array, else as such a copy."""
    cdef cnp.ndarray arr
    if cnp.PyArray_Check(a) and cnp.PyArray_TYPE(<cnp.ndarray>a) == cnp.NPY_FLOAT64 \
            and cnp.PyArray_IS_C_CONTIGUOUS(<cnp.ndarray>a):
        arr = <cnp.ndarray>a
    else:
        arr = np.ascontiguousarray(a, dtype=np.float64)
    cdef Py_ssize_t i, n = cnp.PyArray_SIZE(arr)
    cdef const double* p = <const double*>cnp.PyArray_DATA(arr)
    cdef bint ok = True
    with nogil:
        for i in range(n):
            if not isfinite(p[i]):
                ok = False
                break
    return ok
