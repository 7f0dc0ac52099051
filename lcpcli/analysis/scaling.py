"""Equilibration: exact power-of-two row and column scaling of a problem, and its undoing.

Conventions: ``w = M z + q``.  A :class:`Scaling` with row exponents ``r`` and column exponents
``c`` maps the problem to ``M~ = D_r M D_c``, ``q~ = D_r q`` with ``D_r = diag(2^r)``,
``D_c = diag(2^c)``; then ``z = D_c z~``, ``w = D_r^-1 w~``, bounds ``l~ = D_c^-1 l``.  Every
solution of one problem is a solution of the other (complementarity is a sign pattern), and
because the factors are powers of two the mapping is exact in floating point: scaling and
unscaling lose nothing.

:func:`equilibrate` computes the factors by Ruiz's iteration in the infinity norm (Ruiz, 2001:
divide every row and column by the square root of its largest entry, repeat), on the binary
exponents of the entries (integer arithmetic, no rounding), then normalises ``q`` to norm ~1 by a
common factor (which leaves ``M~`` unchanged and scales ``z~`` with it).  The ``symmetric``
variant uses ``D_r = D_c`` (``D M D``) and so keeps symmetry, positive (semi)definiteness and
copositivity, which some methods' guarantees need; the two-sided variant keeps the P-matrix
property and undoes arbitrary row and column scalings.  PATH equilibrates in the same spirit
(Ferris and Munson, 1999).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from lcpcli.analysis._scaling import balanced_dense, ruiz_exponents
from lcpcli.core.problem import Problem

#: A problem whose row and column maxima are all within 2^BALANCED of each other is left alone.
BALANCED = 4
#: ... and ``q`` is left alone when its largest entry is within 2^Q_BALANCED of 1.
Q_BALANCED = 8
#: Ruiz iterations at most (each halves the spread of the exponents; 12 covers 2^4000).
MAX_ROUNDS = 12
#: The balance test's thresholds as one argument for compiled callers (``is_balanced`` inside
#: a kernel's own call).
BALANCE = (BALANCED, Q_BALANCED)


@dataclass(frozen=True)
class Scaling:
    """Row and column exponents (see the module docstring); ``kind`` is how they were chosen."""

    row: np.ndarray
    col: np.ndarray
    kind: str

    def apply(self, problem: Problem) -> Problem:
        """The scaled problem ``(D_r M D_c, D_r q)`` with bounds ``D_c^-1 [l, u]``."""
        M = problem.M
        (rlo, rhi), (clo, chi) = self.ranges
        uniform = rlo == rhi and clo == chi  # every entry of M times 2^(rlo + clo)
        if uniform and rlo + clo == 0:
            Ms: Any = M  # rows x 2^k and columns x 2^-k: M itself is unchanged
        elif uniform and not problem.sparse:
            Ms = np.ldexp(M, rlo + clo)  # the same values, without an exponent matrix
        elif problem.sparse:
            Mc = M.tocoo()
            data = np.ldexp(Mc.data, (self.row[Mc.row] + self.col[Mc.col]).astype(np.int32))
            Ms = type(M)((data, (Mc.row, Mc.col)), shape=M.shape).tocsr()
        else:
            Ms = np.ldexp(M, (self.row[:, None] + self.col[None, :]).astype(np.int32))
        lower = upper = None
        if problem.lower is not None:
            lower = self.scale_z(problem.lower)
            upper = self.scale_z(problem.upper)
        return Problem(M=Ms, q=np.ldexp(problem.q, self.row.astype(np.int32)),
                       n_eq=problem.n_eq, lower=lower, upper=upper, name=problem.name,
                       description=problem.description, meta=problem.meta)

    def scale_z(self, z: np.ndarray) -> np.ndarray:
        """``z~ = D_c^-1 z`` (also for bounds and warm starts)."""
        return np.ldexp(np.asarray(z, dtype=np.float64), (-self.col).astype(np.int32))

    def unscale_z(self, zt: np.ndarray) -> np.ndarray:
        """``z = D_c z~``; an entry past the float64 range becomes inf, without a warning (an
        answer whose z is not representable in the problem's units: its certificate fails)."""
        with np.errstate(over="ignore"):
            return np.ldexp(np.asarray(zt, dtype=np.float64), self.col.astype(np.int32))

    def scale_w(self, w: np.ndarray) -> np.ndarray:
        """``w~ = D_r w`` (also for vectors in the units of w, e.g. a covering vector)."""
        return np.ldexp(np.asarray(w, dtype=np.float64), self.row.astype(np.int32))

    def unscale_w(self, wt: np.ndarray) -> np.ndarray:
        """``w = D_r^-1 w~``; an entry past the float64 range becomes inf, without a warning
        (its certificate fails)."""
        with np.errstate(over="ignore"):
            return np.ldexp(np.asarray(wt, dtype=np.float64), (-self.row).astype(np.int32))

    def farkas_back(self, yt: Any) -> np.ndarray:
        """A Farkas vector of the scaled problem in the units of the given one: ``y = D_r y~``
        (``M~^T y~ = D_c M^T D_r y~`` and ``q~^T y~ = q^T D_r y~``, so the signs carry over);
        an entry past the float64 range becomes inf, without a warning (its check fails)."""
        with np.errstate(over="ignore"):
            return np.ldexp(np.asarray(yt, dtype=np.float64), self.row.astype(np.int32))

    @cached_property
    def ranges(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """``((min, max) of the row exponents, (min, max) of the column exponents)``, computed
        once (messages and ``info`` both show them)."""
        r, c = self.row.tolist(), self.col.tolist()
        return (min(r), max(r)), (min(c), max(c))

    def describe(self) -> str:
        """One phrase for messages: the ranges of the factors."""
        def span(lo: int, hi: int) -> str:
            return f"2^{lo}" if lo == hi else f"2^{lo}..2^{hi}"

        rows, cols = self.ranges
        return f"equilibrated ({self.kind}: rows x {span(*rows)}, columns x {span(*cols)})"


def equilibrate(problem: Problem, symmetric: bool) -> Scaling | None:
    """The scaling that balances ``problem`` (None when it is balanced already).

    ``symmetric`` asks for ``D M D`` (see the module docstring).  Zero rows and columns keep
    factor 1.  Compiled (``_scaling.pyx``): one pass over the nonzeros when the problem is
    balanced already, O(nnz) integer work per round otherwise.
    """
    if problem.n == 0:
        return None
    found = ruiz_exponents(_matrix_arg(problem.M), problem.q, symmetric, BALANCED, Q_BALANCED,
                           MAX_ROUNDS)
    if found is None:
        return None
    r, c = found
    return Scaling(row=r, col=c, kind="symmetric" if symmetric else "two-sided")


def is_balanced(problem: Problem) -> bool:
    """True when :func:`equilibrate` would leave ``problem`` alone (one compiled pass; the
    answer does not depend on the ``symmetric`` choice)."""
    M = problem.M
    if type(M) is np.ndarray:
        return balanced_dense(M, problem.q, BALANCED, Q_BALANCED)
    if problem.n == 0:
        return True
    return ruiz_exponents(_matrix_arg(M), problem.q, False, BALANCED, Q_BALANCED, 1) is None


def _matrix_arg(M: Any) -> Any:
    if type(M) is np.ndarray:
        return M
    Mc = M.tocsr()
    return (Mc.data, Mc.indices.astype(np.intp, copy=False), Mc.indptr.astype(np.intp, copy=False))


def geometric(problem: Problem, symmetric: bool) -> Scaling | None:
    """Curtis and Reid's scaling (1972), rounded to powers of two: the exponents ``r``, ``c``
    that minimise ``sum over the nonzeros of (log2 |M_ij| + r_i + c_j)^2`` (``r = c`` when
    ``symmetric``), then ``q`` normalised by a common factor as in :func:`equilibrate`.

    Where Ruiz's infinity-norm iteration stops as soon as every row and column *maximum* is
    about 1 (and may leave other entries at 2^-72, e.g. on the diagonal of
    ``diag(2^a) K diag(2^b)``), this least-squares fit recovers any row and column scaling of a
    matrix with entries of one size exactly, up to the rounding of the exponents: it is
    invariant under power-of-two row and column scalings of the data.  Solved by LSQR on the
    sparse incidence matrix (O(nnz) per iteration; scipy).  None when nothing would change.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.linalg import lsqr

    n = problem.n
    if n == 0:
        return None
    Mc = csr_matrix(problem.M).tocoo() if problem.sparse else None
    if Mc is not None:
        rows, cols, vals = Mc.row, Mc.col, Mc.data
    else:
        rows, cols = np.nonzero(problem.M)
        vals = problem.M[rows, cols]
    keep = vals != 0
    rows, cols, vals = rows[keep], cols[keep], vals[keep]
    if vals.size == 0:
        return None
    e = np.frexp(np.abs(vals))[1].astype(np.float64)
    k = np.arange(vals.size)
    if symmetric:
        A = csr_matrix((np.ones(2 * k.size), (np.concatenate([k, k]),
                                              np.concatenate([rows, cols]))),
                       shape=(k.size, n))
    else:
        A = csr_matrix((np.ones(2 * k.size), (np.concatenate([k, k]),
                                              np.concatenate([rows, n + cols]))),
                       shape=(k.size, 2 * n))
    x = lsqr(A, -e, atol=1e-12, btol=1e-12, iter_lim=50 * n + 100)[0]
    if not np.all(np.isfinite(x)):
        return None
    r = np.rint(x[:n]).astype(np.int64)
    c = r.copy() if symmetric else np.rint(x[n:]).astype(np.int64)
    q = problem.q
    nz = q != 0
    if np.any(nz):
        shift = 1 - int(np.max(np.frexp(np.abs(q[nz]))[1] + r[nz]))
        r += shift
        c -= shift
    if not np.any(r) and not np.any(c):
        return None
    scaled = e + r[rows] + c[cols]
    if np.any(nz):
        scaled = np.concatenate([scaled, np.frexp(np.abs(q[nz]))[1] + r[nz]])
    if scaled.max() > GEOMETRIC_RANGE or scaled.min() < -GEOMETRIC_RANGE:
        return None  # the data span more than the double range can hold at one scale
    return Scaling(row=r, col=c, kind="geometric, symmetric" if symmetric else "geometric")


#: :func:`geometric` gives up when a scaled entry would leave ``[2^-GEOMETRIC_RANGE,
#: 2^GEOMETRIC_RANGE]`` (Ruiz's scaling is kept then).
GEOMETRIC_RANGE = 1000
#: Methods and the enumeration turn to :func:`geometric` when a scaled matrix's nonzero
#: entries still span more than 2^GEOMETRIC_SPREAD (Ruiz balanced the maxima only).
GEOMETRIC_SPREAD = 30


def spread(problem: Problem, scaling: Scaling | None) -> int:
    """``max - min`` of the binary exponents of the nonzero entries of ``D_r M D_c`` (of M
    when ``scaling`` is None); 0 for a zero matrix."""
    M = problem.M
    if problem.sparse:
        Mc = M.tocoo()
        rows, cols, vals = Mc.row, Mc.col, Mc.data
    else:
        rows, cols = np.nonzero(M)
        vals = M[rows, cols]
    keep = vals != 0
    if not np.any(keep):
        return 0
    e = np.frexp(vals[keep])[1].astype(np.int64)
    if scaling is not None:
        e = e + scaling.row[rows[keep]] + scaling.col[cols[keep]]
    return int(e.max() - e.min())
