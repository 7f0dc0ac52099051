"""``lcpcli.solve``: one entry point for every method, with timing and certification."""

from __future__ import annotations

from time import perf_counter
from typing import Any

import numpy as np

from lcpcli.analysis.proof import confirm
from lcpcli.core.numeric import check_dtype, real_array
from lcpcli.core.problem import Problem, is_sparse
from lcpcli.core.result import (
    CONVERGED,
    NO_SOLUTION,
    SOLVED,
    UNSOLVED,
    Outcome,
    Result,
)
from lcpcli.solvers.pipeline import certified, run_method
from lcpcli.solvers.request import (  # noqa: F401  (re-exported)
    DEFAULT_METHOD,
    Request,
    check_dense_ok,
    check_dense_work,
    check_sparse_work,
    dense_check,
    resolve,
)
from lcpcli.solvers.support import preload_linalg


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
    ``seconds`` times the method as the dispatcher runs it (its equilibration, final polish and
    the certificate of its answer, see :mod:`lcpcli.solvers.pipeline`), not request
    validation, kernel loading (imports), file reading or the Result record.

    ``warm``: a previous :class:`Result`, a basis (booleans, True: ``z_i`` basic) or a point
    ``z0``.  A method that declares a ``basis`` option (``murty``, ``dantzig``) starts from that
    basis itself on an LCP; with ``auto``, BPP or another pivoting method, block principal
    pivoting (or warm Lemke) first runs from it (:mod:`lcpcli.solvers.warm`; one factorisation
    when the basis is still right).  If that does not end ``solved``, ``method`` runs cold
    (with ``z0`` from ``warm`` when it takes one and did not take the basis), so the verdict is
    never worse than cold.  Other methods get ``z0`` only.
    """
    if not isinstance(problem, Problem):  # solve(M, q, method=...): arrays, not a Problem
        if q is None or isinstance(q, str):
            raise TypeError("lcpcli.solve(M, q, method=...) needs q after M (or pass a Problem)")
        data = {k: options.pop(k) for k in ("n_eq", "lower", "upper") if k in options} \
            if options else {}
        if type(problem) is not np.ndarray and is_sparse(problem):
            check_dtype(problem.dtype, "M")
        else:
            problem = real_array(problem, "M")
        problem = Problem.create(problem, real_array(q, "q"), **data)
    elif q is not None:  # solve(problem, "lemke"): the method given second
        if method is not None or not isinstance(q, str):
            raise TypeError("lcpcli.solve(problem, method, tol=...) takes a method name second")
        method = q
    request = resolve(problem, method, tol, options)
    if warm is not None:
        return _solve_warm(request, warm, options)
    start = perf_counter()
    outcome: Outcome = run_method(request.spec, problem, request.tol, request.given)
    seconds = perf_counter() - start
    return certify_outcome(problem, outcome, request.spec.name, seconds, request.tol)


def _solve_warm(request: Request, warm: Any, options: dict[str, Any]) -> Result:
    """:func:`solve` with ``warm`` (see its docstring).  Everything but the runs (the warm
    start's checks, its basis or point as options, their imports) is done before the clock
    starts."""
    from lcpcli.solvers.warm import (
        check_warm,
        takes_basis,
        uses_warm_basis,
        warm_basis,
        warm_point,
        warm_start,
    )

    problem, spec, tol, opts = request.problem, request.spec, request.tol, request.given
    check_warm(problem, warm)
    # a result that is not finite (a diverged run) holds no basis and no point: cold, as
    # solve_many's rows with NaN (a loop may hand on every previous result)
    diverged = isinstance(warm, Result) and not np.all(np.isfinite(warm.z))
    own = not diverged and takes_basis(spec, problem, opts)
    start_opts = None
    if own:  # the method's own pivots from the basis (Murty, Dantzig); basis= wins
        start_opts = opts if opts.get("basis") is not None else \
            spec.parse_options({**options, "basis": warm_basis(problem, warm)})
        if spec.preload is not None:
            spec.preload(problem, start_opts)
    elif not diverged and "z0" in spec.options and opts.get("z0") is None:  # from z0
        z0 = warm_point(problem, warm)
        if z0 is not None:
            opts = spec.parse_options({**options, "z0": z0})
    bpp_first = not diverged and not own and uses_warm_basis(spec, problem, opts)
    if bpp_first:
        preload_linalg(problem)  # BPP factorises the basic block
    start = perf_counter()
    note = ""
    if own:
        tried = run_method(spec, problem, tol, start_opts)
        res = certify_outcome(problem, tried, spec.name, perf_counter() - start, tol,
                              basis=True)
        if res.solved:  # only solved is kept: the cold run gives any proof
            return res
        note = (f"its answer failed the certificate (error {res.error:.2g})"
                if tried.termination == CONVERGED else f"it ended {tried.termination}")
    elif bpp_first:
        tried, note = warm_start(problem, warm, tol, spec.name)
        if tried is not None:
            factors = tried.info.pop("blocks", None)
            res = certify_outcome(problem, tried, tried.info.pop("method", "bpp"),
                                  perf_counter() - start, tol, basis=True)
            if res.solved:  # never no_solution: the warm start proves nothing
                res.factors = factors  # the next warm start on the same M reuses them
                return res
            note = f"its answer failed the certificate (error {res.error:.2g})"
    outcome = run_method(spec, problem, tol, opts)
    if diverged:
        outcome.message += " (the warm start's z is not finite: solved cold)"
    elif note:
        outcome.message += (f" (warm start from the given basis did not end certified: "
                            f"{note}; solved cold)")
    return certify_outcome(problem, outcome, spec.name, perf_counter() - start, tol)


def certify_outcome(problem: Problem, outcome: Outcome, method: str, seconds: float,
                    tol: float, basis: bool = False) -> Result:
    """Turn a method's raw :class:`Outcome` into a verdict by checking its answer.

    ``basis``: record the final basis (:attr:`Result.basis`) in the same certificate pass
    (warm starts, whose next step needs it); otherwise it is computed on first use."""
    if outcome.import_seconds:  # imports are never timed (Outcome.import_seconds)
        seconds = max(0.0, seconds - outcome.import_seconds)
        outcome.details()["import_seconds"] = outcome.import_seconds
    states = np.empty(problem.n, dtype=np.int8) if basis else None
    cert, w = certified(problem, outcome, tol, states)  # reused when the dispatcher made it
    z = outcome.z
    message = outcome.message
    if cert.passed:
        status = SOLVED
        if outcome.termination != CONVERGED:
            message = f"{message}; the returned point passes the certificate anyway"
    elif outcome.proven_infeasible and (proof := confirm(problem, outcome)) is not None:
        status = NO_SOLUTION  # the Farkas vector passed its check (lcpcli.analysis.proof)
        info = outcome.details()
        info["farkas_y"] = proof.y.tolist()
        info["proof"] = proof.as_dict()
    else:
        if outcome.proven_infeasible:
            message = (f"{message}; claimed infeasible, but no Farkas vector passes the check, "
                       f"so nothing is proven")
        status = UNSOLVED
        if outcome.termination == CONVERGED:
            message = (f"{message}, but the certificate failed: error {cert.error:.3g} > "
                       f"tol {tol:.3g}{_why(cert)}")
    return Result.certified(status, method, z, w, outcome, seconds, cert, message, problem,
                            states)


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
