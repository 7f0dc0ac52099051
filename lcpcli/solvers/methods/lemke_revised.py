"""Revised Lemke: Dai & Drumwright's principal pivoting transform with an updated inverse.

Problem: LCP(q, M), ``w = M z + q``, augmented as in Dai & Drumwright with the artificial column
``d`` (covering vector, default all ones): ``w = q + [M, d] z``.

Matrix classes: the same as the tableau method (same pivot rule): a solution for P-matrices,
and for copositive-plus matrices (e.g. positive semidefinite ones) a solution or a proof that
none exists (secondary ray); on other matrices a ray proves nothing.

Each pivot computes only what Lemke needs, by Dai & Drumwright's equations: the entering column
(eqs 5-8) and ``q'`` (eqs 2-3), from ``B = (M^{alpha beta})^{-1}`` which is *updated* in
O(m^2) per pivot (bordering / Sherman-Morrison; ``m`` = number of basic z's), never recomputed,
except every ``refactor_every`` pivots or after a small pivot (then ``inv`` from scratch).
Per-pivot cost O(n m) instead of the tableau's O(n^2); the pivot sequence is the tableau
method's (same lexicographic rule and tolerances) on non-degenerate problems.  The final basis
is polished like the tableau method's (LU re-solve of the basic block).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, NUMERICAL, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.kernels.dense import bind_numpy_lapack
from lcpcli.solvers.kernels.lemke_revised import (
    MAX_ITER,
    OK,
    SINGULAR,
    TRIVIAL,
    lemke_solve_certified,
)
from lcpcli.solvers.methods.lemke import (
    GUARANTEES,
    PIVOT_TOL,
    TIE_TOL,
    batch_params,
    covering_vector,
    default_max_iter,
    ray_outcome,
)
from lcpcli.solvers.methods.lemke import run as run_tableau
from lcpcli.solvers.options import bool_option, positive_int, vector_option
from lcpcli.solvers.registry import BatchSpec, Cost, Method, Option
from lcpcli.solvers.support import RAY_AT_ROUNDING


def _refactor_every(value: Any) -> int:
    v = int(value)
    if v < 1:
        raise ValueError("must be a positive integer")
    return v


def run(problem: Any, *, tol: float, covering: np.ndarray | None = None,
        max_iter: int | None = None, refactor_every: int | None = None,
        trace: bool = False, balance: tuple[int, int] | None = None) -> Outcome | None:
    """Solve ``problem`` (an LCP) by the revised Lemke method; see the module docstring.

    ``trace=True`` records the pivots with the tableau method's step-by-step replica: the
    same pivot rule, hence the same pivots on non-degenerate problems.  ``balance`` (not an
    option: the dispatcher's, ``Method.balance_test``): the thresholds of
    :data:`lcpcli.analysis.scaling.BALANCE`; the compiled call first makes the balance test
    and None is returned, nothing solved, when the problem is not balanced.
    """
    if trace:
        out = run_tableau(problem, tol=tol, covering=covering, max_iter=max_iter, trace=True)
        out.info["trace_engine"] = "tableau replica (same pivot rule)"
        return out
    q = problem.q
    n = len(q)
    M = problem.M  # the kernel takes it as it is when float64 C-contiguous
    if type(M) is not np.ndarray:
        M = problem.dense_M()
    d = None if covering is None else covering_vector(n, covering)  # None: all ones
    # kernel, final polish and the certificate in one compiled call (a limit of 0: the
    # kernels' defaults, default_max_iter and default_refactor_every)
    got = lemke_solve_certified(M, q, d, max_iter or 0, PIVOT_TOL, TIE_TOL, refactor_every or 0,
                                balance)
    if got is None:
        return None
    status = got.status
    if status == OK:  # the artificial variable left the basis
        # the certificate of this z for this problem, as check() computes it (None: out of
        # range or not finite, left to check(), which rescales or computes w)
        cert = got.certificate(tol)
        pivots, refactors = got.pivots, got.refactors
        return Outcome.converged(got.z, pivots,
                                 f"artificial variable left the basis after "
                                 f"{plural(pivots, 'pivot')} ({refactors} refactorisations)",
                                 {"refactorisations": refactors, "basis": got.basis},
                                 None if cert is None else (cert, got.w))
    if status == TRIVIAL:
        return Outcome(np.zeros(n), 0, CONVERGED, "q >= 0: z = 0 solves the problem")
    z, pivots, refactors = got.z, got.pivots, got.refactors
    info = {"refactorisations": refactors}
    if status == MAX_ITER:
        return Outcome(np.maximum(z, 0.0), pivots, ITERATION_LIMIT,
                       f"pivot limit {max_iter or default_max_iter(n)} reached (raise it with "
                       f"--max-iter)", info=info)
    if status == SINGULAR:
        out = Outcome(np.maximum(z, 0.0), pivots, NUMERICAL,
                      f"basis block M^(alpha beta) became singular at a refactorisation "
                      f"after {plural(pivots, 'pivot')}", info=info)
    else:
        out = ray_outcome(problem, M, q, z, pivots, got.ray, got.z0)
        out.info.update(info)
        if out.proven_infeasible:
            return out
    # an unproven ray or a singular block can come from the drift of the updated inverse (a
    # ray at z0 ~ 1e-13 where the tableau reaches the solution): the tableau method follows the
    # same pivot rule with O(n^2) rank-one updates of the whole tableau; let it decide
    again = run_tableau(problem, tol=tol, covering=covering, max_iter=max_iter)
    if again.termination == CONVERGED or again.proven_infeasible \
            or again.info.get(RAY_AT_ROUNDING):
        again.message = f"{out.message}; rerun as lemke-tableau: {again.message}"
        again.iterations += out.iterations
        again.info.update(info)
        return again
    return out


METHODS = [
    Method(
        name="lemke-revised",
        run=run,
        summary="Lemke's complementary pivoting, revised: Dai & Drumwright's transform with an "
                "updated inverse of M^(alpha beta), lexicographic anti-cycling",
        guarantees=GUARANTEES,
        cost=Cost.PIVOTING,
        preference=10,
        fallback="solves many problems outside its classes (a ray then proves nothing)",
        kinds=("lcp",),
        options={
            "covering": Option(vector_option, None, "covering vector d > 0 (default all ones)"),
            "max_iter": Option(positive_int, None, "pivot limit (default max(1000, 100 n))"),
            "refactor_every": Option(_refactor_every, None,
                                     "pivots between refactorisations (default max(50, n))"),
            "trace": Option(bool_option, False, "record every pivot (tableau replica, same "
                                                 "pivot rule)"),
        },
        # the faster of the two on benchmarks/bench_lemke.py (CPU time, n = 10..1000)
        aliases=("lemke",),
        scaling="auto",
        balance_test=True,
        # numpy's OpenBLAS for refactorisations from 64 basic variables: bound before timing,
        # never scipy.linalg (kernels/dense.pyx)
        prepare=bind_numpy_lapack,
        # stacks: the tableau kernel (same lexicographic pivot rule; faster for small n)
        batch=BatchSpec("lemke", ("covering", "max_iter"), runs_as="lemke-tableau",
                        params=batch_params),
    ),
]
