"""The compiled :func:`mxs128` hash (``mxs128.h``; definition in :mod:`lcpcli.batch.digest`)."""

from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBuffer_Release, PyObject_GetBuffer
from libc.stdint cimport uint64_t


cdef extern from "mxs128.h" nogil:
    void c_mxs128 "mxs128"(const unsigned char *data, uint64_t length, uint64_t seed,
                           unsigned char *out)


def mxs128(data, uint64_t seed=0):
    """The 16 bytes of mxs128 of the bytes of ``data`` (any C-contiguous buffer: bytes, a numpy
    array, read as its memory bytes), computed without the GIL.  The buffer protocol directly,
    not a typed memoryview (docs/kernels.md: generated code and build time)."""
    cdef Py_buffer view
    cdef unsigned char out[16]
    cdef unsigned char empty = 0
    cdef const unsigned char *p = &empty
    cdef uint64_t length
    PyObject_GetBuffer(data, &view, PyBUF_C_CONTIGUOUS)
    try:
        length = <uint64_t>view.len
        if length:
            p = <const unsigned char *>view.buf
        with nogil:
            c_mxs128(p, length, seed, out)
    finally:
        PyBuffer_Release(&view)
    return out[:16]
