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
``info["classify_seconds"]`` the time spent classifying and planning.  When the first attempt
solves (the usual case), ``info`` is built on first read (:class:`lcpcli.core.result.LazyInfo`:
the same dict, from values fixed at the solve): on a 4 us solve at n = 10 its records cost a
tenth of the call.  On a dense M the memoised first attempt (:data:`lcpcli.solvers.memo.FIRSTS`)
is found from the q >= 0 and diagonal tests' one compiled pass; a
:class:`~lcpcli.analysis.classify.Classifier` is built only when the plan or a message needs it.

Matrix classes: any; the guarantees are those of the methods it picks (see docs/methods.md).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from time import perf_counter
from typing import Any

import numpy as np

from lcpcli.analysis._scaling import dense_minima
from lcpcli.analysis.classify import (
    POSITIVE_DIAGONAL_FACTS,
    Classifier,
    diagonal_facts,
    positive_diagonal_report,
)
from lcpcli.analysis.proof import confirm, preload_proof_search, search_proof
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import LCP
from lcpcli.core.result import (
    CONVERGED,
    ITERATION_LIMIT,
    NO_SOLUTION,
    SOLVED,
    UNSOLVED,
    LazyInfo,
    Outcome,
    Status,
)
from lcpcli.solvers import policy
from lcpcli.solvers.memo import ATTEMPTS, FIRSTS
from lcpcli.solvers.options import positive_int, vector_option
from lcpcli.solvers.pipeline import run_method
from lcpcli.solvers.policy import Step
from lcpcli.solvers.registry import Method, Option, get_method, methods, resolve
from lcpcli.solvers.registry import version as registry_version
from lcpcli.solvers.support import preload_linalg, start_point, timed_imports


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


def first_key(c: Classifier, max_iter: int | None) -> tuple[Any, ...] | None:
    """The key of :data:`lcpcli.solvers.memo.FIRSTS` (None: a sparse problem, never
    memoised): auto's first attempt and its message head depend on the opening's facts
    (:func:`lcpcli.solvers.policy.opening_key`: kind, n, registry, the diagonal test's facts),
    the ``max_iter`` given (the attempt's options) and, for the class report's phrase
    (:meth:`ClassReport.describe`), the number of zero diagonal entries: every field that
    phrase reads and the diagonal test sets."""
    if policy.opening_key(c) is None:  # sparse (for a dense M: runs the diagonal test)
        return None
    r = c.report
    return first_key_of(r.kind, r.n, diagonal_facts(r), r.zero_diagonal, max_iter)


def first_key_of(kind: str, n: int, facts: tuple[Any, ...], zero_diagonal: int,
                 max_iter: int | None) -> tuple[Any, ...]:
    """:func:`first_key` from its facts, as one flat tuple: those of the opening's key
    (:func:`lcpcli.solvers.policy.opening_key`: ``kind``, ``n``, the registry's version, the
    diagonal test's ``facts``), the number of zero diagonal entries and ``max_iter``.
    :func:`run` builds it so for a dense M with a positive diagonal, whose facts it knows from
    the minima alone (:data:`lcpcli.analysis.classify.POSITIVE_DIAGONAL_FACTS`, no zero
    entries), without a classifier."""
    return (kind, n, registry_version(), facts, zero_diagonal, max_iter)


def _first(problem: Any, c: Classifier, max_iter: int | None, z0: np.ndarray | None,
           given: list[Step] | None) -> tuple[Any, Step | None, Method | None, dict[str, Any],
                                              str]:
    """``(regime, step, method, options, head)``: auto's first attempt (the first of the
    ``order=`` steps ``given``, or :func:`lcpcli.solvers.policy.first_step`), its method and
    options (:func:`_attempt`; None and ``{}`` when no method applies) and the head of its
    message when it succeeds, ``"auto (<class report>): solved by <method> (<reason>)"``.

    Memoised (:func:`first_key`) without ``z0`` or ``order`` for a dense problem whose
    opening needed only the O(n) diagonal test (as :func:`lcpcli.solvers.policy.opening`),
    so that a repeated small solve makes one look-up."""
    key = first_key(c, max_iter) if z0 is None and given is None else None
    if key is not None:
        found = FIRSTS.get(key)
        if found is not None:
            return found
    before = c.tests_run
    if given is not None:
        regime, step = policy.regime_of(c), (given[0] if given else None)
    else:
        regime, step = policy.first_step(problem, c)
    if step is None:
        return regime, None, None, {}, ""
    spec, opts = _attempt(step.method, max_iter, z0)
    found = (regime, step, spec, opts, _solved_by(c.report, step.method, step.reason))
    if key is not None and c.tests_run == before:  # planned on the diagonal test alone
        FIRSTS.put(key, found)
    return found


def _solved_by(report: Any, name: str, why: str) -> str:
    """The head of auto's message when ``name`` solved the problem (``report``: what is known
    of M, :meth:`ClassReport.describe`)."""
    return f"auto ({report.describe()}): solved by {name} ({why})"


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, order: str | None = None) -> Outcome:
    """Plan, try and certify methods until one's answer passes; see the module docstring.
    Each attempt goes through the dispatcher (:func:`lcpcli.solvers.pipeline.run_method`),
    which certifies it."""
    if z0 is not None:
        z0 = start_point(problem, z0)  # length check before any method runs
    t_start = perf_counter()
    M = problem.M
    if type(M) is np.ndarray and z0 is None and not order:
        # a dense M: the q >= 0 and diagonal tests in one compiled pass; with a positive
        # diagonal (and q >= 0 refuted for an LCP) the first attempt's key follows from the
        # minima (it is first_key(Classifier(problem, minima), max_iter)), no report needed
        minima = dense_minima(M, problem.q)
        if minima[0] > 0:
            kind = LCP if problem.lower is None and not problem.n_eq else problem.kind
            if kind != LCP or minima[1] < 0:
                found = FIRSTS.get(first_key_of(kind, len(M), POSITIVE_DIAGONAL_FACTS, 0,
                                                max_iter))
                if found is not None:
                    return _first_from_memo(problem, tol, max_iter, found, minima, kind,
                                            t_start)
        return _search(problem, tol, max_iter, None, None, t_start, minima)
    return _search(problem, tol, max_iter, z0, order, t_start, None)


def _first_from_memo(problem: Any, tol: float, max_iter: int | None, found: tuple[Any, ...],
                     minima: tuple[float, float], kind: str, t_start: float) -> Outcome:
    """:func:`run` on a dense M with a positive diagonal (``kind``: the problem's) whose first
    attempt ``found`` came from :data:`~lcpcli.solvers.memo.FIRSTS`: that attempt through the
    dispatcher and, when it solves (the usual case), its Outcome handed on with the head of
    auto's message and ``info`` built on first read; otherwise the search goes on from it
    (:func:`_search`)."""
    t1 = perf_counter()
    try:  # _try's body, in line: this is the small solves' path
        out = run_method(found[2], problem, tol, found[3])  # certified there
    except (np.linalg.LinAlgError, MemoryError, ValueError, RuntimeError) as exc:
        if isinstance(exc, OptionError):
            raise
        return _search(problem, tol, max_iter, None, None, t_start, minima, found,
                       (exc, t1, perf_counter()))
    t2 = perf_counter()
    cert = out.checked[0]  # type: ignore[index]
    if cert.passed:
        return _solved_first(out, cert.error, found[1], found[0].name, found[4], t_start, t1,
                             t2, (kind, len(problem.q), problem.n_eq, minima[0]))
    return _search(problem, tol, max_iter, None, None, t_start, minima, found, (out, t1, t2))


def _solved_first(out: Outcome, error: float, step: Step, regime: str, head: str,
                  t_start: float, t1: float, t2: float, report: Any) -> Outcome:
    """auto's Outcome when its first attempt (``step``, run from ``t1`` to ``t2``) solved and
    no test ran since its plan: the dispatcher's ``out`` (certified error ``error``) becomes
    auto's (Outcome.converged's fields, one record fewer), its message the head ``head``, its
    info built on first read (:class:`LazyInfo`, :func:`_first_info`) from values fixed here."""
    iterations = int(out.iterations)
    out.info = LazyInfo(_first_info, step, out.termination, iterations, out.message, error,
                        t2 - t1, regime, t1 - t_start, report)
    out.iterations, out.termination, out.message = iterations, CONVERGED, head
    out.proven_infeasible, out.trace = False, None  # import_seconds: the attempt's, auto's
    return out


def _try(spec: Method, problem: Any, tol: float, opts: dict[str, Any]
         ) -> Outcome | BaseException:
    """One attempt through the dispatcher, which certifies it: its Outcome, or the numerical
    error it raised (a failed attempt; an :class:`OptionError` is the caller's and raised)."""
    try:
        return run_method(spec, problem, tol, opts)
    except (np.linalg.LinAlgError, MemoryError, ValueError, RuntimeError) as exc:
        if isinstance(exc, OptionError):
            raise
        return exc


def _search(problem: Any, tol: float, max_iter: int | None, z0: np.ndarray | None,
            order: str | None, t_start: float, minima: tuple[float, float] | None,
            found: tuple[Any, ...] | None = None,
            tried: tuple[Any, float, float] | None = None) -> Outcome:
    """:func:`run` from its first attempt on: ``minima`` (a dense LCP's, or None), the first
    attempt ``found`` from the memo and its result ``tried`` (``(Outcome or the exception it
    raised, start, end)``) when :func:`_first_from_memo` ran it already."""
    M, n, kind = problem.M, problem.n, problem.kind
    c: Classifier | None = None  # built once the plan or a message needs more than the minima
    if minima is None:
        if type(M) is np.ndarray:  # the q >= 0 and diagonal tests: one compiled pass
            minima = dense_minima(M, problem.q)
        else:
            c = Classifier(problem)
            minima = c.minima() if kind == "lcp" else None
    if kind == "lcp" and (n == 0 or minima[1] >= 0):  # type: ignore[index]
        return Outcome(np.zeros(n), 0, CONVERGED, "auto: q >= 0, so z = 0 solves the problem",
                       info={"chosen": None, "attempts": []})
    given = None
    if found is None:
        if c is None:  # the diagonal test's facts from the minima, as the plan would find them
            # (an MLCP or a box LCP with order=: only the plan decides whether it runs)
            c = Classifier(problem, minima if kind == "lcp" or not order else None)
        given = _given_order(order, c, methods()) if order else None
        found = _first(problem, c, max_iter, z0, given)
    regime, step, spec, opts, head = found
    # the steps after the first: order='s, or (None) planned once the first attempt failed
    queue: Iterator[Step] | None = None if given is None else iter(given[1:])
    attempts: list[dict[str, Any]] = []
    hints: list[Any] = []  # the failed attempts' ray directions (proof candidates)
    best: tuple[float, np.ndarray, Any] | None = None
    total_it = 0
    t_methods = 0.0
    imported = 0.0

    while True:
        if spec is None:  # the next step (the first is planned above)
            if c is None:  # the first attempt (from the memo) failed: classify from here on
                c = Classifier(problem, minima)
            if queue is None:  # the first attempt failed: plan the rest
                # the tests and methods that follow may factorise: their modules load here,
                # timed apart (Outcome.import_seconds, left out of Result.seconds)
                imported += timed_imports(problem, preload_linalg)
                queue = policy.iter_plan(problem, c, skip=[a["method"] for a in attempts],
                                         regime=regime)
            step = next(queue, None)
            if step is None:
                break
            spec, opts = _attempt(step.method, max_iter, z0)
            head = ""
        name, why = step.method, step.reason
        if tried is not None:  # run by _first_from_memo already
            got, t1, t2 = tried
            tried = None
        else:
            t1 = perf_counter()
            got = _try(spec, problem, tol, opts)
            t2 = perf_counter()
        spec = None
        if type(got) is not Outcome:  # the attempt raised
            t_methods += t2 - t1
            attempts.append({"method": name, "reason": why, "status": Status.ERROR,
                             "message": f"{type(got).__name__}: {got}", "seconds": t2 - t1})
            continue
        out = got
        iterations = int(out.iterations)
        cert, w = out.checked  # type: ignore[misc]
        if cert.passed and head and not attempts:
            return _solved_first(out, cert.error, step, regime.name, head, t_start, t1, t2,
                                 c.report)  # type: ignore[union-attr]
        # the modules the attempt loaded as it went (Outcome.import_seconds) are not its time
        imported += out.import_seconds
        t_methods += t2 - t1 - out.import_seconds
        total_it += iterations
        z = out.z
        proof = None if cert.passed else confirm(problem, out)
        status = SOLVED if cert.passed else NO_SOLUTION if proof is not None else UNSOLVED
        attempts.append(_record(name, why, status, out.termination, iterations, cert.error,
                                t2 - t1 - out.import_seconds, out.message))
        if c is None:
            c = Classifier(problem, minima)
        report = c.report
        if status is SOLVED:
            message = _solved_by(report, name, why) + "".join(
                f"; {a['method']} failed first ({a['message']})" for a in attempts[:-1])
            return Outcome.converged(z, total_it, message,
                                     _info(name, attempts, report, regime.name,
                                           t2 - t_start - t_methods - imported),
                                     (cert, w), imported)
        if status is NO_SOLUTION:
            return Outcome(z, total_it, out.termination,
                           f"auto ({report.describe()}): {name} proved that no solution "
                           f"exists: {out.message}", proven_infeasible=True,
                           info={**_info(name, attempts, report, regime.name,
                                         perf_counter() - t_start - t_methods - imported),
                                 "farkas_y": proof.y.tolist()}, import_seconds=imported)
        if best is None or cert.error < best[0]:
            best = (cert.error, z, out.termination)
        if out.info.get("ray") is not None:  # a direction that may still be a Farkas vector
            hints.append(out.info["ray"])
    report = c.report
    tried = "; ".join(f"{a['method']}: {a['message']}" for a in attempts) or "no method applies"
    z = best[1] if best else np.clip(np.zeros(n), problem.bounds()[0], None)
    # no answer and no proof from any method: a proof may still exist where no method's
    # class argument offered one (a ray on a matrix not known to be copositive-plus, a
    # singular equality block): the linear program of the proof search, on the data as given
    imported += timed_imports(problem, preload_proof_search)
    proof = search_proof(problem, hints)
    if proof is not None:
        return Outcome(z, total_it, best[2] if best else ITERATION_LIMIT,
                       f"auto ({report.describe()}): no method solved it ({tried}); "
                       f"{proof.describe()}", proven_infeasible=True,
                       info={**_info(None, attempts, report, regime.name,
                                     perf_counter() - t_start - t_methods - imported),
                             "farkas_y": proof.y.tolist()}, import_seconds=imported)
    return Outcome(z, total_it, best[2] if best else ITERATION_LIMIT,
                   f"auto ({report.describe()}): every suitable method failed ({tried})",
                   info=_info(None, attempts, report, regime.name,
                              perf_counter() - t_start - t_methods - imported),
                   import_seconds=imported)


def _record(name: str, why: str, status: Status, termination: Any, iterations: int,
            error: float, seconds: float, message: str) -> dict[str, Any]:
    """One entry of ``info["attempts"]`` for an attempt that returned (see the module
    docstring; one that raised has ``method``, ``reason``, ``status``, ``message``,
    ``seconds``)."""
    return {"method": name, "reason": why, "status": status, "termination": termination,
            "iterations": iterations, "error": error, "seconds": seconds, "message": message}


def _info(chosen: str | None, attempts: list[dict[str, Any]], report: Any, regime: str,
          classify_seconds: float) -> dict[str, Any]:
    """``Outcome.info`` of auto (see the module docstring); ``regime``: its name;
    ``classify_seconds``: the time spent outside the attempts (classifying and planning)."""
    return {"chosen": chosen, "attempts": attempts, "classification": report,
            "regime": regime, "classify_seconds": classify_seconds}


def _first_info(step: Step, termination: Any, iterations: int, message: str, error: float,
                seconds: float, regime: str, classify_seconds: float,
                report: Any) -> dict[str, Any]:
    """:func:`_info` when the first attempt (``step``) solved, its :func:`_record` the only
    attempt (``termination``, ``iterations``, ``message``: its dispatcher's, ``error``: its
    certified error, ``seconds``: its time).  ``report``: the class report, or
    ``(kind, n, n_eq, dmin)`` of a dense M whose O(n) diagonal test alone ran and found every
    diagonal entry positive, the smallest ``dmin`` (the report
    :func:`lcpcli.analysis.classify.positive_diagonal_report` builds from them)."""
    if type(report) is tuple:
        report = positive_diagonal_report(*report)
    return _info(step.method, [_record(step.method, step.reason, SOLVED, termination,
                                       iterations, error, seconds, message)],
                 report, regime, classify_seconds)


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
