"""``auto``: try the likely method first, classify further only if its answer fails.

Problem: any kind (LCP, MLCP, box LCP), ``w = M z + q``.  The plan comes from the policy
tables of :mod:`lcpcli.solvers.policy` (regimes by size and storage, rows declared by the
methods: condition on the class report -> method, reason); no method is named here.

1. An LCP with ``q >= 0``: ``z = 0``.
2. The regime (size and storage) gives the order of the cost classes.  In an optimistic
   regime (small dense problems, sparse ones that are cheap to factor) the first attempt is
   planned on the O(n) and O(n^2) tests only (:class:`lcpcli.analysis.classify.Classifier`):
   the first row whose condition is not refuted is tried, e.g. Lemke on any dense n <= 1500
   LCP.  In the other regimes the tests a row needs run before it is chosen (a failed
   sweeping attempt would cost more than a Cholesky factorisation).
3. If an answer fails the certificate: the next rows are evaluated lazily, each running only
   the tests its condition names (symmetry, a Cholesky attempt, the H-matrix test, P-matrix
   tests only where a guarantee names P), and the methods are tried in the policy's order.

Every attempt runs through the dispatcher (:func:`lcpcli.solvers.pipeline.run_method`), which
certifies it, and the first that passes is returned: the certificate decides, never the
classification.  A method's *proof* that no solution exists ends the search with
``no_solution`` only when its Farkas vector passes the check of :mod:`lcpcli.analysis.proof`
(a ray without one is a failed attempt: the search goes on).  ``message`` names what is known
of M, the method that succeeded and every failed attempt; ``info["attempts"]`` has the details
(method, reason, status, error, iterations, seconds, certification included),
``info["classify_seconds"]`` the time spent classifying and planning.

Matrix classes: any; the guarantees are those of the methods it picks (see docs/methods.md).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from time import perf_counter
from typing import Any

import numpy as np

from lcpcli.analysis.classify import Classifier
from lcpcli.analysis.proof import confirm
from lcpcli.core.errors import OptionError
from lcpcli.core.result import (
    CONVERGED,
    ITERATION_LIMIT,
    NO_SOLUTION,
    SOLVED,
    UNSOLVED,
    Outcome,
    Status,
)
from lcpcli.solvers import policy
from lcpcli.solvers.memo import ATTEMPTS
from lcpcli.solvers.options import positive_int, vector_option
from lcpcli.solvers.pipeline import run_method
from lcpcli.solvers.policy import Step
from lcpcli.solvers.registry import Method, Option, get_method, methods, resolve
from lcpcli.solvers.registry import version as registry_version
from lcpcli.solvers.support import preload_linalg, start_point


def prepare() -> None:
    """Warm up the compiled kernels of every method auto may try (outside the timed region)."""
    for m in methods().values():
        if policy.plannable(m):
            m.prepare_once()


def _given_order(order: str, c: Classifier, registry: Mapping[str, Method]) -> list[Step]:
    """The steps of ``order=`` (a method that would densify a huge sparse M is left out, as in
    a plan)."""
    kind = c.report.kind
    steps = []
    for name in order.replace(",", " ").split():
        key = resolve(name)
        spec = registry.get(key) if key else None
        if spec is None or spec.planner or kind not in spec.kinds:
            raise OptionError(f"auto: method '{name}' in order= is unknown or does not "
                              f"handle {kind.upper()} problems")
        if not spec.densifies(c.problem):
            steps.append(Step(spec.name, "given by order=", False))
    return steps


def attempt_key(name: str, max_iter: int | None) -> tuple[Any, ...]:
    """The key of :data:`lcpcli.solvers.memo.ATTEMPTS`: an attempt's method and options
    (without a warm start) depend on the method's name, the ``max_iter`` given and the
    registry (its version)."""
    return (name, max_iter, registry_version())


def _attempt(name: str, max_iter: int | None, z0: np.ndarray | None
             ) -> tuple[Method, dict[str, Any]]:
    """The method called ``name`` and the options of an attempt that differ from their
    defaults (parsed and checked; :meth:`Method.given_options`: what the dispatcher passes to
    ``run``), the method prepared once."""
    key = None
    if z0 is None:
        key = attempt_key(name, max_iter)
        found = ATTEMPTS.get(key)
        if found is not None:
            return found
    spec = get_method(name)
    opts: dict[str, Any] = {}
    if "max_iter" in spec.options:
        cap = max_iter if max_iter is not None else spec.auto_max_iter
        if cap is not None:
            opts["max_iter"] = cap
    if z0 is not None and "z0" in spec.options:
        opts["z0"] = z0
    spec.prepare_once()
    found = spec, spec.given_options(spec.parse_options(opts))
    return found if key is None else ATTEMPTS.put(key, found)


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, order: str | None = None) -> Outcome:
    """Plan, try and certify methods until one's answer passes; see the module docstring.
    Each attempt goes through the dispatcher (:func:`lcpcli.solvers.pipeline.run_method`),
    which certifies it."""
    if z0 is not None:
        z0 = start_point(problem, z0)  # length check before any method runs
    t_start = perf_counter()
    c = Classifier(problem)
    n = c.report.n
    if c.report.kind == "lcp" and (n == 0 or c.minima()[1] >= 0):
        return Outcome(np.zeros(n), 0, CONVERGED, "auto: q >= 0, so z = 0 solves the problem",
                       info={"chosen": None, "attempts": []})
    queue: Iterator[Step]
    if order:
        regime = policy.regime_of(c)
        queue, replanned = iter(_given_order(order, c, methods())), True
    else:
        regime, first = policy.first_step(problem, c)
        queue, replanned = iter(() if first is None else (first,)), False
    attempts: list[dict[str, Any]] = []
    best: tuple[float, np.ndarray, Any] | None = None
    total_it = 0
    t_methods = 0.0
    imported = 0.0

    while True:
        step = next(queue, None)
        if step is None and not replanned:  # the first attempt failed: plan the rest
            # the tests and methods that follow may factorise: their modules load here, timed
            # apart (Outcome.import_seconds, left out of Result.seconds)
            t_import = perf_counter()
            preload_linalg(problem)
            imported += perf_counter() - t_import
            queue = policy.iter_plan(problem, c, skip=[a["method"] for a in attempts],
                                     regime=regime)
            replanned = True
            step = next(queue, None)
        if step is None:
            break
        name, why, _ = step
        spec, opts = _attempt(name, max_iter, z0)
        t1 = perf_counter()
        try:
            out: Outcome = run_method(spec, problem, tol, opts)  # certified there
        except (np.linalg.LinAlgError, MemoryError, ValueError, RuntimeError) as exc:
            if isinstance(exc, OptionError):
                raise
            t2 = perf_counter()
            t_methods += t2 - t1
            attempts.append({"method": name, "reason": why, "status": Status.ERROR,
                             "message": f"{type(exc).__name__}: {exc}", "seconds": t2 - t1})
            continue
        t2 = perf_counter()
        t_methods += t2 - t1
        iterations = int(out.iterations)
        total_it += iterations
        z = out.z
        cert, w = out.checked  # type: ignore[misc]
        proof = None if cert.passed else confirm(problem, out)
        status = SOLVED if cert.passed else NO_SOLUTION if proof is not None else UNSOLVED
        attempts.append({"method": name, "reason": why, "status": status,
                         "termination": out.termination, "iterations": iterations,
                         "error": cert.error, "seconds": t2 - t1, "message": out.message})
        if status is SOLVED:
            failed = "".join(f"; {a['method']} failed first ({a['message']})"
                             for a in attempts[:-1]) if len(attempts) > 1 else ""
            return Outcome.converged(z, total_it,
                                     f"auto ({c.report.describe()}): solved by {name} ({why})"
                                     f"{failed}",
                                     _info(name, attempts, c, regime, t_start,
                                           t_methods + imported),
                                     (cert, w), imported)
        if status is NO_SOLUTION:
            return Outcome(z, total_it, out.termination,
                           f"auto ({c.report.describe()}): {name} proved that no solution "
                           f"exists: {out.message}", proven_infeasible=True,
                           info={**_info(name, attempts, c, regime, t_start,
                                         t_methods + imported),
                                 "farkas_y": proof.y.tolist()}, import_seconds=imported)
        if best is None or cert.error < best[0]:
            best = (cert.error, z, out.termination)
    tried = "; ".join(f"{a['method']}: {a['message']}" for a in attempts) or "no method applies"
    z = best[1] if best else np.clip(np.zeros(n), problem.bounds()[0], None)
    return Outcome(z, total_it, best[2] if best else ITERATION_LIMIT,
                   f"auto ({c.report.describe()}): every suitable method failed ({tried})",
                   info=_info(None, attempts, c, regime, t_start, t_methods + imported),
                   import_seconds=imported)


def _info(chosen: str | None, attempts: list[dict[str, Any]], c: Classifier, regime: Any,
          t_start: float, t_methods: float) -> dict[str, Any]:
    """``Outcome.info`` of auto (see the module docstring)."""
    spent = perf_counter() - t_start
    return {"chosen": chosen, "attempts": attempts, "classification": c.report,
            "regime": regime.name, "classify_seconds": spent - t_methods}


METHODS = [
    Method(
        name="auto",
        run=run,
        summary="try the likely method first, classify M further only if its certified "
                "answer fails, fall back in the policy's order (the default)",
        notes="any M: the guarantees of the method it picks (see 'lcpcli info FILE')",
        kinds=("lcp", "mlcp", "box"),
        sparse=True,
        planner=True,
        options={
            "max_iter": Option(positive_int, None,
                               "iteration / pivot limit passed to each method tried"),
            "z0": Option(vector_option, None, "warm start passed to the methods that take one"),
            "order": Option(str, None, "comma-separated methods to try instead of the plan"),
        },
        prepare=prepare,
    ),
]
