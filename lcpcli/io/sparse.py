"""Sparse matrices in files: CSR, CSC or COO given as named parts (shared by every format)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import check_size

PARTS = {"csr": ("data", "indices", "indptr"), "csc": ("data", "indices", "indptr"),
         "coo": ("data", "row", "col")}


def sparse_from_parts(parts: Mapping[str, Any], label: str = "M") -> Any:
    """A CSR matrix from ``{"format", "shape", "data", ...}``; ProblemError when inconsistent."""
    import scipy.sparse as sp

    fmt = str(_scalar(parts.get("format", ""))).lower()
    if fmt not in PARTS:
        raise ProblemError(f"sparse {label}: format must be one of csr, csc, coo (got {fmt!r})")
    shape = parts.get("shape")
    try:
        shape = tuple(int(x) for x in np.asarray(shape).ravel())
    except (TypeError, ValueError):
        shape = ()
    if len(shape) != 2:
        raise ProblemError(f"sparse {label}: 'shape' must be two integers")
    missing = [k for k in PARTS[fmt] if k not in parts]
    if missing:
        raise ProblemError(f"sparse {label}: missing {', '.join(missing)}")
    data = np.asarray(parts["data"], dtype=np.float64).ravel()
    check_size(*shape, sparse=True, nnz=data.size)
    try:
        if fmt == "coo":
            row = np.asarray(parts["row"], dtype=np.int64).ravel()
            col = np.asarray(parts["col"], dtype=np.int64).ravel()
            if not (row.size == col.size == data.size):
                raise ProblemError(f"sparse {label}: row, col and data differ in length")
            if data.size and (row.min() < 0 or col.min() < 0 or row.max() >= shape[0]
                              or col.max() >= shape[1]):
                raise ProblemError(f"sparse {label}: an index is outside the shape {shape}")
            return sp.csr_matrix(sp.coo_matrix((data, (row, col)), shape=shape))
        indices = np.asarray(parts["indices"], dtype=np.int64).ravel()
        indptr = np.asarray(parts["indptr"], dtype=np.int64).ravel()
        major = shape[0] if fmt == "csr" else shape[1]
        minor = shape[1] if fmt == "csr" else shape[0]
        if indptr.size != major + 1 or indptr[0] != 0 or indptr[-1] != data.size \
                or indices.size != data.size or np.any(np.diff(indptr) < 0):
            raise ProblemError(f"sparse {label}: indptr/indices/data are inconsistent")
        if indices.size and (indices.min() < 0 or indices.max() >= minor):
            raise ProblemError(f"sparse {label}: an index is outside the shape {shape}")
        cls = sp.csr_matrix if fmt == "csr" else sp.csc_matrix
        return sp.csr_matrix(cls((data, indices, indptr), shape=shape))
    except (TypeError, ValueError) as exc:
        raise ProblemError(f"sparse {label}: {exc}") from None


def sparse_parts(M: Any) -> dict[str, Any]:
    """The CSR parts of a scipy.sparse matrix (inverse of :func:`sparse_from_parts`)."""
    csr = M.tocsr()
    return {"format": "csr", "shape": [int(csr.shape[0]), int(csr.shape[1])],
            "data": np.asarray(csr.data, dtype=np.float64),
            "indices": np.asarray(csr.indices, dtype=np.int64),
            "indptr": np.asarray(csr.indptr, dtype=np.int64)}


def _scalar(x: Any) -> Any:
    if isinstance(x, bytes):
        return x.decode()
    if isinstance(x, np.ndarray):
        return _scalar(x.item()) if x.size == 1 else x
    return x
