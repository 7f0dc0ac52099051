"""``lcpcli.solve``: one entry point for every method, with timing and certification."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from lcpcli.analysis.proof import confirm
from lcpcli.core import limits
from lcpcli.core.certificate import check, validate_tol
from lcpcli.core.errors import OptionError
from lcpcli.core.limits import DENSE_N_ENV, DENSE_N_FLOOR
from lcpcli.core.numeric import check_dtype, float64_array, real_array
from lcpcli.core.problem import Problem, is_sparse
from lcpcli.core.result import (
    CONVERGED,
    NO_SOLUTION,
    SOLVED,
    UNSOLVED,
    Outcome,
    Result,
)
from lcpcli.solvers import DEFAULT_METHOD
from lcpcli.solvers.pipeline import run_method
from lcpcli.solvers.registry import Cost, Method, get_method


def check_dense_ok(problem: Problem, spec: Method) -> None:
    """OptionError when ``spec`` would densify a huge sparse M (checked before any work)."""
    n = problem.n
    if spec.densifies(problem):
        raise OptionError(f"method '{spec.name}' works on a dense {n} x {n} matrix "
                          f"({n * n * 8 / 2**30:.1f} GiB) but M is sparse (nnz={problem.M.nnz}); "
                          f"choose a method for large sparse problems (see 'lcpcli methods'), "
                          f"or set {DENSE_N_ENV}={n} to densify it anyway")


def check_dense_work(n: int, spec: Method) -> None:
    """ProblemError when ``spec`` factorises or pivots on a dense n x n M above the dense-work
    budget of :mod:`lcpcli.core.limits` (``auto`` included: it factorises; sweeping methods,
    O(n^2) per sweep, are not checked).  One comparison up to ``DENSE_N_FLOOR``."""
    if n > DENSE_N_FLOOR and (spec.planner or spec.cost in (Cost.PIVOTING, Cost.FACTORING)):
        limits.check_dense_work(n, f"method '{spec.name}' factorises or pivots on the dense M",
                                instead="use a sweeping method (-m pgs, -m psor: O(n^2) per "
                                        "sweep)")


def check_sparse_work(n: int, spec: Method) -> None:
    """ProblemError when ``spec`` factorises a sparse n x n M (sparse LU: ``ip``, ``newton``,
    ... and ``auto``, whose plan may) above the sparse-factorisation budget of
    :mod:`lcpcli.core.limits`; sweeping methods (O(nnz) per sweep) are not checked."""
    if n > limits.SPARSE_N_FLOOR and (spec.planner or spec.cost is Cost.FACTORING):
        limits.check_sparse_factorisation(n, f"method '{spec.name}' factorises the sparse M",
                                          instead="use a sweeping method (-m pgs, -m psor: "
                                                  "O(nnz) per sweep)")


def dense_check(method: str | None) -> Any:
    """:func:`check_dense_work` for ``method`` as a one-argument hook for
    :func:`lcpcli.io.load` (``check_dense=``: refused from the file's header, before a dense M
    is read); None when the method is not limited or unknown (:func:`solve` says so)."""
    try:
        spec = get_method(DEFAULT_METHOD if method is None else method)
    except OptionError:
        return None
    if not (spec.planner or spec.cost in (Cost.PIVOTING, Cost.FACTORING)):
        return None
    return lambda n: check_dense_work(n, spec)


def solve(problem: Problem | Any, q: Any = None, method: str | None = None, *,
          tol: float | None = None, warm: Any = None, **options: Any) -> Result:
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

    ``warm``: a previous :class:`Result`, a basis (booleans, True: ``z_i`` basic) or a point
    ``z0``.  With ``auto``, BPP or a pivoting method, block principal pivoting first runs from
    that basis (:mod:`lcpcli.solvers.warm`; one factorisation when the basis is still right);
    if that does not end certified, ``method`` runs cold (with ``z0`` from ``warm`` when it
    takes one), so the verdict is never worse than cold.  Other methods get ``z0`` only.
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
    if problem.sparse:
        check_dense_ok(problem, spec)
        check_sparse_work(problem.n, spec)
    else:
        check_dense_work(problem.n, spec)
    opts = spec.parse_options(options)
    tol = validate_tol(spec.default_tol if tol is None else tol)
    spec.prepare_once()
    start = time.perf_counter()
    if warm is not None:
        from lcpcli.solvers.warm import check_warm, uses_warm_basis, warm_point, warm_start

        check_warm(problem, warm)
        note = ""
        if uses_warm_basis(spec, problem):
            tried, note = warm_start(problem, warm, tol, spec.name)
            if tried is not None:
                factors = tried.info.pop("blocks", None)
                res = certify_outcome(problem, tried, tried.info.pop("method", "bpp"),
                                      time.perf_counter() - start, tol, basis=True)
                if res.solved:  # never no_solution: the warm start proves nothing
                    res.factors = factors  # the next warm start on the same M reuses them
                    return res
                note = f"its answer failed the certificate (error {res.error:.2g})"
        if "z0" in spec.options and opts.get("z0") is None:  # the cold run starts from z0
            z0 = warm_point(problem, warm)
            if z0 is not None:
                opts = spec.parse_options({**options, "z0": z0})
        if note:
            outcome = run_method(spec, problem, tol, opts)
            outcome.message += f" (warm start from the given basis did not end certified: " \
                               f"{note}; solved cold)"
            return certify_outcome(problem, outcome, spec.name, time.perf_counter() - start,
                                   tol)
    outcome: Outcome = run_method(spec, problem, tol, opts)
    seconds = time.perf_counter() - start
    return certify_outcome(problem, outcome, spec.name, seconds, tol)


def certify_outcome(problem: Problem, outcome: Outcome, method: str, seconds: float,
                    tol: float, basis: bool = False) -> Result:
    """Turn a method's raw :class:`Outcome` into a verdict by checking its answer.

    ``basis``: record the final basis (:attr:`Result.basis`) in the same certificate pass
    (warm starts, whose next step needs it); otherwise it is computed on first use."""
    z = float64_array(outcome.z)
    states = None
    if outcome.checked is not None and outcome.checked[0].tol == tol:
        cert, w = outcome.checked  # the method certified this very z (auto does)
    elif basis:
        states = np.empty(problem.n, dtype=np.int8)
        cert, w = check(problem, z, tol, state=states)
    else:
        cert, w = check(problem, z, tol)
    message = outcome.message
    if cert.passed:
        status = SOLVED
        if outcome.termination != CONVERGED:
            message = f"{message}; the returned point passes the certificate anyway"
    elif outcome.proven_infeasible and (proof := confirm(problem, outcome)) is not None:
        status = NO_SOLUTION  # the Farkas vector passed its check (lcpcli.analysis.proof)
        outcome.info["farkas_y"] = proof.y.tolist()
        outcome.info["proof"] = proof.as_dict()
    else:
        if outcome.proven_infeasible:
            message = (f"{message}; claimed infeasible, but no Farkas vector passes the check, "
                       f"so nothing is proven")
        status = UNSOLVED
        if outcome.termination == CONVERGED:
            message = (f"{message}, but the certificate failed: error {cert.error:.3g} > "
                       f"tol {tol:.3g}{_why(cert)}")
    # positional, in the order of Result's fields (this is on the small-solve path)
    return Result(status, method, z, w, outcome.iterations, seconds, cert, message,
                  outcome.termination, problem.name, outcome.trace, dict(outcome.info), states,
                  None, None if states is not None else problem)  # else: on first use


def _why(cert: Any) -> str:
    """Which part of the certificate failed, in words (for ``message``)."""
    if cert.growth > 1.0 and cert.backward_error <= cert.tol < cert.error:
        return (f" (backward error {cert.backward_error:.2g}, but the rows coupled to pair "
                f"{cert.worst + 1} balance only by cancellation: growth {cert.growth:.2g})")
    if cert.worst >= 0:
        return f" (worst at pair {cert.worst + 1})"
    return ""


#: The stack API, moved to :mod:`lcpcli.stacks`; ``lcpcli.api.solve_many`` etc. still work.
_STACK_NAMES = frozenset({"AUTO_SAMPLE", "STACK_MIN", "StackPlan", "plan_stack", "solve_many",
                          "solve_each", "_batched_method"})


def __getattr__(name: str) -> Any:
    """The names of :mod:`lcpcli.stacks` (imported on first use: it imports this module)."""
    if name in _STACK_NAMES:
        from lcpcli import stacks

        return getattr(stacks, name)
    raise AttributeError(f"module 'lcpcli.api' has no attribute {name!r}")
