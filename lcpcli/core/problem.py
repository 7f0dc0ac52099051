"""The problem model: one class for the LCP, the mixed LCP and the box LCP.

Sign convention (one for all forms, stated once): ``w = M z + q``.

* **LCP**: ``0 <= z  _|_  w >= 0``.
* **MLCP** (Siconos form): the first ``n_eq`` variables are free and their rows are
  equalities, ``M = [[A, C], [D, B]]``, ``q = [a; b]``: ``A u + C v + a = 0`` and
  ``0 <= v _|_ D u + B v + b >= 0``.
* **Box LCP**: ``lower <= z <= upper`` and ``-w`` lies in the normal cone of the box at ``z``:
  ``w >= 0`` where ``z_i = lower_i``, ``w <= 0`` where ``z_i = upper_i``, ``w = 0`` strictly
  between.
  Acary et al.'s Siconos note writes ``-y in N_[l,u](lambda)`` with ``y = W lambda + b``: the
  same thing with ``w = y``, ``z = lambda``, ``M = W``, ``q = b`` (data written as
  ``y = -W lambda + b`` must
  be given with ``M = -W``).

All three are the mixed complementarity problem over the box ``[l, u]`` returned by
:meth:`Problem.bounds` (LCP: ``[0, inf)``; free MLCP variables: ``(-inf, inf)``), which is how the
certificate treats them uniformly.

``M`` is a dense ``numpy`` array or a ``scipy.sparse`` CSR matrix; it is never densified here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.core._finite import all_finite
from lcpcli.core.errors import ProblemError

#: Largest dense matrix accepted, in entries (2.5e8 float64 entries = 2 GB).
MAX_DENSE_ENTRIES = 250_000_000
#: Largest sparse matrix accepted, in stored entries.
MAX_SPARSE_NNZ = 500_000_000
#: Largest dimension accepted at all.
MAX_N = 50_000_000


def check_size(n_rows: int, n_cols: int, *, sparse: bool = False, nnz: int | None = None) -> None:
    """Refuse absurd sizes *before* any allocation (readers call this from file headers)."""
    if n_rows < 0 or n_cols < 0:
        raise ProblemError(f"negative matrix size {n_rows} x {n_cols}")
    if max(n_rows, n_cols) > MAX_N:
        raise ProblemError(f"matrix of size {n_rows} x {n_cols} is too large (limit n = {MAX_N})")
    if sparse:
        if nnz is not None and nnz > MAX_SPARSE_NNZ:
            raise ProblemError(f"sparse matrix with {nnz} stored entries is too large "
                               f"(limit {MAX_SPARSE_NNZ})")
    elif n_rows * n_cols > MAX_DENSE_ENTRIES:
        gib = n_rows * n_cols * 8 / 2**30
        raise ProblemError(
            f"dense {n_rows} x {n_cols} matrix would need {gib:.1f} GiB "
            f"(limit {MAX_DENSE_ENTRIES} entries); store M sparse (CSR/COO) instead")


#: The one-sided bounds rule, one definition for :meth:`Problem.create`,
#: :func:`lcpcli.solve_many` and stacked files: a box LCP given only one of its bounds gets
#: ``lower = 0`` / ``upper = +inf`` for the other (the LCP's own bound, ``z >= 0``).
BOUND_DEFAULTS = {"lower": 0.0, "upper": math.inf}


def default_bound(label: str, shape: int | tuple[int, ...]) -> np.ndarray:
    """The bound ``label`` (``"lower"`` or ``"upper"``) a box LCP gets when only the other one
    is given (:data:`BOUND_DEFAULTS`), as a float64 array of ``shape``."""
    return np.full(shape, BOUND_DEFAULTS[label])


def check_n_eq(n_eq: Any, n: int, *, bounded: bool = False) -> int:
    """The rule on an MLCP's ``n_eq``, one definition for :meth:`Problem.create`,
    :func:`lcpcli.solve_many` and stacked files: an integer (not a boolean, a float or text)
    with ``0 <= n_eq <= n``, and no bounds beside a positive one (``bounded``); ProblemError
    otherwise.  Returns it as an int."""
    if isinstance(n_eq, (bool, np.bool_)) or not isinstance(n_eq, (int, np.integer)):
        raise ProblemError(f"n_eq must be an integer, got {n_eq!r}")
    if not 0 <= n_eq <= n:
        raise ProblemError(f"n_eq = {n_eq} is outside 0..{n}")
    if n_eq and bounded:
        raise ProblemError("give either n_eq (MLCP) or bounds (box LCP), not both")
    return int(n_eq)


def broken_bounds(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Where the rules on box bounds fail, entry by entry (booleans of the bounds' shape): NaN,
    ``lower = inf``, ``upper = -inf`` or ``lower > upper``.  The one definition of the rules;
    :func:`check_bounds` says which one failed."""
    return (np.isnan(lower) | np.isnan(upper) | (lower == np.inf) | (upper == -np.inf)
            | (lower > upper))


def check_bounds(lower: np.ndarray, upper: np.ndarray) -> None:
    """The rules on box bounds (:func:`broken_bounds`), for one problem (shape (n,)) or a
    stack ((K, n)): no NaN, ``lower < inf``, ``upper > -inf``, ``lower <= upper``
    (ProblemError naming the first offending index, 1-based, and for a stack the 0-based
    problem)."""
    if not broken_bounds(lower, upper).any():
        return
    for vec, label in ((lower, "lower"), (upper, "upper")):
        if np.isnan(vec).any():
            raise ProblemError(f"{label} contains NaN")
    if np.any(lower == np.inf) or np.any(upper == -np.inf):
        raise ProblemError("bounds must satisfy lower < inf and upper > -inf")
    bad = np.argwhere(lower > upper)
    if bad.size:
        at = tuple(int(x) for x in bad[0])
        where = f"problem {at[0]}: " if len(at) == 2 else ""
        raise ProblemError(f"{where}lower > upper at index {at[-1] + 1} "
                           f"({lower[at]:g} > {upper[at]:g})")


#: The kinds of problem (:attr:`Problem.kind`).
LCP, MLCP, BOX = "lcp", "mlcp", "box"


def problem_kind(n_eq: int, bounded: bool) -> str:
    """The kind of a problem (or of a stack): ``"box"`` when bounds are given, ``"mlcp"`` when
    ``n_eq > 0``, else ``"lcp"`` (bounds and n_eq together are refused by the validation)."""
    if bounded:
        return BOX
    return MLCP if n_eq else LCP


def is_sparse(M: Any) -> bool:
    """True for a ``scipy.sparse`` matrix or array (checked without importing scipy)."""
    return hasattr(M, "tocsr") and hasattr(M, "nnz")


@dataclass
class Problem:
    """A linear complementarity problem ``w = M z + q`` (LCP, MLCP or box LCP).

    Build one with :meth:`Problem.create` (validates and normalises) or read one with
    :func:`lcpcli.io.load`.  Attributes are 0-based arrays.  Whatever the constructor is given,
    the arrays are stored as C-contiguous float64 (a dense M) or canonical CSR (a sparse M):
    every compiled kernel relies on that layout.
    """

    M: Any
    q: np.ndarray
    n_eq: int = 0
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    name: str = ""
    description: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.q = _c_float(self.q)
        if type(self.M) is not np.ndarray and is_sparse(self.M):
            if self.M.format != "csr" or self.M.data.dtype != np.float64:
                self.M = self.M.tocsr().astype(np.float64)
        else:
            self.M = _c_float(self.M)
        if self.lower is not None:
            self.lower = _c_float(self.lower)
            self.upper = _c_float(self.upper)

    # ------------------------------------------------------------------ construction
    @classmethod
    def create(cls, M: Any, q: Any, *, n_eq: int = 0, lower: Any = None, upper: Any = None,
               name: str = "", description: str = "",
               meta: dict[str, Any] | None = None) -> Problem:
        """Validate and normalise the data; raise :class:`ProblemError` with a one-line reason."""
        if (type(M) is np.ndarray and type(q) is np.ndarray and M.dtype is _F64
                and q.dtype is _F64 and M.ndim == 2 and q.ndim == 1 and lower is None
                and upper is None and type(n_eq) is int and n_eq == 0
                and M.shape[0] == M.shape[1] == q.shape[0] <= MAX_N
                and M.size <= MAX_DENSE_ENTRIES and M.flags.c_contiguous):
            # the usual call (a dense LCP in native float64 arrays): the checks below reduce
            # to these and the two finiteness tests (tests/core/test_problem_fast.py)
            _check_finite(M, "M")
            _check_finite(q, "q")
            return cls._trusted(M, q.copy(), 0, None, None, str(name or ""),
                                str(description or ""), dict(meta or {}))
        M = _as_matrix(M)
        n_rows, n_cols = M.shape
        if n_rows != n_cols:
            raise ProblemError(f"M must be square, got {n_rows} x {n_cols}")
        n = n_rows
        q = _as_vector(q, "q")
        if q.shape[0] != n:
            raise ProblemError(f"q has length {q.shape[0]} but M is {n} x {n}")
        _check_finite(M, "M")
        _check_finite(q, "q")
        bounded = lower is not None or upper is not None
        n_eq = check_n_eq(n_eq, n, bounded=bounded)
        if bounded:
            lower = default_bound("lower", n) if lower is None else \
                _as_vector(lower, "lower", inf=-math.inf)
            upper = default_bound("upper", n) if upper is None else \
                _as_vector(upper, "upper", inf=math.inf)
            for vec, label in ((lower, "lower"), (upper, "upper")):
                if vec.shape[0] != n:
                    raise ProblemError(f"{label} has length {vec.shape[0]} but M is {n} x {n}")
            check_bounds(lower, upper)
        # normalised already: _as_matrix and _as_vector return C-contiguous float64 (or
        # canonical CSR), default_bound too
        return cls._trusted(M, q, n_eq, lower, upper, str(name or ""), str(description or ""),
                            dict(meta or {}))

    @classmethod
    def _trusted(cls, M: Any, q: np.ndarray, n_eq: int, lower: np.ndarray | None,
                 upper: np.ndarray | None, name: str, description: str,
                 meta: dict[str, Any]) -> Problem:
        """The record of data that :meth:`create` has validated and normalised (C-contiguous
        float64 arrays, canonical CSR), every field by name, without ``__post_init__``'s
        second pass over them."""
        obj = object.__new__(cls)
        obj.__dict__ = {"M": M, "q": q, "n_eq": n_eq, "lower": lower, "upper": upper,
                        "name": name, "description": description, "meta": meta}
        return obj

    # ------------------------------------------------------------------ properties
    @property
    def n(self) -> int:
        """Number of variables (and of rows)."""
        return len(self.q)  # q is a 1-D float64 array (__post_init__): len is its length

    @property
    def kind(self) -> str:
        """``"lcp"``, ``"mlcp"`` (n_eq > 0) or ``"box"`` (bounds given)."""
        return problem_kind(self.n_eq, self.lower is not None)

    @property
    def sparse(self) -> bool:
        """True when M is stored as a scipy.sparse matrix."""
        return type(self.M) is not np.ndarray and is_sparse(self.M)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The box ``[l, u]`` of the equivalent mixed complementarity problem."""
        if self.lower is not None:
            return self.lower, self.upper  # type: ignore[return-value]
        lo = np.zeros(self.n)
        lo[: self.n_eq] = -np.inf
        return lo, np.full(self.n, np.inf)

    def inside(self, z: np.ndarray) -> np.ndarray:
        """``z`` moved onto the box ``[l, u]`` of :meth:`bounds` where it lies outside (a
        method's rounding, e.g. ``z_i = -1e-15`` of an LCP), else ``z`` itself; NaN stays."""
        if self.lower is None:
            rest = z[self.n_eq:]
            if rest.size and rest.min() < 0.0:
                z = z.copy()
                np.maximum(z[self.n_eq:], 0.0, out=z[self.n_eq:])
            return z
        lo, up = self.bounds()
        if np.any(z < lo) or np.any(z > up):
            return np.clip(z, lo, up)
        return z

    def w(self, z: np.ndarray) -> np.ndarray:
        """``w = M z + q``."""
        return np.asarray(self.M @ z).ravel() + self.q

    def dense_M(self) -> np.ndarray:
        """M as a dense array (a copy-free view when it is already dense)."""
        M = self.M
        return M if type(M) is np.ndarray else M.toarray()  # else: sparse (__post_init__)

    def label(self) -> str:
        """A short name for messages."""
        return self.name or "problem"

    def summary(self) -> str:
        """One line: kind, size, storage."""
        store = f"sparse, nnz={self.M.nnz}" if self.sparse else "dense"
        extra = f", n_eq={self.n_eq}" if self.n_eq else ""
        return f"{self.kind.upper()} n={self.n}{extra} ({store})"


# ---------------------------------------------------------------------- helpers
def _as_matrix(M: Any) -> Any:
    if type(M) is not np.ndarray and is_sparse(M):
        if M.ndim != 2:
            raise ProblemError("M must be 2-D")
        check_size(*M.shape, sparse=True, nnz=M.nnz)
        M = M.tocsr().astype(np.float64)
        M.sum_duplicates()
        return M
    try:
        arr = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ProblemError(f"M is not a numeric matrix ({_short(exc)})") from None
    if arr.ndim == 0 and arr.size == 1:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2:
        raise ProblemError(f"M must be a 2-D matrix, got {arr.ndim}-D data")
    check_size(*arr.shape)
    return np.ascontiguousarray(arr)


def _as_vector(v: Any, label: str, *, inf: float | None = None) -> np.ndarray:
    """A float vector; for bounds (``inf`` given) JSON ``null`` means that infinity."""
    try:
        if inf is not None and isinstance(v, (list, tuple)):
            v = [_bound_value(x, inf) for x in v]
        arr = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ProblemError(f"{label} is not a numeric vector ({_short(exc)})") from None
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.ravel()
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise ProblemError(f"{label} must be a vector, got shape {arr.shape}")
    return arr.copy()


def _bound_value(x: Any, inf: float) -> Any:
    """JSON bounds: ``null`` and the strings "inf"/"-inf" are accepted for infinite bounds."""
    if x is None:
        return inf
    if isinstance(x, str):
        s = x.strip().lower()
        if s in ("inf", "+inf", "infinity", "+infinity"):
            return math.inf
        if s in ("-inf", "-infinity"):
            return -math.inf
    return x


_F64 = np.dtype(np.float64)


def _c_float(a: Any) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (no copy when it is one already)."""
    if type(a) is np.ndarray and a.dtype is _F64 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(a, dtype=np.float64)


def _check_finite(M: Any, label: str) -> None:
    data = M.data if type(M) is not np.ndarray and is_sparse(M) else M
    if not all_finite(data):
        raise ProblemError(f"{label} contains NaN or Inf")


def _short(exc: Exception) -> str:
    return str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
