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
from typing import Any

import numpy as np

from lcpcli.core.problem import Problem

#: A problem whose row and column maxima are all within 2^BALANCED of each other is left alone.
BALANCED = 4
#: ... and ``q`` is left alone when its largest entry is within 2^Q_BALANCED of 1.
Q_BALANCED = 8
#: Ruiz iterations at most (each halves the spread of the exponents; 12 covers 2^4000).
MAX_ROUNDS = 12


@dataclass(frozen=True)
class Scaling:
    """Row and column exponents (see the module docstring); ``kind`` is how they were chosen."""

    row: np.ndarray
    col: np.ndarray
    kind: str

    def apply(self, problem: Problem) -> Problem:
        """The scaled problem ``(D_r M D_c, D_r q)`` with bounds ``D_c^-1 [l, u]``."""
        M = problem.M
        if np.all(self.row == -self.col[0]) and np.all(self.col == self.col[0]):
            Ms: Any = M  # rows x 2^k and columns x 2^-k: M itself is unchanged
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
        """``z = D_c z~``."""
        return np.ldexp(np.asarray(zt, dtype=np.float64), self.col.astype(np.int32))

    def scale_w(self, w: np.ndarray) -> np.ndarray:
        """``w~ = D_r w`` (also for vectors in the units of w, e.g. a covering vector)."""
        return np.ldexp(np.asarray(w, dtype=np.float64), self.row.astype(np.int32))

    def unscale_w(self, wt: np.ndarray) -> np.ndarray:
        """``w = D_r^-1 w~`` (also for dual vectors: a Farkas ``y~`` maps to ``D_r y~``)."""
        return np.ldexp(np.asarray(wt, dtype=np.float64), (-self.row).astype(np.int32))

    def describe(self) -> str:
        """One phrase for messages: the ranges of the factors."""
        def span(e: np.ndarray) -> str:
            lo, hi = int(e.min()), int(e.max())
            return f"2^{lo}" if lo == hi else f"2^{lo}..2^{hi}"

        return f"equilibrated ({self.kind}: rows x {span(self.row)}, columns x {span(self.col)})"


def equilibrate(problem: Problem, symmetric: bool) -> Scaling | None:
    """The scaling that balances ``problem`` (None when it is balanced already).

    ``symmetric`` asks for ``D M D`` (see the module docstring).  Zero rows and columns keep
    factor 1.  Cost: one pass over the nonzeros to read their exponents, then O(nnz) integer
    work per round.
    """
    n = problem.n
    if n == 0:
        return None
    M = problem.M
    if problem.sparse:
        Mc = M.tocoo()
        rows, cols, vals = Mc.row, Mc.col, Mc.data
        keep = vals != 0
        rows, cols, vals = rows[keep], cols[keep], vals[keep]
    else:
        rows, cols = np.nonzero(M)
        vals = M[rows, cols]
    e = np.frexp(vals)[1].astype(np.int64)  # |M_ij| in [2^(e-1), 2^e)
    r = np.zeros(n, dtype=np.int64)
    c = np.zeros(n, dtype=np.int64)
    floor = np.iinfo(np.int64).min // 4
    for _ in range(MAX_ROUNDS):
        ee = e + r[rows] + c[cols]
        rmax = np.full(n, floor)
        cmax = np.full(n, floor)
        np.maximum.at(rmax, rows, ee)
        np.maximum.at(cmax, cols, ee)
        rmax[rmax == floor] = 1   # zero rows and columns: leave them
        cmax[cmax == floor] = 1
        if max(np.ptp(rmax), np.ptp(cmax)) <= BALANCED and abs(int(rmax.max()) - 1) <= BALANCED:
            break
        if symmetric:
            d = -(np.maximum(rmax, cmax) - 1) // 2
            r = r + d
            c = c + d
        else:
            r = r - (rmax - 1) // 2
            ee = e + r[rows] + c[cols]
            cmax = np.full(n, floor)
            np.maximum.at(cmax, cols, ee)
            cmax[cmax == floor] = 1
            c = c - (cmax - 1) // 2
    # a common factor normalising q (M~ unchanged: rows x 2^k, columns x 2^-k)
    qt = np.ldexp(problem.q, r.astype(np.int32))
    qmax = float(np.max(np.abs(qt)))
    k = -int(np.frexp(qmax)[1]) + 1 if qmax > 0 else 0
    if abs(k) <= Q_BALANCED and not r.any() and not c.any():
        return None
    r = r + k
    c = c - k
    return Scaling(row=r, col=c, kind="symmetric" if symmetric else "two-sided")
