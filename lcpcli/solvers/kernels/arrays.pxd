# Cheap access to numpy arrays for the kernels' Python wrappers (numpy C API: flag checks and a
# data pointer instead of a typed memoryview, whose set-up costs about a microsecond per
# argument: too much on the small-solve path, where the whole solve is a few microseconds).
cimport numpy as cnp
from libc.stdint cimport int64_t



cdef inline cnp.ndarray f64(object a, Py_ssize_t n0, Py_ssize_t n1):
    """``a`` as a C-contiguous float64 array of shape (n0,) (n1 < 0) or (n0, n1): the array
    itself when it already is one, else a converted copy; ValueError on another shape."""
    cdef cnp.ndarray arr
    cdef int nd = 1 if n1 < 0 else 2
    if cnp.PyArray_Check(a):
        arr = <cnp.ndarray>a
        if not (cnp.PyArray_TYPE(arr) == cnp.NPY_FLOAT64 and cnp.PyArray_IS_C_CONTIGUOUS(arr)
                and cnp.PyArray_ISALIGNED(arr)):
            arr = cnp.PyArray_FROMANY(a, cnp.NPY_FLOAT64, nd, nd,
                                      cnp.NPY_ARRAY_C_CONTIGUOUS | cnp.NPY_ARRAY_ALIGNED)
    else:
        arr = cnp.PyArray_FROMANY(a, cnp.NPY_FLOAT64, nd, nd,
                                  cnp.NPY_ARRAY_C_CONTIGUOUS | cnp.NPY_ARRAY_ALIGNED)
    if cnp.PyArray_NDIM(arr) != nd or cnp.PyArray_DIM(arr, 0) != n0 or (
            nd == 2 and cnp.PyArray_DIM(arr, 1) != n1):
        raise ValueError("array of the wrong shape")
    return arr


cdef inline double* f64_ptr(cnp.ndarray a) noexcept:
    return <double*>cnp.PyArray_DATA(a)


cdef inline cnp.ndarray empty_f64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_EMPTY(1, &dim, cnp.NPY_FLOAT64, 0)


cdef inline cnp.ndarray empty_i64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_EMPTY(1, &dim, cnp.NPY_INT64, 0)
