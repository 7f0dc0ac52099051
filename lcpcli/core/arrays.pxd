# Cheap access to numpy arrays for the kernels' Python wrappers (numpy C API: flag checks and a
# data pointer).  Typed memoryviews would cost about a microsecond per argument (too much on the
# small-solve path, where a whole solve takes a few) and ~20,000 lines of generated C per module
# (build time).  Every module that cimports this must call ``cnp.import_array()``.
cimport numpy as cnp
from libc.stdint cimport int64_t, uint8_t


cdef inline cnp.ndarray _as(object a, int typenum, Py_ssize_t n0, Py_ssize_t n1):
    """``a`` as a C-contiguous aligned array of ``typenum`` and shape (n0,) (n1 < 0) or
    (n0, n1) (n0 < 0: any length): the array itself when it already is one, else a converted
    copy; ValueError on another shape."""
    cdef cnp.ndarray arr
    cdef int nd = 1 if n1 < 0 else 2
    if cnp.PyArray_Check(a) and cnp.PyArray_TYPE(<cnp.ndarray>a) == typenum \
            and cnp.PyArray_IS_C_CONTIGUOUS(<cnp.ndarray>a) \
            and cnp.PyArray_ISALIGNED(<cnp.ndarray>a):
        arr = <cnp.ndarray>a
    else:
        arr = cnp.PyArray_FROMANY(a, typenum, nd, nd,
                                  cnp.NPY_ARRAY_C_CONTIGUOUS | cnp.NPY_ARRAY_ALIGNED)
    if cnp.PyArray_NDIM(arr) != nd or (n0 >= 0 and cnp.PyArray_DIM(arr, 0) != n0) or (
            nd == 2 and cnp.PyArray_DIM(arr, 1) != n1):
        raise ValueError("array of the wrong shape")
    return arr


cdef inline cnp.ndarray f64(object a, Py_ssize_t n0, Py_ssize_t n1):
    """A float64 input (converted when needed); see :func:`_as`."""
    return _as(a, cnp.NPY_FLOAT64, n0, n1)


cdef inline cnp.ndarray i64(object a, Py_ssize_t n0, Py_ssize_t n1):
    """An int64 input (converted when needed); see :func:`_as`."""
    return _as(a, cnp.NPY_INT64, n0, n1)


cdef inline cnp.ndarray inout(object a, int typenum, Py_ssize_t n0, Py_ssize_t n1):
    """An array the kernel writes into: must already be C-contiguous, aligned, writeable and
    of ``typenum`` (no silent copy, which would lose the writes); ValueError otherwise."""
    if not (cnp.PyArray_Check(a) and cnp.PyArray_TYPE(<cnp.ndarray>a) == typenum
            and cnp.PyArray_IS_C_CONTIGUOUS(<cnp.ndarray>a)
            and cnp.PyArray_ISALIGNED(<cnp.ndarray>a)
            and cnp.PyArray_ISWRITEABLE(<cnp.ndarray>a)):
        raise ValueError("output array must be a writeable C-contiguous array of the "
                         "kernel's dtype")
    return _as(a, typenum, n0, n1)


cdef inline double* f64_ptr(cnp.ndarray a) noexcept nogil:
    return <double*>cnp.PyArray_DATA(a)


cdef inline int64_t* i64_ptr(cnp.ndarray a) noexcept nogil:
    return <int64_t*>cnp.PyArray_DATA(a)


cdef inline uint8_t* u8_ptr(cnp.ndarray a) noexcept nogil:
    return <uint8_t*>cnp.PyArray_DATA(a)


cdef inline cnp.ndarray empty_f64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_EMPTY(1, &dim, cnp.NPY_FLOAT64, 0)


cdef inline cnp.ndarray zeros_f64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_ZEROS(1, &dim, cnp.NPY_FLOAT64, 0)


cdef inline cnp.ndarray empty_i64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_EMPTY(1, &dim, cnp.NPY_INT64, 0)


cdef inline cnp.ndarray zeros_i64(Py_ssize_t n):
    cdef cnp.npy_intp dim = n
    return cnp.PyArray_ZEROS(1, &dim, cnp.NPY_INT64, 0)
