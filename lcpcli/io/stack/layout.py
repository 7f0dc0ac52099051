"""Stacked problem files: K problems of one size n in one NPZ or HDF5 file.

Problem ``k`` (0-based, ``k = 0 .. K-1``) is ``w = M[k] z + q[k]``.  Layout, the same names in
both formats (HDF5: datasets at the root; NPZ: members ``NAME.npy``):

* ``M`` of shape (K, n, n) and ``q`` of shape (K, n): real numbers (integers or floats, read as
  float64; the rule of :mod:`lcpcli.core.numeric`), K >= 1, n x n within
  :func:`~lcpcli.core.problem.check_size`, K at most :data:`MAX_STACK_PROBLEMS`;
* ``names`` (K,), optional: strings (HDF5 variable-length UTF-8 or fixed-length; NPZ a numpy
  string array), each at most :data:`~lcpcli.io.files.MAX_NAME_BYTES`;
* ``lower`` and ``upper``, optional (box LCPs), each of shape (n,), shared by every problem,
  or (K, n); one of them alone follows the one-sided bounds rule of :meth:`Problem.create`
  and :func:`lcpcli.solve_many` (:func:`lcpcli.core.problem.default_bound`: a missing lower
  bound is 0, a missing upper bound +inf);
* ``n_eq``, optional, one integer ``0 <= n_eq <= n`` shared by every problem (MLCP: the first
  ``n_eq`` variables free), not together with bounds: in HDF5 a root *attribute* ``n_eq`` (as
  in the one-problem layout), in NPZ a member ``n_eq``.

Naming rule (:func:`problem_name`, used everywhere): problem ``k`` is called ``names[k]`` when
the file has names and that name is not empty, else ``STEM[k]`` (the file's stem, then the
index in brackets: ``scenes[0]``, ``scenes[1]``, ...).

Everything is checked from headers and metadata before any data is read (:func:`stack_info`);
data are read one chunk of problems at a time (:class:`StackReader`): HDF5 by slicing into
preallocated float64 arrays, NPZ by reading at the member's offset in the zip (a member
stored uncompressed, as ``np.savez`` writes it) or by decompressing sequentially (a compressed
one).  NaN/Inf values are not refused by the reader (a batch records such a problem as an
error on its own); :func:`iter_problems` validates each problem (:meth:`Problem.create`).
Errors are :class:`ProblemError` with a one-line message; readers leave the file name out
(``io.load`` adds it), the functions that take a whole file from start to end
(:func:`iter_problems`, the conversions) add it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import check_n_eq, check_size
from lcpcli.io.files import MAX_NAME_BYTES

#: Extensions of stack files and their formats.
STACK_FORMATS = {".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5", ".npz": "npz"}
#: Most problems one stack may declare (a batch keeps one record per problem).
MAX_STACK_PROBLEMS = 100_000_000
#: About the bytes of one HDF5 storage chunk of M written by a :class:`StackWriter` that is not
#: told the number of problems in advance (:func:`write_stack` stores M contiguous).
H5_CHUNK_BYTES = 2**20
#: The HDF5 chunk cache of a reader (a storage chunk cut by two read chunks is read once).
H5_CACHE_BYTES = 16 * 2**20
H5_CACHE_SLOTS = 10_007
#: Most bytes of fixed-width names decoded at once.
_NAME_BLOCK_BYTES = 8 * 2**20
#: Largest size of a stack's ``names`` as declared by the HDF5 header: rows x fixed length, or
#: x the fill value that the rows never written repeat (1 GiB: 16.7 million 64-byte names).
MAX_NAMES_DECLARED = 2**30
#: Default bytes of M in one chunk read by :meth:`StackReader.chunks` / :func:`chunk_size`.
_CHUNK_BUDGET = 32 * 2**20


def stacked_message(K: int) -> str:
    """What ``io.load`` says about a stack of ``K > 1`` problems."""
    return (f"holds {K:,} stacked problems; solve them as a batch (lcpcli solve FILE), pick one "
            f"with --problem NAME (or its index), or convert them (lcpcli convert)")


@dataclass(frozen=True)
class StackInfo:
    """What a stack file holds, from its headers (nothing read yet)."""

    path: str
    fmt: str             # "hdf5" | "npz"
    K: int               # problems
    n: int               # size of each
    n_eq: int            # 0 for LCP
    has_names: bool
    bounds: str | None   # None, "shared" (every stored bound (n,)) or "per_problem"
    #: The shapes of the bounds the file stores ((n,) or (K, n)); None: not stored (a box LCP
    #: given one bound gets the other by the one-sided bounds rule, core.problem.default_bound).
    lower_shape: tuple[int, ...] | None = None
    upper_shape: tuple[int, ...] | None = None
    #: Whether every row of M, q and per-problem bounds is stored so that a mapped reader
    #: reads it in place (:mod:`lcpcli.io.stack.mapped`: one run each, from the metadata;
    #: the reader still checks); a batch then reads larger chunks.  Not part of equality (a
    #: property of the storage, not of what the file holds).
    in_place: bool = field(default=False, compare=False)


@dataclass
class StackChunk:
    """Problems ``start .. start + len(M) - 1`` of a stack (C-contiguous float64 arrays)."""

    start: int
    M: np.ndarray                 # (c, n, n)
    q: np.ndarray                 # (c, n)
    names: list[str] | None       # the stored names (empty strings kept), None without names
    lower: np.ndarray | None      # (c, n); a shared bound is copied to every row
    upper: np.ndarray | None
    #: For arrays read in place (read-only views of the mapped file): raises ProblemError
    #: when the file was truncated under them; call it once done with the data
    #: (:mod:`lcpcli.io.stack.mapped`).  None: every array is a copy.
    check: Callable[[], None] | None = None


def problem_name(stem: str, names: list[str] | None, k: int, start: int = 0) -> str:
    """The naming rule: ``names[k - start]`` if present and not empty, else ``STEM[k]``."""
    if names is not None and names[k - start]:
        return names[k - start]
    return f"{stem}[{k}]"


def chunk_size(n: int, *, budget_bytes: int = _CHUNK_BUDGET) -> int:
    """Problems per chunk so that one chunk's M (float64) fits ``budget_bytes`` (at least 1)."""
    return max(1, budget_bytes // max(8, 8 * n * n))


def _stack_format(path: str | Path) -> str:
    ext = Path(path).suffix.lower()
    if ext not in STACK_FORMATS:
        raise ProblemError(f"a stacked file is .h5/.hdf5/.hdf or .npz, not {ext or '(none)'}")
    return STACK_FORMATS[ext]


def _layout(path: str, fmt: str, m_shape: tuple[int, ...], q_shape: tuple[int, ...] | None, *,
            names_shape: tuple[int, ...] | None, lower: tuple[int, ...] | None,
            upper: tuple[int, ...] | None, n_eq: Any) -> StackInfo:
    """Every rule on shapes, from the headers (one definition for both formats)."""
    if len(m_shape) != 3:
        raise ProblemError(f"a stack needs M of shape (K, n, n), got shape {m_shape}")
    K, n, m = m_shape
    if n != m:
        raise ProblemError(f"M must hold square matrices, got shape {m_shape}")
    check_size(n, n)
    if K < 1:
        raise ProblemError(f"holds no problem (M has shape {m_shape})")
    if K > MAX_STACK_PROBLEMS:
        raise ProblemError(f"M declares {K:,} problems (limit {MAX_STACK_PROBLEMS:,})")
    if q_shape is None:
        raise ProblemError("missing 'q' (a stack holds M of shape (K, n, n) and q of (K, n))")
    if q_shape != (K, n):
        raise ProblemError(f"q has shape {q_shape}; expected ({K}, {n}) for M of shape "
                           f"{m_shape}")
    if names_shape is not None and names_shape != (K,):
        raise ProblemError(f"names has shape {names_shape}; expected ({K},)")
    bounds = None
    given = [shape for shape in (lower, upper) if shape is not None]
    for label, shape in (("lower", lower), ("upper", upper)):
        if shape is not None and shape not in ((n,), (K, n)):
            raise ProblemError(f"{label} has shape {shape}; expected ({n},) or ({K}, {n})")
    if given:
        bounds = "shared" if all(shape == (n,) for shape in given) else "per_problem"
    n_eq = check_n_eq(n_eq, n, bounded=bounds is not None)
    return StackInfo(path=path, fmt=fmt, K=K, n=n, n_eq=n_eq,
                     has_names=names_shape is not None, bounds=bounds, lower_shape=lower,
                     upper_shape=upper)


def _check_names(text: list[str]) -> list[str]:
    for name in text:
        if len(name.encode("utf-8", errors="replace")) > MAX_NAME_BYTES:
            raise ProblemError(f"a name is longer than {MAX_NAME_BYTES:,} bytes")
    return text
