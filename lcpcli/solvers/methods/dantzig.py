"""Dantzig's principal pivoting (Cottle-Dantzig / Keller, as ODE's dLCP) for LCPs and box LCPs.

Problem: ``w = M z + q`` with ``lower <= z <= upper`` (LCP: ``lower = 0``, ``upper = inf``);
the box form asks ``w >= 0`` where ``z_i = lower_i``, ``w <= 0`` where ``z_i = upper_i`` and
``w = 0`` strictly between.  Either side may be infinite; a variable with both infinite is
free (its row is an equality ``w_i = 0``) and is processed first; ``lower_i = upper_i`` fixes
``z_i``.

Method: the indices are added one at a time; the driving index moves its ``z`` until its ``w``
is zero or ``z`` reaches a bound, while the clamped block ``C`` (``w_C = 0``) follows and
clamped/bounded indices change sides at the first blocking event.  The inverse of ``M[C, C]``
is updated by bordering/downdating in O(k^2) per pivot, with a periodic
refactorisation; the final active set is re-solved on the original
problem.  O(n) pivots in practice, O(n^2) work each.

Matrix classes: symmetric positive semidefinite (incl. PD) and P-matrices (all principal
pivots positive), with box bounds, infinite sides and free variables (those need ``M`` of the
free block invertible).  Other matrices may hit a singular block or an unbounded direction:
``unsolved``, never a false ``solved`` (every answer is certified).

Warm start from an index set (LCP only): ``basis=`` names the set ``F`` of basic z's (a
previous Result, its ``basis`` codes or letters, booleans; see
:func:`lcpcli.solvers.options.basis_option`).  The LCP is first replaced by its principal pivot
transform on ``M_FF`` (:func:`principal_pivot_transform`: ``w_F`` and ``z_F`` exchange roles),
then the method runs on the transform from its start and the answer is mapped back, so a basis
that still solves the problem ends in 0 pivots (one factorisation of ``M_FF``: its basic
solution is feasible, and the transform is not even formed).  A singular
``M_FF`` is repaired first by dropping its dependent pairs
(:func:`lcpcli.solvers.methods.lemke_warm.repair`, as warm Lemke does).  Which guarantees
survive: a principal pivot transform of a P-matrix is a P-matrix and one of a positive
semidefinite matrix (``x^T M x >= 0``) is positive semidefinite (Cottle-Pang-Stone, *The
Linear Complementarity Problem*, section 4.1, the invariance theorems); so is one of a column
sufficient matrix (Cottle, Pang and Venkateswaran, "Sufficient matrices and the linear
complementarity problem", 1989).  It is not symmetric in general.  So the warm start keeps the
guarantee for P-matrices, positive definite ones included (their transform is positive
definite, non-symmetric); on a singular symmetric PSD M the transform leaves the method's
stated class (symmetric PSD), and a warm run that ends without an answer is followed by the
cold run (:mod:`lcpcli.solvers.warm`).  A box LCP's basis has three states and its transform
is no box LCP: ``basis=`` is refused there.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis._scaling import is_symmetric_dense
from lcpcli.analysis.mlcp import polish
from lcpcli.core.errors import OptionError
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, NUMERICAL, RAY, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.kernels.dantzig import (
    AT_LOWER,
    AT_UPPER,
    CLAMPED,
    MAX_ITER,
    OK,
    SINGULAR,
    dantzig_kernel,
)
from lcpcli.solvers.methods.bpp import factor_block
from lcpcli.solvers.methods.lemke_warm import repair
from lcpcli.solvers.options import basis_option, bool_option, index_set, positive_int
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import preload_for_basis


def processing_order(lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Free variables first (they must end clamped), then the rest in index order."""
    free = ~np.isfinite(lo) & ~np.isfinite(up)
    return np.concatenate([np.flatnonzero(free), np.flatnonzero(~free)]).astype(np.int64)


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        basis: np.ndarray | None = None, trace: bool = False) -> Outcome:
    """Solve an LCP or box LCP by principal pivoting; see the module docstring.

    ``basis`` (booleans, True: ``z_i`` basic; LCP only) starts from that index set.
    ``trace=True`` runs the numpy replica :mod:`lcpcli.solvers.trace.dantzig` instead of the
    kernel (same pivots) and records each pivot in ``Outcome.trace`` (a cold run only).
    """
    if basis is not None:
        if problem.kind != "lcp":
            raise OptionError("basis= starts dantzig from an LCP's index set; a box LCP's "
                              "basis has three states (its principal pivot transform is no "
                              "box LCP)")
        if trace:
            raise OptionError("dantzig's trace shows a cold run; it does not start from basis=")
        F = index_set(basis, problem.n)
        if F.any():
            return _run_from(problem, F, max_iter)
    if trace:
        from lcpcli.solvers.trace import Recorder
        from lcpcli.solvers.trace.dantzig import dantzig_traced

        recorder = Recorder(dantzig_traced)
        out = _run(problem, max_iter=max_iter, kernel=recorder)
        out.trace = recorder.trace
        return out
    return _run(problem, max_iter=max_iter)



def default_max_iter(n: int) -> int:
    """Pivot limit when none is given: ``max(1000, 50 n)``."""
    return max(1000, 50 * n)

def _run(problem: Any, *, max_iter: int | None, kernel: Any = None) -> Outcome:

    kernel = kernel or dantzig_kernel

    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    lo, up = problem.bounds()
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    up = np.ascontiguousarray(up, dtype=np.float64)
    limit = max_iter or default_max_iter(n)
    status, z, pivots, state = kernel(M, problem.q, lo, up, processing_order(lo, up), limit)
    return _outcome(problem, status, z, int(pivots), state, limit, "")


def _run_from(problem: Any, F: np.ndarray, max_iter: int | None) -> Outcome:
    """The method from the index set ``F`` (an LCP): on the principal pivot transform of
    ``M_FF``, the answer mapped back (``z_F = w'_F``); see the module docstring."""
    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    limit = max_iter or default_max_iter(n)
    given = int(F.sum())
    start = basic_solution(M, q, F)
    if start is None:  # the block stays singular after the repair: start cold
        out = _run(problem, max_iter=max_iter)
        out.message += " (the given basis's block M_FF is singular; started from z = 0)"
        return out
    kept, solve, z = start
    dropped = given - int(kept.sum())
    how = (f" from the given basis ({given} z basic"
           + (f", {plural(dropped, 'dependent pair')} dropped from its singular block"
              if dropped else ""))
    if feasible(M, q, kept, z):  # q' >= 0: the transform's run would end at once
        state = np.where(kept, CLAMPED, AT_LOWER)
        return _outcome(problem, OK, z, 0, state, limit,
                        f"{how}; its basic solution is feasible: one factorisation)",
                        solved=True)
    how += "; principal pivot transform on its block)"
    Mp, qp = principal_pivot_transform(M, q, kept, solve)
    zero, inf = np.zeros(n), np.full(n, np.inf)
    status, zp, pivots, state = dantzig_kernel(Mp, qp, zero, inf, np.arange(n, dtype=np.int64),
                                               limit)
    z = zp.copy()
    z[kept] = (Mp[kept] @ zp + qp[kept])  # z_F = w'_F: the transform's w of the pairs of F
    # the pairs of F: clamped in the transform means w_i basic here, and the other way round
    state = np.where(kept, np.where(state == AT_LOWER, CLAMPED, np.where(
        state == CLAMPED, AT_LOWER, state)), state)
    return _outcome(problem, status, np.maximum(z, 0.0), int(pivots), state, limit, how)


def basic_solution(M: np.ndarray, q: np.ndarray, F: np.ndarray
                   ) -> tuple[np.ndarray, Any, np.ndarray] | None:
    """``(F', solve, z)``: the basis ``F`` (booleans, True: ``z_i`` basic) made nonsingular,
    its block's solver and its basic solution (``M_F'F' z_F' = -q_F'``, 0 elsewhere; one step
    of iterative refinement).
    ``F'`` is ``F`` less the pairs :func:`lemke_warm.repair` drops when ``M_FF`` is singular;
    None when the repaired block is still singular (one factorisation of ``M_F'F'``,
    :func:`lcpcli.solvers.methods.bpp.factor_block`: Cholesky for a symmetric M)."""
    symmetric = is_symmetric_dense(M)
    a = np.flatnonzero(F)
    solve = factor_block(M.take(a, 0).take(a, 1), symmetric) if a.size else _empty
    if solve is None:
        F = repair(M, F)
        a = np.flatnonzero(F)
        solve = factor_block(M.take(a, 0).take(a, 1), symmetric) if a.size else _empty
        if solve is None:
            return None
    z = np.zeros(q.shape[0])
    z[a] = solve(-q[a])
    if a.size:
        z[a] -= solve(M.take(a, 0) @ z + q[a])
    if not np.all(np.isfinite(z)):
        return None
    return F.copy(), solve, z


def _empty(b: np.ndarray) -> np.ndarray:
    """The solver of an empty block."""
    return b


def feasible(M: np.ndarray, q: np.ndarray, F: np.ndarray, z: np.ndarray) -> bool:
    """Is the basic solution ``z`` of ``F`` feasible: ``z_F >= 0`` and ``w_G >= 0``?  (Then
    every basic variable is nonnegative and the basis solves the LCP.)"""
    if np.any(z[F] < 0.0):
        return False
    G = ~F
    return bool(np.all(q[G] + M[G] @ z >= 0.0))


def principal_pivot_transform(M: np.ndarray, q: np.ndarray, F: np.ndarray, solve: Any
                              ) -> tuple[np.ndarray, np.ndarray]:
    """``(M', q')``: LCP(q, M) pivoted on the nonsingular block ``A = M_FF`` (``solve``: its
    solver, :func:`basic_solution`; Cottle-Pang-Stone, section 4.1), whose variables are
    ``z' = (w_F, z_G)``, ``w' = (z_F, w_G)`` (G the other pairs, index positions kept)::

        M'_FF = A^-1,  M'_FG = -A^-1 M_FG,  M'_GF = M_GF A^-1,  M'_GG = M_GG - M_GF A^-1 M_FG,
        q'_F = -A^-1 q_F,  q'_G = q_G - M_GF A^-1 q_F.

    O(n^2 |F|)."""
    a, b = np.flatnonzero(F), np.flatnonzero(~F)
    k = a.size
    perm = np.concatenate([a, b])  # blocks in the order (F, G): slices, not scatters
    back = np.empty_like(perm)
    back[perm] = np.arange(perm.size)
    P = M.take(perm, 0).take(perm, 1)
    inv = solve(np.eye(k))
    B = np.empty_like(P)
    B[:k, :k] = inv
    np.matmul(inv, P[:k, k:], out=B[:k, k:])  # A^-1 M_FG, negated below
    np.matmul(P[k:, :k], inv, out=B[k:, :k])
    B[k:, k:] = P[k:, k:]
    B[k:, k:] -= P[k:, :k] @ B[:k, k:]
    # not np.negative(..., out=...): numpy 2.4's in-place negative is wrong on a view whose
    # stride is 8 elements (one column of an 8 x 8 B), tests/solvers/test_warm_index_set.py
    B[:k, k:] *= -1.0
    qa = inv @ q[a]
    qp = q.copy()
    qp[a] = -qa
    qp[b] = q[b] - P[k:, :k] @ qa
    return B.take(back, 0).take(back, 1), qp


def _outcome(problem: Any, status: int, z: np.ndarray, pivots: int, state: np.ndarray,
             limit: int, how: str, solved: bool = False) -> Outcome:
    """The Outcome of a kernel run (``how``: the warm start's words, or empty); ``solved``:
    ``z`` is a basic solution solved and refined already (:func:`basic_solution`), not
    polished again."""
    n = problem.n
    clamped = int(np.sum(state == CLAMPED))
    info = {"clamped": clamped, "at_lower": int(np.sum(state == AT_LOWER)),
            "at_upper": int(np.sum(state == AT_UPPER))}
    if status == OK:
        return Outcome(z if solved else polish(problem, z), pivots, CONVERGED,
                       f"all {n} indices processed in {plural(pivots, 'pivot')} "
                       f"({clamped} clamped){how}",
                       info=info)
    if status == MAX_ITER:
        return Outcome(z, pivots, ITERATION_LIMIT,
                       f"pivot limit {limit} reached{how} (raise it with --max-iter)", info=info)
    if status == SINGULAR:
        return Outcome(z, pivots, NUMERICAL,
                       f"singular principal block after {plural(pivots, 'pivot')}{how}: M is "
                       f"not in the method's class (symmetric PSD or P)", info=info)
    return Outcome(z, pivots, RAY,
                   f"unbounded driving direction after {plural(pivots, 'pivot')}{how}: "
                   f"no blocking event "
                   f"(for a PSD M this indicates that no solution exists; not proven here)",
                   info=info)


METHODS = [
    Method(
        name="dantzig",
        preload=preload_for_basis,
        run=run,
        summary="Cottle-Dantzig principal pivoting (ODE's dLCP): one index at a time, "
                "clamped block inverse updated in O(k^2)",
        guarantees=(
            Guarantee(when("symmetric", "psd"), "finite principal pivoting"),
            Guarantee(when("p_matrix"), "finite principal pivoting", kinds=("lcp",)),
        ),
        notes="box bounds, infinite sides and free variables handled",
        cost=Cost.PIVOTING,
        preference=30,
        fallback="principal pivoting outside its classes (on a box LCP, the pivoting method)",
        fallback_preference=90,  # after the other fallbacks of its cost class
        kinds=("lcp", "box"),
        options={"max_iter": Option(positive_int, None, "pivot limit (default max(1000, 50 n))"),
                 "basis": Option(basis_option, None, "warm start (LCP): start from this index "
                                                     "set (a previous result, its basis letters "
                                                     "'FLF' or booleans; True/F: z_i basic) by "
                                                     "a principal pivot transform"),
                 "trace": Option(bool_option, False, "record every pivot (numpy replica of "
                                                      "the kernel, same pivots)")},
        scaling="auto",
    ),
]
