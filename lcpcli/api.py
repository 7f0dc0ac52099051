"""``lcpcli.solve``: one entry point for every method, with timing and certification."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from lcpcli.core.certificate import check, validate_tol
from lcpcli.core.errors import OptionError
from lcpcli.core.numeric import check_dtype, real_array
from lcpcli.core.problem import Problem, is_sparse
from lcpcli.core.result import CONVERGED, NO_SOLUTION, SOLVED, UNSOLVED, Outcome, Result
from lcpcli.solvers.pipeline import run_method
from lcpcli.solvers.registry import Method, get_method

DEFAULT_METHOD = "auto"


def check_dense_ok(problem: Problem, spec: Method) -> None:
    """OptionError when ``spec`` would densify a huge sparse M (checked before any work)."""
    n = problem.n
    if spec.densifies(problem):
        raise OptionError(f"method '{spec.name}' works on a dense {n} x {n} matrix "
                          f"({n * n * 8 / 2**30:.1f} GiB) but M is sparse (nnz={problem.M.nnz}); "
                          f"choose a method for large sparse problems (see 'lcpcli methods')")


def solve(problem: Problem | Any, q: Any = None, method: str | None = None, *,
          tol: float | None = None, **options: Any) -> Result:
    """Solve ``problem`` with ``method`` and certify the answer.

    Two ways to call it: ``solve(problem, "lemke", tol=...)`` with a :class:`Problem`, or
    ``solve(M, q, method="lemke")`` with ``M`` a dense array or a scipy.sparse matrix and ``q``
    a vector (``n_eq=``, ``lower=``, ``upper=`` then make an MLCP or a box LCP).  Arrays follow
    the data rule of :mod:`lcpcli.core.numeric`: real numbers only (booleans, complex numbers
    and text raise :class:`ProblemError`).

    ``tol`` bounds the certificate's scaled ``error`` (default: the method's own, 1e-8 for
    pivoting methods).  Method-specific ``options`` (e.g. ``covering=``, ``max_iter=``) are
    checked against the method's declared options; unknown ones raise :class:`OptionError`.

    The verdict is ``solved`` only if the recomputed certificate passes; ``no_solution`` only
    when the method proved it (the proof is in ``message``); ``unsolved`` otherwise.
    ``seconds`` times the method (with its equilibration and final polish, see
    :mod:`lcpcli.solvers.pipeline`), not file reading or certification.
    """
    if not isinstance(problem, Problem):  # solve(M, q, method=...): arrays, not a Problem
        if q is None or isinstance(q, str):
            raise TypeError("lcpcli.solve(M, q, method=...) needs q after M (or pass a Problem)")
        data = {k: options.pop(k) for k in ("n_eq", "lower", "upper") if k in options}
        if is_sparse(problem):
            check_dtype(problem.dtype, "M")
        else:
            problem = real_array(problem, "M")
        problem = Problem.create(problem, real_array(q, "q"), **data)
    elif q is not None:  # solve(problem, "lemke"): the method given second
        if method is not None or not isinstance(q, str):
            raise TypeError("lcpcli.solve(problem, method, tol=...) takes a method name second")
        method = q
    method = DEFAULT_METHOD if method is None else method
    spec = get_method(method)
    if problem.kind not in spec.kinds:
        raise OptionError(f"method '{spec.name}' does not handle {problem.kind.upper()} problems "
                          f"(it handles: {', '.join(k.upper() for k in spec.kinds)})")
    check_dense_ok(problem, spec)
    opts = spec.parse_options(options)
    tol = validate_tol(spec.default_tol if tol is None else tol)
    spec.prepare_once()
    start = time.perf_counter()
    outcome: Outcome = run_method(spec, problem, tol, opts)
    seconds = time.perf_counter() - start
    return certify_outcome(problem, outcome, spec.name, seconds, tol)


def certify_outcome(problem: Problem, outcome: Outcome, method: str, seconds: float,
                    tol: float) -> Result:
    """Turn a method's raw :class:`Outcome` into a verdict by checking its answer."""
    z = np.asarray(outcome.z, dtype=np.float64)
    if outcome.checked is not None and outcome.checked[0].tol == tol:
        cert, w = outcome.checked  # the method certified this very z (auto does)
    else:
        cert, w = check(problem, z, tol)
    message = outcome.message
    if cert.passed:
        status = SOLVED
        if outcome.termination != CONVERGED:
            message = f"{message}; the returned point passes the certificate anyway"
    elif outcome.proven_infeasible:
        status = NO_SOLUTION
    else:
        status = UNSOLVED
        if outcome.termination == CONVERGED:
            message = (f"{message}, but the certificate failed: error {cert.error:.3g} > "
                       f"tol {tol:.3g}{_why(cert)}")
    return Result(status=status, method=method, z=z, w=w, iterations=outcome.iterations,
                  seconds=seconds, certificate=cert, message=message,
                  termination=outcome.termination, problem_name=problem.name,
                  trace=outcome.trace, info=dict(outcome.info))


def _why(cert: Any) -> str:
    """Which part of the certificate failed, in words (for ``message``)."""
    if cert.growth > 1.0 and cert.backward_error <= cert.tol < cert.error:
        return (f" (backward error {cert.backward_error:.2g}, but the rows coupled to pair "
                f"{cert.worst + 1} balance only by cancellation: growth {cert.growth:.2g})")
    if cert.worst >= 0:
        return f" (worst at pair {cert.worst + 1})"
    return ""
