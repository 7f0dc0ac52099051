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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.mlcp import polish
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, NUMERICAL, RAY, Outcome
from lcpcli.solvers.kernels.dantzig import MAX_ITER, OK, SINGULAR, dantzig_kernel
from lcpcli.solvers.options import bool_option, positive_int
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when


def processing_order(lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Free variables first (they must end clamped), then the rest in index order."""
    free = ~np.isfinite(lo) & ~np.isfinite(up)
    return np.concatenate([np.flatnonzero(free), np.flatnonzero(~free)]).astype(np.int64)


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        trace: bool = False) -> Outcome:
    """Solve an LCP or box LCP by principal pivoting; see the module docstring.

    ``trace=True`` runs the numpy replica :mod:`lcpcli.solvers.trace.dantzig` instead of the
    kernel (same pivots) and records each pivot in ``Outcome.trace``.
    """
    if trace:
        from lcpcli.solvers.trace import Recorder
        from lcpcli.solvers.trace.dantzig import dantzig_traced

        recorder = Recorder(dantzig_traced)
        out = _run(problem, max_iter=max_iter, kernel=recorder)
        out.trace = recorder.trace
        return out
    return _run(problem, max_iter=max_iter)


def _run(problem: Any, *, max_iter: int | None, kernel: Any = None) -> Outcome:

    kernel = kernel or dantzig_kernel

    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    lo, up = problem.bounds()
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    up = np.ascontiguousarray(up, dtype=np.float64)
    limit = max_iter or max(1000, 50 * n)
    status, z, pivots, state = kernel(M, problem.q, lo, up, processing_order(lo, up), limit)
    clamped = int(np.sum(state == 1))
    info = {"clamped": clamped, "at_lower": int(np.sum(state == 2)),
            "at_upper": int(np.sum(state == 3))}
    if status == OK:
        return Outcome(polish(problem, z), int(pivots), CONVERGED,
                       f"all {n} indices processed in {pivots} pivots ({clamped} clamped)",
                       info=info)
    if status == MAX_ITER:
        return Outcome(z, int(pivots), ITERATION_LIMIT,
                       f"pivot limit {limit} reached (raise it with --max-iter)", info=info)
    if status == SINGULAR:
        return Outcome(z, int(pivots), NUMERICAL,
                       f"singular principal block after {pivots} pivots: M is not in the "
                       f"method's class (symmetric PSD or P)", info=info)
    return Outcome(z, int(pivots), RAY,
                   f"unbounded driving direction after {pivots} pivots: no blocking event "
                   f"(for a PSD M this indicates that no solution exists; not proven here)",
                   info=info)


METHODS = [
    Method(
        name="dantzig",
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
        kinds=("lcp", "box"),
        options={"max_iter": Option(positive_int, None, "pivot limit (default max(1000, 50 n))"),
                 "trace": Option(bool_option, False, "record every pivot (numpy replica of "
                                                      "the kernel, same pivots)")},
        scaling="auto",
    ),
]
