"""``lcpcli.solve``: one entry point for every method, with timing and certification."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from lcpcli.core.certificate import certify, matrix_norm_inf
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem
from lcpcli.core.result import CONVERGED, NO_SOLUTION, SOLVED, UNSOLVED, Outcome, Result
from lcpcli.solvers.registry import Method, get_method

DEFAULT_METHOD = "auto"


def check_dense_ok(problem: Problem, spec: Method) -> None:
    """OptionError when ``spec`` would densify a huge sparse M (checked before any work)."""
    n = problem.n
    if spec.densifies(problem):
        raise OptionError(f"method '{spec.name}' works on a dense {n} x {n} matrix "
                          f"({n * n * 8 / 2**30:.1f} GiB) but M is sparse (nnz={problem.M.nnz}); "
                          f"choose a method for large sparse problems (see 'lcpcli methods')")


def solve(problem: Problem, method: str = DEFAULT_METHOD, *, tol: float | None = None,
          **options: Any) -> Result:
    """Solve ``problem`` with ``method`` and certify the answer.

    ``tol`` bounds the certificate's scaled ``error`` (default: the method's own, 1e-8 for
    pivoting methods).  Method-specific ``options`` (e.g. ``covering=``, ``max_iter=``) are
    checked against the method's declared options; unknown ones raise :class:`OptionError`.

    The verdict is ``solved`` only if the recomputed certificate passes; ``no_solution`` only
    when the method proved it (the proof is in ``message``); ``unsolved`` otherwise.
    ``seconds`` times the method alone (no file reading, no certification).
    """
    spec = get_method(method)
    if problem.kind not in spec.kinds:
        raise OptionError(f"method '{spec.name}' does not handle {problem.kind.upper()} problems "
                          f"(it handles: {', '.join(k.upper() for k in spec.kinds)})")
    check_dense_ok(problem, spec)
    opts = spec.parse_options(options)
    tol = spec.default_tol if tol is None else float(tol)
    if not (np.isfinite(tol) and tol > 0):
        raise OptionError(f"tolerance must be positive and finite, got {tol}")
    spec.prepare_once()
    start = time.perf_counter()
    outcome: Outcome = spec.run(problem, tol=tol, **opts)
    seconds = time.perf_counter() - start
    return certify_outcome(problem, outcome, spec.name, seconds, tol)


#: Above this ratio ``||M|| ||z|| / ||q||`` a certified answer carries a warning.
LARGE_SOLUTION = 1e10


def _growth(problem: Problem, z: np.ndarray) -> float:
    nq = float(np.max(np.abs(problem.q))) if problem.n else 0.0
    nz = float(np.max(np.abs(z))) if problem.n else 0.0
    if nz == 0.0:
        return 0.0
    return 0.0 if nq == 0.0 else matrix_norm_inf(problem.M) * nz / nq


def certify_outcome(problem: Problem, outcome: Outcome, method: str, seconds: float,
                    tol: float) -> Result:
    """Turn a method's raw :class:`Outcome` into a verdict by checking its answer."""
    z = np.asarray(outcome.z, dtype=np.float64)
    w = problem.w(z) if np.all(np.isfinite(z)) else np.full(problem.n, np.nan)
    cert = certify(problem, z, tol, w=w, norm_M=matrix_norm_inf(problem.M))
    message = outcome.message
    if cert.passed:
        status = SOLVED
        if outcome.termination != CONVERGED:
            message = f"{message}; the returned point passes the certificate anyway"
        growth = _growth(problem, z)
        if growth > LARGE_SOLUTION:
            message = (f"{message}; warning: ||M|| ||z|| / ||q|| = {growth:.1e}: the solution is "
                       f"huge compared with the data, so the problem is close to having none "
                       f"(the error is a backward error: z solves a nearby problem)")
    elif outcome.proven_infeasible:
        status = NO_SOLUTION
    else:
        status = UNSOLVED
        if outcome.termination == CONVERGED:
            message = (f"{message}, but the certificate failed: error {cert.error:.3g} > "
                       f"tol {tol:.3g}")
    return Result(status=status, method=method, z=z, w=w, iterations=outcome.iterations,
                  seconds=seconds, certificate=cert, message=message,
                  termination=outcome.termination, problem_name=problem.name,
                  trace=outcome.trace, info=dict(outcome.info))
