"""Block principal pivoting (Kostreva 1978; Júdice & Pires 1994) for the LCP and the MLCP.

Problem: LCP(q, M), ``w = M z + q`` (MLCP: the first ``n_eq`` variables free, always basic).
A *basis* is the set ``F`` of basic z's (the other pairs have ``w_i`` basic and ``z_i = 0``); its
basic solution solves ``M_FF z_F = -q_F`` and sets ``w_G = q_G + M_GF z_F`` (G the complement).
Every iteration solves for the basic solution and finds the *infeasible* pairs (``z_i < 0`` in F,
``w_i < 0`` in G); with none, the basic solution solves the problem.  Otherwise (Júdice &
Pires, "A block principal pivoting algorithm for large-scale strictly monotone linear
complementarity problems", Computers & Operations Research 21, 1994):

* while the number of infeasible pairs keeps falling, or for at most ``block_tries`` iterations
  after it last fell, *every* infeasible pair is exchanged at once (a block pivot);
* after that, only the least-index infeasible pair is exchanged (Murty's least-index rule,
  1974), until the count falls below its best again.

Pure block pivoting can cycle even on P-matrices; the single-pivot fallback makes the method
finite on **P-matrices** (Murty's rule is), ending at the unique solution.  Block pivots usually
end it in a handful of factorisations, independent of n, which is why a nearby basis (a warm
start: :mod:`lcpcli.solvers.warm`) ends it in one or two.  On other matrices ``M_FF`` may be
singular (reported as ``singular_basis``) or the pivot limit may be reached; the answer is
judged by the shared certificate, never by this module.

Cost: one product with M (O(n^2)) per iteration, and a dense factorisation of ``M_FF``
(Cholesky for a symmetric M, else LU; O(|F|^3)) only when the basis has moved more than
``2 sqrt(n)`` pairs from the last factored one (:class:`Blocks`: bordered Schur-complement
solves otherwise); a sparse M is densified.  ``z0`` starts from the basis ``{i: z0_i > 0}``
(or give ``basis=``).
"""

from __future__ import annotations

import copy
import warnings
from typing import Any

import numpy as np

from lcpcli.analysis.classify import is_symmetric
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, SINGULAR, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.options import basis_option, index_set, positive_int, vector_option
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import preload_linalg, start_point

#: Block pivots allowed without a new lowest count of infeasible pairs (Júdice & Pires' p).
BLOCK_TRIES = 3
#: A basic value is infeasible below ``-NEG_TOL`` times its row's scale ``|q_i| + (|M||z|)_i``
#: (for ``w_i``) or ``||z||_inf`` (for ``z_i``).
NEG_TOL = 1e-12
#: A pivot block whose LU has ``min |u_ii| <= SINGULAR_TOL * max |u_ii|`` counts as singular.
SINGULAR_TOL = 1e-14


def default_max_iter(n: int) -> int:
    """Iteration limit when none is given (finite for P-matrices)."""
    return max(100, 10 * n)


def factor_block(A: np.ndarray, symmetric: bool) -> Any:
    """A solver ``x = solve(b)`` (b a vector or a matrix of columns) for the square ``A``
    (destroyed), or None when ``A`` is singular to :data:`SINGULAR_TOL`: Cholesky when
    ``symmetric`` and ``A`` is positive definite (half the work of LU), LU otherwise."""
    from scipy.linalg import LinAlgError, LinAlgWarning, cho_factor, cho_solve, lu_factor, lu_solve

    if symmetric:
        try:
            c = cho_factor(A.copy(), lower=False, overwrite_a=True, check_finite=False)
        except LinAlgError:
            pass
        else:
            d = np.abs(np.diag(c[0]))
            if np.all(np.isfinite(d)) and d.min() ** 2 > SINGULAR_TOL * d.max() ** 2:
                return lambda b: cho_solve(c, b, check_finite=False)
    # factor the transpose: a C-ordered A is a Fortran-ordered A^T, factored in place (no
    # copy); solves then use trans=1
    with warnings.catch_warnings():  # a singular block is reported below, not warned about
        warnings.simplefilter("ignore", LinAlgWarning)
        lu = lu_factor(A.T, overwrite_a=True, check_finite=False)
    d = np.abs(np.diag(lu[0]))
    if not np.all(np.isfinite(d)) or d.min() <= SINGULAR_TOL * d.max():
        return None
    return lambda b: lu_solve(lu, b, trans=1, check_finite=False)


def _probe(M: np.ndarray) -> np.ndarray:
    """A copy of the entries of ``M`` that :meth:`Blocks.reuse` compares to tell an M changed
    in place: its diagonal and a grid of at most 17 x 17 entries (O(n), against O(n^2) to
    compare or copy all of M)."""
    step = max(1, M.shape[0] // 16)
    return np.concatenate([M.diagonal(), M[::step, ::step].ravel()])


class Blocks:
    """Basic solutions of the bases of one LCP, with one factorisation shared by nearby bases.

    The block ``M_{F0 F0}`` of a basis ``F0`` is factored once; a basis ``F`` that differs from
    it in ``k`` pairs (``F = F0 - R + A``) is solved through the bordered system (the Schur
    complement, Cottle-Pang-Stone section 4.1 on principal pivoting)::

        [ M_{F0 F0}  M_{F0 A}  E_R ] [x  ]   [-q_F0]
        [ M_{A F0}   M_{A A}   0   ] [z_A] = [-q_A ],      x_R = E_R^T x = 0,
        [ E_R^T      0         0   ] [l  ]   [ 0   ]

    at the cost of k solves with the factors and one k x k LU; ``F`` is refactored instead
    when ``k`` exceeds :attr:`max_k` or the Schur complement is singular.  The solved border
    columns (``M_{F0 F0}^-1 M_{F0 j}``, ``M_{F0 F0}^-1 e_r``) depend on M and ``F0`` only, so
    they are kept for the next bases and the next ``q`` (:meth:`reuse`: a time-stepping
    sequence solves only the columns of pairs it has not bordered before), and so is the Schur
    complement's LU of the last basis (for :meth:`refine`).  ``factorisations`` counts the full
    ones.
    """

    def __init__(self, M: np.ndarray, q: np.ndarray, symmetric: bool) -> None:
        self.M, self.q, self.symmetric = M, q, symmetric
        self._probe = _probe(M)  # M is held by reference: a caller may change it in place
        self.F0: np.ndarray | None = None
        self.solve0: Any = None
        self.x0 = np.zeros(0)
        self.factorisations = 0
        #: Pairs changed from the factored basis beyond which a new factorisation is cheaper.
        self.max_k = max(8, int(np.sqrt(q.shape[0])) * 2)
        self._columns: dict[int, np.ndarray] = {}  # pair -> its solved border column
        self._schur: tuple[bytes, Any, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None \
            = None

    def fork(self) -> Blocks:
        """A copy for one more solve (:func:`lcpcli.solvers.warm.warm_start` takes one from a
        Result): the factors, the solved border columns and the Schur complement's LU are
        shared, never changed in place; what a solve changes (``q``, the last basis's
        solution, a refactorisation, new columns) is the copy's own.  So a Result's blocks
        give the same answer whatever solves used them before, in this thread or another."""
        twin = copy.copy(self)
        twin._columns = dict(self._columns)
        return twin

    def reuse(self, M: np.ndarray, q: np.ndarray) -> bool:
        """Take the new ``q`` of a problem with the same M (True), keeping the factors of the
        last basis; False (nothing changed) when M differs, or when the M these factors were
        made from has changed in place at its probe (:func:`_probe`: a simulation loop that
        updates one M array; a change the probe misses gives factors whose answer fails the
        certificate, and the solve goes on cold)."""
        if not np.array_equal(_probe(self.M), self._probe):
            return False
        if M is not self.M and (M.shape != self.M.shape or not np.array_equal(M, self.M)):
            return False
        self.q = q
        if self.F0 is not None and self.solve0 is not None:
            self.x0 = self.solve0(-q[self.idx0])
        return True

    def _refactor(self, F: np.ndarray) -> bool:
        idx = np.flatnonzero(F)
        self.F0, self.factorisations = F.copy(), self.factorisations + 1
        self.idx0 = idx
        self._columns, self._schur = {}, None
        self.solve0 = factor_block(self.M[np.ix_(idx, idx)], self.symmetric) if idx.size else \
            (lambda b: b)
        if self.solve0 is None:  # singular: nothing factored (the next basis refactors)
            self.F0 = None
            return False
        self.x0 = self.solve0(-self.q[idx])
        return True

    def solve(self, F: np.ndarray) -> np.ndarray | None:
        """The basic z of basis ``F`` (booleans); None when its block is singular.  No
        refinement here (:meth:`refine`: the final basis only; the signs that decide the next
        basis do not need it)."""
        n = self.q.shape[0]
        z = np.zeros(n)
        if self.F0 is None or np.count_nonzero(F != self.F0) > self.max_k:
            if not self._refactor(F):
                return None
            z[self.idx0] = self.x0
        elif np.array_equal(F, self.F0):
            z[self.idx0] = self.x0
        else:
            zF = self._bordered(F, None)
            if zF is None:
                if not self._refactor(F):
                    return None
                z[self.idx0] = self.x0
            else:
                z[F] = zF[F]
        return z if np.all(np.isfinite(z)) else None

    def solve_rhs(self, F: np.ndarray, b: np.ndarray) -> np.ndarray | None:
        """``y`` with ``M_FF y_F = b_F`` and 0 off F (a length-n vector), through the factors
        (bordered when ``F`` is near the factored basis, else refactored); None when the block
        is singular."""
        n = self.q.shape[0]
        far = self.F0 is None or np.count_nonzero(F != self.F0) > self.max_k
        if far and not self._refactor(F):
            return None
        out = np.zeros(n)
        if np.array_equal(F, self.F0):
            out[self.idx0] = self.solve0(b[self.idx0])
        else:
            y = self._bordered(F, b)
            if y is None:
                if not self._refactor(F):
                    return None
                out[self.idx0] = self.solve0(b[self.idx0])
            else:
                out[F] = y[F]
        return out if np.all(np.isfinite(out)) else None

    def refine(self, F: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """One step of iterative refinement of the basic z of ``F`` (the one just solved),
        given ``w = M z + q``, whose rows in F should be 0."""
        idx = np.flatnonzero(F)
        if idx.size == 0 or self.F0 is None:
            return z
        out = z.copy()
        if np.array_equal(F, self.F0):
            out[idx] -= self.solve0(w[idx])
        else:
            rhs = np.zeros(self.q.shape[0])
            rhs[idx] = -w[idx]
            dz = self._bordered(F, rhs)
            if dz is None:
                return z
            out[idx] += dz[idx]
        return out if np.all(np.isfinite(out)) else z

    def _border(self, added: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """``M_{F0 F0}^-1 [M_{F0 A}, E_R]`` (R at places ``pos`` of F0), new columns solved in
        one call and all kept (:attr:`_columns`: key ``j`` for an added pair, ``-1 - p`` for
        the unit column of place ``p``)."""
        idx0, cache = self.idx0, self._columns
        keys = [int(j) for j in added] + [-1 - int(p) for p in pos]
        new = [k for k in keys if k not in cache]
        if new:
            if len(cache) + len(new) > 8 * self.max_k:
                cache.clear()
                new = keys
            B = np.zeros((idx0.size, len(new)))
            for c, k in enumerate(new):
                if k >= 0:
                    B[:, c] = self.M[idx0, k]
                else:
                    B[-1 - k, c] = 1.0
            X = self.solve0(B)
            for c, k in enumerate(new):
                cache[k] = X[:, c]
        X = np.empty((idx0.size, len(keys)))
        for c, k in enumerate(keys):
            X[:, c] = cache[k]
        return X

    def _bordered(self, F: np.ndarray, b: np.ndarray | None) -> np.ndarray | None:
        """Solve ``M_FF z_F = b_F`` through the factors of ``M_{F0 F0}`` (a length-n vector,
        meaningful on F; ``b`` None: ``-q``), or None when the Schur complement is
        singular."""
        idx0 = self.idx0
        key = F.tobytes()
        if self._schur is not None and self._schur[0] == key:
            _, lu, X, added, removed, pos = self._schur
        else:
            from scipy.linalg import LinAlgWarning, lu_factor

            added = np.flatnonzero(F & ~self.F0)
            removed = np.flatnonzero(self.F0 & ~F)
            pos = np.searchsorted(idx0, removed)  # places of the removed pairs within F0
            a = added.size
            X = self._border(added, pos) if idx0.size else np.zeros((0, a + removed.size))
            S = np.zeros((a + removed.size, a + removed.size))
            S[:a, :a] = self.M[np.ix_(added, added)]
            if idx0.size:
                S[:a] -= self.M[np.ix_(added, idx0)] @ X
                S[a:] -= X[pos]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", LinAlgWarning)
                lu = lu_factor(S, check_finite=False)
            d = np.abs(np.diag(lu[0]))
            if d.size and (not np.all(np.isfinite(d)) or d.min() <= 1e-10 * d.max()):
                return None
            self._schur = (key, lu, X, added, removed, pos)
        from scipy.linalg import lu_solve

        a = added.size
        if idx0.size:
            x0 = self.x0 if b is None else self.solve0(b[idx0])
            rhs = np.concatenate([(-self.q if b is None else b)[added]
                                  - self.M[np.ix_(added, idx0)] @ x0, -x0[pos]])
        else:
            x0 = np.zeros(0)
            rhs = np.concatenate([(-self.q if b is None else b)[added], np.zeros(pos.size)])
        u = lu_solve(lu, rhs, check_finite=False) if rhs.size else np.zeros(0)
        out = np.zeros(self.q.shape[0])
        out[idx0] = x0 - X @ u
        out[removed] = 0.0
        out[added] = u[:a]
        return out


def pivot(M: np.ndarray, q: np.ndarray, F: np.ndarray, free: np.ndarray, max_iter: int,
          block_tries: int = BLOCK_TRIES, symmetric: bool = False,
          blocks: Blocks | None = None) -> tuple[str, np.ndarray, int, int, np.ndarray, int]:
    """Run block principal pivoting from the basis ``F`` (booleans; ``free`` pairs are always
    basic).  Returns ``(status, z, iterations, single_pivots, F, factorisations)`` with status
    ``"ok"`` (every basic variable nonnegative), ``"singular"`` (a singular ``M_FF``) or
    ``"limit"``.  ``symmetric``: M is symmetric (Cholesky is tried first); ``blocks``: the
    factors of an earlier run on the same M and q (:meth:`Blocks.reuse`), updated in place."""
    n = q.shape[0]
    F = F | free
    if blocks is None:
        blocks = Blocks(M, q, symmetric)
    done = blocks.factorisations
    best, tries, singles = n + 1, block_tries, 0
    z = np.zeros(n)
    for it in range(1, max_iter + 1):
        zn = blocks.solve(F)
        if zn is None:
            return "singular", z, it, singles, F, blocks.factorisations - done
        z = zn
        w = M @ z + q
        zmax = float(np.max(np.abs(z), initial=0.0))
        bad = F & (z < -NEG_TOL * max(1.0, zmax)) & ~free
        rows = np.flatnonzero(~F & (w < 0))  # w_i < 0: judged against the row's own scale
        if rows.size:
            scale = np.abs(q[rows]) + np.abs(M[rows]) @ np.abs(z)
            bad[rows[w[rows] < -NEG_TOL * scale]] = True
        count = int(np.count_nonzero(bad))
        if count == 0:
            z = blocks.refine(F, z, w)
            return "ok", z, it, singles, F, blocks.factorisations - done
        if count < best:
            best, tries = count, block_tries
            F = F ^ bad
        elif tries > 0:
            tries -= 1
            F = F ^ bad
        else:  # Murty's least-index rule: finite on P-matrices
            i = int(np.argmax(bad))
            F = F.copy()
            F[i] = not F[i]
            singles += 1
    return "limit", z, max_iter, singles, F, blocks.factorisations - done


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, basis: Any = None,
        block_tries: int = BLOCK_TRIES, blocks: Blocks | None = None,
        keep_blocks: bool = False) -> Outcome:
    """Solve ``problem`` (LCP or MLCP) by block principal pivoting; see the module docstring.

    ``blocks`` (not a user option; :mod:`lcpcli.solvers.warm`): the :class:`Blocks` of an
    earlier run on the same M, whose factors are reused; ``keep_blocks``: return this run's
    in ``info["blocks"]``."""
    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    limit = max_iter or default_max_iter(n)
    free = np.zeros(n, dtype=bool)
    free[:problem.n_eq] = True
    F = np.zeros(n, dtype=bool)
    start = ""
    if basis is not None:
        F = index_set(basis, n)
        start = f" from the given basis ({int(F.sum())} z basic)"
    elif z0 is not None:
        F = start_point(problem, z0) > 0
        start = f" from the warm-start basis ({int(F.sum())} z basic)"
    if blocks is None or not blocks.reuse(M, q):
        blocks = Blocks(M, q, is_symmetric(M, 0.0))
    status, z, its, singles, F, factors = pivot(M, q, F, free, limit, block_tries,
                                                blocks=blocks)
    info: dict[str, Any] = {"basis": np.flatnonzero(F).tolist(), "single_pivots": singles,
                            "factorisations": factors}
    if keep_blocks:
        info["blocks"] = blocks
    did = (f"{plural(its, 'iteration')}, {plural(factors, 'factorisation')} "
           f"({plural(singles, 'single pivot')} by Murty's least-index fallback){start}")
    if status == "ok":
        return Outcome(z, its, CONVERGED, f"BPP: all basic variables nonnegative after {did}",
                       info=info)
    if status == "singular":
        return Outcome(z, its, SINGULAR, f"BPP: singular pivot block M_FF after {did}; M is "
                                         f"not a P-matrix, outside the method's class",
                       info=info)
    return Outcome(z, its, ITERATION_LIMIT, f"BPP: limit of {limit} iterations reached "
                                            f"{start} (M may not be a P-matrix)", info=info)


METHODS = [
    Method(
        name="bpp",
        preload=preload_linalg,
        run=run,
        summary="block principal pivoting (Kostreva; Júdice-Pires), Murty's least-index "
                "fallback against cycling; warm-startable from a basis",
        guarantees=(Guarantee(when("p_matrix"), "finite: the unique solution"),),
        notes="others: may stop on a singular pivot block",
        cost=Cost.FACTORING,
        preference=50,
        kinds=("lcp", "mlcp"),
        options={
            "max_iter": Option(positive_int, None, "iteration limit (default "
                                                   "max(100, 10 n))"),
            "z0": Option(vector_option, None, "warm start: start from the basis "
                                              "{i: z0_i > 0}"),
            "basis": Option(basis_option, None, "start from this basis (booleans, True: z_i "
                                                 "basic)"),
            "block_tries": Option(positive_int, BLOCK_TRIES, "block pivots without progress "
                                                             "before the single-pivot rule"),
        },
        scaling="auto",
    ),
]
