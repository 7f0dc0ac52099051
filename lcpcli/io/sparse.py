"""Sparse matrices in files: CSR, CSC or COO given as named parts (shared by every format)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import INDEX_KINDS, check_dtype, real_array
from lcpcli.core.problem import check_size

PARTS = {"csr": ("data", "indices", "indptr"), "csc": ("data", "indices", "indptr"),
         "coo": ("data", "row", "col")}


def sparse_from_parts(parts: Mapping[str, Any], label: str = "M") -> Any:
    """A CSR matrix from ``{"format", "shape", "data", ...}``; ProblemError when inconsistent."""
    import scipy.sparse as sp

    fmt = parse_format(parts.get("format", ""), label)
    shape = _shape(parts.get("shape"), label)
    missing = [k for k in PARTS[fmt] if k not in parts]
    if missing:
        raise ProblemError(f"sparse {label}: missing {', '.join(missing)}")
    data = real_array(parts["data"], f"sparse {label} data").ravel()
    check_size(*shape, sparse=True, nnz=data.size)
    try:
        if fmt == "coo":
            row = index_array(parts["row"], f"sparse {label} row")
            col = index_array(parts["col"], f"sparse {label} col")
            if not (row.size == col.size == data.size):
                raise ProblemError(f"sparse {label}: row, col and data differ in length")
            if data.size and (row.min() < 0 or col.min() < 0 or row.max() >= shape[0]
                              or col.max() >= shape[1]):
                raise ProblemError(f"sparse {label}: an index is outside the shape {shape}")
            return sp.csr_matrix(sp.coo_matrix((data, (row, col)), shape=shape))
        indices = index_array(parts["indices"], f"sparse {label} indices")
        indptr = index_array(parts["indptr"], f"sparse {label} indptr")
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


def check_part_sizes(fmt: str, shape: tuple[int, int], sizes: Mapping[str, int],
                     label: str = "M") -> None:
    """Before reading any part: their lengths (from file headers) fit ``fmt`` and ``shape``.

    ``sizes`` maps part names (``data``, ``indices``, ``indptr``, ``row``, ``col``) to their
    declared lengths; every format's index parts must be as long as ``data`` and ``indptr``
    one longer than the major dimension, so no part can be larger than the data it indexes.
    """
    nnz = sizes.get("data", 0)
    check_size(*shape, sparse=True, nnz=nnz)
    for k in ("indices", "row", "col"):
        if k in sizes and sizes[k] != nnz:
            raise ProblemError(f"sparse {label}: '{k}' has {sizes[k]:,} entries, 'data' {nnz:,}")
    if "indptr" in sizes:
        major = shape[0] if fmt == "csr" else shape[1]
        if sizes["indptr"] != major + 1:
            raise ProblemError(f"sparse {label}: 'indptr' has {sizes['indptr']:,} entries, "
                               f"expected {major + 1:,}")


def parse_format(value: Any, label: str = "M") -> str:
    """The sparse format name (csr, csc, coo) from a string, bytes or one-element array."""
    fmt = _scalar(value)
    if not isinstance(fmt, str):
        raise ProblemError(f"sparse {label}: 'format' must be a string (csr, csc or coo)")
    fmt = fmt.lower()
    if fmt not in PARTS:
        raise ProblemError(f"sparse {label}: format must be one of csr, csc, coo "
                           f"(got {fmt[:20]!r})")
    return fmt


def parse_shape(value: Any, label: str = "M") -> tuple[int, int]:
    """Two non-negative integers within the size limits (a list, an array, an attribute)."""
    return _shape(value, label)


def _shape(value: Any, label: str) -> tuple[int, int]:
    """Two non-negative integers (a list, an array or an HDF5 attribute)."""
    arr = np.asarray(value) if value is not None else np.zeros(0)
    if arr.dtype.kind == "O" and isinstance(value, (list, tuple)) \
            and all(isinstance(x, int) and not isinstance(x, bool) for x in value):
        arr = np.asarray([min(x, 2**62) for x in value], dtype=np.int64)  # huge: refused below
    if arr.dtype.kind not in INDEX_KINDS or arr.size != 2 or arr.ndim > 1 \
            or isinstance(value, (list, tuple)) and any(isinstance(x, bool) for x in value):
        raise ProblemError(f"sparse {label}: 'shape' must be two integers")
    rows, cols = (int(x) for x in arr.ravel())
    check_size(rows, cols, sparse=True)
    return rows, cols


def index_array(value: Any, label: str) -> np.ndarray:
    """A 1-D int64 index array; integers only (no booleans, floats or text)."""
    if isinstance(value, (list, tuple)):
        bad = next((x for x in value if isinstance(x, bool) or not isinstance(x, int)), None)
        if bad is not None or any(not -2**63 <= x < 2**63 for x in value):
            raise ProblemError(f"{label} must hold integers")
        return np.asarray(value, dtype=np.int64).reshape(-1)
    arr = np.asarray(value)
    check_dtype(arr.dtype, label, kinds=INDEX_KINDS)
    if arr.dtype.kind == "u" and arr.size and arr.max() >= 2**63:
        raise ProblemError(f"{label}: an index is too large")
    return arr.astype(np.int64, copy=False).reshape(-1)


def sparse_parts(M: Any) -> dict[str, Any]:
    """The CSR parts of a scipy.sparse matrix (inverse of :func:`sparse_from_parts`)."""
    csr = M.tocsr()
    return {"format": "csr", "shape": [int(csr.shape[0]), int(csr.shape[1])],
            "data": np.asarray(csr.data, dtype=np.float64),
            "indices": np.asarray(csr.indices, dtype=np.int64),
            "indptr": np.asarray(csr.indptr, dtype=np.int64)}


def _scalar(x: Any) -> Any:
    if isinstance(x, bytes):
        return x.decode("utf-8", errors="replace")
    if isinstance(x, np.ndarray):
        return _scalar(x.item()) if x.size == 1 else x
    return x
