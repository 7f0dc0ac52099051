"""A solve request: ``(problem, method, tol, options)`` resolved and validated once.

:func:`resolve` is the one place where a method name becomes a registered :class:`Method`
(``None``: :data:`DEFAULT_METHOD`), the problem kind and size are checked against it, its
options are parsed, the default tolerance is filled in and validated (:func:`resolve_tol`) and
its compiled kernels are loaded.  :func:`lcpcli.solve`, the contact solver, batch runs and
benchmarks all go through it; the resulting :class:`Request` is what the dispatcher
(:func:`lcpcli.solvers.pipeline.run_method`) runs.

Checks, each defined here once: :func:`check_kind` (the method handles the problem kind),
:func:`check_dense_ok` (a method that densifies is refused on a huge sparse M) and
:func:`check_dense_work` (the dense-work budget of :mod:`lcpcli.core.limits`) and
:func:`check_sparse_work` (the sparse-factorisation budget).  All raise
:class:`OptionError` / :class:`ProblemError` before any work.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.core import limits
from lcpcli.core.certificate import validate_tol
from lcpcli.core.errors import OptionError
from lcpcli.core.limits import DENSE_N_ENV, DENSE_N_FLOOR
from lcpcli.solvers import DEFAULT_METHOD
from lcpcli.solvers.memo import REQUESTS
from lcpcli.solvers.registry import Cost, Method, get_method

_NO_OPTIONS: Mapping[str, Any] = {}


@dataclass(slots=True)
class Request:
    """A validated request: the ``problem``, the registered method ``spec``, the tolerance
    ``tol`` of the certificate, the parsed ``options`` (defaults filled in) and ``given``:
    those that differ from their defaults (what the dispatcher passes to ``Method.run``, whose
    keyword defaults are the options' defaults: ``tests/solvers/test_memo.py`` checks it)."""

    problem: Any
    spec: Method
    tol: float
    options: dict[str, Any]
    given: dict[str, Any]


def method_of(method: str | None) -> Method:
    """The registered method called ``method`` (None: :data:`DEFAULT_METHOD`); OptionError
    if unknown."""
    return get_method(DEFAULT_METHOD if method is None else method)


def resolve_tol(spec: Method, tol: Any) -> float:
    """The certificate's tolerance: ``tol`` validated, or ``spec``'s default when None."""
    return validate_tol(spec.default_tol if tol is None else tol)


def check_kind(spec: Method, kind: str) -> None:
    """OptionError when ``spec`` does not handle problems of ``kind``."""
    if kind not in spec.kinds:
        raise OptionError(f"method '{spec.name}' does not handle {kind.upper()} problems "
                          f"(it handles: {', '.join(k.upper() for k in spec.kinds)})")


def check_dense_ok(problem: Any, spec: Method) -> None:
    """OptionError when ``spec`` would densify a huge sparse M (:meth:`Method.densifies`)."""
    n = problem.n
    if spec.densifies(problem):
        raise OptionError(f"method '{spec.name}' works on a dense {n} x {n} matrix "
                          f"({n * n * 8 / 2**30:.1f} GiB) but M is sparse (nnz={problem.M.nnz}); "
                          f"choose a method for large sparse problems (see 'lcpcli methods'), "
                          f"or set {DENSE_N_ENV}={n} to densify it anyway")


def dense_limited(spec: Method) -> bool:
    """Whether ``spec`` factorises or pivots on a dense M (``auto`` included: it factorises;
    sweeping methods, O(n^2) per sweep, are not limited)."""
    return spec.planner or spec.cost in (Cost.PIVOTING, Cost.FACTORING)


def check_dense_work(n: int, spec: Method) -> None:
    """ProblemError when ``spec`` (:func:`dense_limited`) works on a dense n x n M above the
    dense-work budget of :mod:`lcpcli.core.limits`.  One comparison up to ``DENSE_N_FLOOR``."""
    if n > DENSE_N_FLOOR and dense_limited(spec):
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


def dense_check(method: str | None) -> Callable[[int], None] | None:
    """:func:`check_dense_work` for ``method`` as a one-argument hook for
    :func:`lcpcli.io.load` (``check_dense=``: refused from the file's header, before a dense M
    is read); None when the method is not limited or unknown (:func:`resolve` says so)."""
    try:
        spec = method_of(method)
    except OptionError:
        return None
    if not dense_limited(spec):
        return None
    return lambda n: check_dense_work(n, spec)


def resolve(problem: Any, method: str | None, tol: Any = None,
            options: Mapping[str, Any] = _NO_OPTIONS) -> Request:
    """The validated :class:`Request` (see the module docstring); OptionError / ProblemError
    before any work.  Loads the method's compiled kernels once per process
    (:meth:`Method.prepare_once`), outside any timed region."""
    spec = get_method(DEFAULT_METHOD if method is None else method)
    key = request_key(spec, tol) if not options else None
    found = None if key is None else REQUESTS.get(key)
    if found is not None and found[0] is not spec:  # another record under a reused id
        found = None
    if problem.kind not in spec.kinds:
        check_kind(spec, problem.kind)
    if type(problem.M) is not np.ndarray and problem.sparse:  # a dense M: one type test
        check_dense_ok(problem, spec)
        check_sparse_work(problem.n, spec)
    elif problem.n > DENSE_N_FLOOR:
        check_dense_work(problem.n, spec)
    if found is None:
        opts = spec.parse_options(options)
        found = spec, resolve_tol(spec, tol), opts, spec.given_options(opts)
        spec.prepare_once()
        if key is not None:
            REQUESTS.put(key, found)
    if spec.preload is not None:  # the imports run needs, outside the timed region
        spec.preload(problem, found[2])
    return Request(problem, spec, found[1], found[2], found[3])


def request_key(spec: Method, tol: Any) -> tuple[Any, ...] | None:
    """The key of :data:`lcpcli.solvers.memo.REQUESTS` for a request without options: the
    parsed (default) options and the validated tol depend on the method's record (its ``id``;
    the stored value holds the record, checked on a hit) and the tol given; None (not
    memoised) for a tol that is not a float or None."""
    if tol is not None and type(tol) is not float:
        return None
    return (id(spec), tol)
