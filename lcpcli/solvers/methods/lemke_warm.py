"""Lemke's method started from a given complementary basis (a warm start).

Problem: LCP(q, M), ``w = M z + q``, augmented as ``w - M z - d z0 = q``.  A complementary
basis is the set ``F`` of basic z's (``w_i`` basic for the other pairs); its basis matrix ``B``
has the column ``e_i`` for a basic ``w_i`` and ``-M_{:i}`` for a basic ``z_i``, and its basic
solution ``x = B^-1 q`` is BPP's (``M_FF z_F = -q_F``, ``w_G = q_G + M_GF z_F``).

* ``x >= 0``: the basis solves the problem (one factorisation; :class:`bpp.Blocks` keeps it).
* Otherwise the covering vector is chosen *in the coordinates of that basis*: ``d = B e``
  (``d_i = [i not in F] - sum_{j in F} M_ij``), so that ``B^-1 d = e`` and raising the
  artificial ``z0`` to ``-min x`` makes every basic variable nonnegative, the most negative one
  leaving.  From that almost complementary basis Lemke's complementary pivoting runs as usual
  (the complement of the variable that left enters; minimum ratio test) until ``z0`` leaves (a
  solution) or a secondary ray.  This is the warm start of Drake's UnrevisedLemkeSolver and of
  Drumwright's Moby LCP solver (Lemke from the previous basis, covering vector ``B e``); from the
  all-w basis ``F = {}`` it is cold Lemke with ``d = e``.

Linear algebra: the starting basis is solved through :class:`bpp.Blocks` (the factors of a
nearby basis block of the same M, bordered); each later pivot replaces one column of ``B``,
kept as an eta file (the product form of the inverse: one O(n) update per pivot and per solve),
so a pivot costs one solve with the block's factors and one product with M.  The final
complementary basis is solved afresh (with one refinement), never taken from the updates.

Guarantees: with a covering vector that is not positive the classical ones (P-matrix,
copositive-plus) do not carry over, so a secondary ray, a singular pivot or the pivot limit
proves nothing here: :func:`run` then reports failure and the caller solves cold
(:mod:`lcpcli.solvers.warm`), whose Lemke gives the proofs.  An answer counts only when it
passes the shared certificate.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis._scaling import is_symmetric_dense
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, RAY, SINGULAR, Outcome
from lcpcli.core.text import plural
from lcpcli.core.tolerances import PIVOT_TOL, TINY_Z
from lcpcli.solvers.methods.bpp import NEG_TOL, Blocks
from lcpcli.solvers.support import better

#: Pivots a warm start may take before the cold solve takes over (a nearby basis needs a
#: handful; each costs O(n^2), a cold Lemke about n/2 pivots of O(n^2)).
WARM_MAX_PIVOTS = 60


class _Basis:
    """The basis matrix ``B`` of Lemke's augmented system as ``B0`` (a complementary basis,
    solved through :class:`Blocks`) times an eta file: ``slots[s]`` is the variable basic in
    slot ``s`` (``i``: ``w_i``, ``n + i``: ``z_i``, ``2n``: ``z0``)."""

    def __init__(self, M: np.ndarray, blocks: Blocks, F: np.ndarray) -> None:
        self.M, self.blocks, self.F0 = M, blocks, F
        n = F.shape[0]
        self.n = n
        self.slots = np.where(F, n + np.arange(n), np.arange(n))
        self.etas: list[tuple[int, np.ndarray]] = []

    def solve0(self, b: np.ndarray) -> np.ndarray | None:
        """``B0^-1 b`` by slot: ``y_F = -M_FF^-1 b_F``, ``y_G = b_G + M_GF y_F``."""
        F = self.F0
        yz = self.blocks.solve_rhs(F, -b)
        if yz is None:
            return None
        y = b + self.M @ yz
        y[F] = yz[F]
        return y

    def solve(self, b: np.ndarray) -> np.ndarray | None:
        """``B^-1 b`` (B0, then the eta file in order)."""
        y = self.solve0(b)
        if y is None:
            return None
        for p, col in self.etas:
            t = y[p] / col[p]
            y -= t * col
            y[p] = t
        return y

    def column(self, var: int, d: np.ndarray) -> np.ndarray:
        """The column of ``var`` in ``w - M z - d z0 = q``."""
        n = self.n
        if var < n:
            e = np.zeros(n)
            e[var] = 1.0
            return e
        if var < 2 * n:
            return -self.M[:, var - n]
        return -d

    def pivot(self, p: int, var: int, col: np.ndarray) -> None:
        """``var`` (whose column in basis coordinates is ``col``) replaces slot ``p``."""
        self.etas.append((p, col))
        self.slots[p] = var


def repair(M: np.ndarray, F: np.ndarray, tol: float = 1e-13) -> np.ndarray:
    """A basis whose block is nonsingular, from ``F`` (booleans): greedy diagonal pivoting on
    ``M_FF`` (the largest diagonal entry of the remaining Schur complement pivots); the pairs
    left when none exceeds ``tol`` times the block's largest entry leave the basis (their
    ``w_i`` becomes basic), as simplex codes repair a singular basis.  Contact LCPs need it:
    redundant contacts make M singular, and the basis ``{i: z0_i > 0}`` of a previous answer
    can have a singular block.  O(|F|^3)."""
    idx = np.flatnonzero(F)
    A = M[np.ix_(idx, idx)].astype(np.float64)
    big = float(np.max(np.abs(A), initial=0.0))
    alive = np.ones(idx.size, dtype=bool)
    keep = np.zeros(idx.size, dtype=bool)
    while alive.any():
        diag = np.where(alive, np.abs(np.diag(A)), -1.0)
        p = int(np.argmax(diag))
        if not diag[p] > tol * big:
            break
        keep[p], alive[p] = True, False
        A -= np.outer(A[:, p], A[p, :]) / A[p, p]
        A[p, :] = 0.0
        A[:, p] = 0.0
    out = np.zeros_like(F, dtype=bool)
    out[idx[keep]] = True
    return out


def run(M: np.ndarray, q: np.ndarray, F: np.ndarray, *, blocks: Blocks | None = None,
        max_pivots: int = WARM_MAX_PIVOTS, problem: Any = None) -> Outcome:
    """Lemke's method for LCP(q, M) (dense M, C-contiguous float64) from the complementary basis
    ``F`` (booleans, True: ``z_i`` basic); see the module docstring.

    ``blocks``: the :class:`Blocks` of an earlier solve with the same M (reused when it is);
    this run's are returned in ``info["blocks"]``, the final basis (0-based basic z's) in
    ``info["basis"]``.  Termination ``CONVERGED`` only with every basic variable nonnegative;
    otherwise ``RAY``, ``SINGULAR`` or ``ITERATION_LIMIT``, which prove nothing (the caller
    solves cold).
    """
    n = q.shape[0]
    F = np.asarray(F, dtype=bool).copy()
    if blocks is None or not blocks.reuse(M, q):
        blocks = Blocks(M, q, is_symmetric_dense(M))
    info: dict[str, Any] = {"blocks": blocks}
    done = blocks.factorisations
    z = blocks.solve(F)
    if z is None:  # a singular block: repaired (the dependent z's leave the basis)
        F = repair(M, F)
        z = blocks.solve(F)
    if z is None:
        return Outcome(np.zeros(n), 0, SINGULAR, "warm Lemke: the given basis's block M_FF is "
                                                  "singular", info=info)
    basis = _Basis(M, blocks, F)
    x = q + M @ z  # the basic values by slot: w_G here, z_F below
    x[F] = z[F]
    # infeasible: z_i < 0 against ||z||, w_i < 0 against its row's scale (as BPP judges)
    neg = F & (x < -NEG_TOL * max(1.0, float(np.max(np.abs(z), initial=0.0))))
    rows = np.flatnonzero(~F & (x < 0))
    if rows.size:
        scale = np.abs(q[rows]) + np.abs(M[rows]) @ np.abs(z)
        neg[rows[x[rows] < -NEG_TOL * scale]] = True
    if not neg.any():
        return _final(M, q, F, blocks, 0, done, info, "the given basis is feasible", problem)
    # z0 enters along the covering ray d = B0 e: x(t) = x + t e; the most negative leaves
    d = np.where(F, 0.0, 1.0) - M @ F.astype(np.float64)
    p = int(np.argmin(x))
    t = -float(x[p])
    x = x + t
    ones = np.ones(n)
    left = int(basis.slots[p])
    basis.pivot(p, 2 * n, -ones)
    x[p] = t
    pivots = 1
    while pivots < max_pivots:
        enter = left + n if left < n else left - n  # the complement of the variable that left
        col = basis.solve(basis.column(enter, d))
        if col is None or not np.all(np.isfinite(col)):
            return Outcome(np.zeros(n), pivots, SINGULAR,
                           f"warm Lemke: singular basis after {plural(pivots, 'pivot')}",
                           info=info)
        big = float(np.max(np.abs(col)))
        cand = np.flatnonzero(col > PIVOT_TOL * max(1.0, big))
        if cand.size == 0:
            return Outcome(np.zeros(n), pivots, RAY,
                           f"warm Lemke: secondary ray after {plural(pivots, 'pivot')} (the "
                           f"covering vector of the given basis is not positive: proves "
                           f"nothing)", info=info)
        ratios = np.maximum(x[cand], 0.0) / col[cand]
        theta = float(ratios.min())
        ties = cand[ratios <= theta * (1.0 + 1e-12) + 1e-300]
        z0_slot = np.flatnonzero(basis.slots[ties] == 2 * n)
        p = int(ties[z0_slot[0]]) if z0_slot.size else int(ties[0])  # z0 first: ends it
        x = x - theta * col
        x[p] = theta
        left = int(basis.slots[p])
        basis.pivot(p, enter, col)
        pivots += 1
        if left == 2 * n:  # z0 left: the basis is complementary
            Fend = np.zeros(n, dtype=bool)
            zs = basis.slots[basis.slots >= n]
            Fend[zs[zs < 2 * n] - n] = True
            return _final(M, q, Fend, blocks, pivots, done, info,
                          f"the artificial variable left after {plural(pivots, 'pivot')} "
                          f"from the given basis ({int(F.sum())} z basic)", problem)
    return Outcome(np.zeros(n), pivots, ITERATION_LIMIT,
                   f"warm Lemke: {plural(pivots, 'pivot')} without a solution", info=info)


def _final(M: np.ndarray, q: np.ndarray, F: np.ndarray, blocks: Blocks, pivots: int, done: int,
           info: dict[str, Any], how: str, problem: Any = None) -> Outcome:
    """The basic solution of the complementary basis ``F``, solved afresh and refined once;
    with ``problem`` given and entries at rounding level (``<= TINY_Z ||z||``: degenerate
    basic z's, which a tableau leaves exactly 0), the candidate with them set to 0 too, the
    one the certificate scores better kept."""
    n = q.shape[0]
    z = blocks.solve(F)
    if z is None:
        return Outcome(np.zeros(n), pivots, SINGULAR,
                       "warm Lemke: the final basis's block is singular", info=info)
    z = np.maximum(blocks.refine(F, z, M @ z + q), 0.0)
    tiny = (z != 0.0) & (z <= TINY_Z * float(np.max(z, initial=0.0)))
    if problem is not None and tiny.any():
        z = better(problem, [z, np.where(tiny, 0.0, z)])[0]
    info["basis"] = np.flatnonzero(F).tolist()
    info["factorisations"] = blocks.factorisations - done
    return Outcome(z, max(pivots, 1), CONVERGED,
                   f"warm Lemke: {how} ({plural(blocks.factorisations - done, 'factorisation')})",
                   info=info)
