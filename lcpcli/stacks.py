"""``lcpcli.solve_many``: stacks of K problems of one size n, solved by the batched kernels
(:mod:`lcpcli.solvers.batched`) and certified; ``solve_each``: a list of problems, stacked by
size where that pays.  The one-problem path, every problem a kernel hands back goes through,
is :func:`lcpcli.api.solve`."""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.analysis.classify import Classifier
from lcpcli.api import check_dense_work, solve
from lcpcli.core import _certificate
from lcpcli.core.certificate import BETWEEN, check, from_row, scored
from lcpcli.core.errors import LcpError, OptionError, ProblemError
from lcpcli.core.numeric import check_dtype
from lcpcli.core.problem import (
    Problem,
    broken_bounds,
    check_bounds,
    check_n_eq,
    check_size,
    default_bound,
    problem_kind,
)
from lcpcli.core.result import (
    CONVERGED,
    SOLVED,
    STATUS_CODES,
    UNSOLVED,
    Result,
    StackResult,
    Status,
    Termination,
)
from lcpcli.core.text import option_name
from lcpcli.solvers.registry import Method, get_method
from lcpcli.solvers.request import check_kind, method_of, resolve_tol

#: Problems of a stack that ``auto`` classifies to choose the stack's method.
AUTO_SAMPLE = 8


@dataclass(frozen=True)
class StackPlan:
    """How :func:`solve_many` runs a stack: ``method`` (the registered method asked for, which
    also solves the retried problems), ``kernel_method`` (the method whose batched kernel runs
    the stack, None: one problem at a time) and the kernel's parsed ``kernel_options``.
    Made by :func:`plan_stack`; pass it back to :func:`solve_many` (``plan=``) to solve more
    chunks of the same stack without sampling again."""

    method: str
    kernel_method: str | None
    kernel_options: dict[str, Any]


def plan_stack(M: Any, q: Any, method: str | None = None, *, lower: Any = None,
               upper: Any = None, n_eq: int = 0, **options: Any) -> StackPlan:
    """The :class:`StackPlan` of :func:`solve_many` for this stack (same arguments)."""
    M, q, lower, upper, n_eq, spec, kind = _check_stack(M, q, method, lower, upper, n_eq,
                                                        options)
    lower, upper = _kernel_bounds(lower, upper)[:2]
    run_spec, kernel_options = _batched_method(spec, kind, options, M, q, lower, upper)
    return StackPlan(spec.name, None if run_spec is None else run_spec.name, kernel_options)


def _check_stack(M: Any, q: Any, method: str | None, lower: Any, upper: Any, n_eq: Any,
                 options: dict[str, Any]) -> tuple[Any, ...]:
    """Arrays, bounds, n_eq, method and kind of a stack, checked (ProblemError/OptionError)."""

    M = _stack_array(M, 3, "M")
    q = _stack_array(q, 2, "q")
    K, n = q.shape
    if M.shape != (K, n, n):
        raise ProblemError(f"a stack needs M of shape (K, n, n) and q of shape (K, n); got M "
                           f"{M.shape} and q {q.shape}")
    check_size(n, n)
    n_eq = check_n_eq(n_eq, n, bounded=lower is not None or upper is not None)
    lower, upper = _stack_bounds(lower, upper, K, n)
    kind = problem_kind(n_eq, lower is not None)
    spec = method_of(method)
    check_kind(spec, kind)
    spec.parse_options(options)  # unknown options and bad values: OptionError before any work
    check_dense_work(n, spec)  # K problems of dense work each: the budget of one
    return M, q, lower, upper, n_eq, spec, kind


def solve_many(M: Any, q: Any, method: str | None = None, *, tol: float | None = None,
               lower: Any = None, upper: Any = None, n_eq: int = 0, threads: int | None = None,
               backend: str | None = None, on_error: str = "raise",
               plan: StackPlan | None = None, warm: Any = None, record_basis: bool = False,
               certificates: bool = False, pivot_basis: bool = False,
               **options: Any) -> StackResult:
    """Solve a stack of K problems of one size n and certify every answer.

    ``M`` has shape (K, n, n) and ``q`` (K, n): problem ``k`` (0-based) is ``w = M[k] z +
    q[k]``, ``z >= 0``, ``w >= 0``, ``z^T w = 0``; ``lower``/``upper`` of shape (n,) or (K, n)
    make box LCPs, ``n_eq`` MLCPs (the first ``n_eq`` variables free).  ``method``, ``tol`` and
    method ``options`` as in :func:`solve`.

    A method with a batched kernel (``lcpcli methods``: Lemke, PGS, PSOR) solves the whole
    stack in one compiled call, in ``threads`` threads (default: the cores this process may
    use, one per 2 ms of estimated work at most: :func:`lcpcli.solvers.batched.useful_threads`)
    of ``backend`` (None: this process's default, ``"cpu"`` unless ``--backend`` or
    :func:`lcpcli.solvers.batched.set_default_backend` chose another; ``"c"``, ``"cuda"``:
    the single-source kernels on the CPU / a CUDA device; ``"auto"``: ``"cuda"`` for large
    stacks when a device is present; see :mod:`lcpcli.solvers.batched`); the certificate is
    checked
    inside the same call.  Every problem whose answer fails it (or whose method stopped) goes
    through the full one-problem pipeline, :func:`solve`, so the verdicts follow the same rules:
    ``solved`` only with a passed certificate, ``no_solution`` only with a proof.  ``auto``
    classifies a sample of up to :data:`AUTO_SAMPLE` problems, runs the method auto would try
    first on them for the whole stack when it has a batched kernel, and retries the rest with
    ``auto`` itself.  Without a batched kernel (or with options the kernel does not take, or an
    MLCP) every problem is solved by :func:`solve`.

    With ``backend="cuda"`` (or ``"auto"``) ``M`` and ``q`` may be device arrays (CuPy, or
    anything with ``__dlpack__`` on a CUDA device): the stack is not copied to the host and
    ``z``, ``w`` come back as CuPy arrays (:func:`lcpcli.solvers.backends.cuda.
    solve_many_device`).

    ``warm``: the :class:`StackResult` of a previous stack of the same shape (or a (K, n)
    array of points ``z0``, or of booleans: bases).  Below n = 200, when Lemke's batched
    kernel runs on the ``"cpu"`` backend, every problem starts from its basis in that kernel
    (:mod:`lcpcli.solvers.warm_stack`: block principal pivoting, then cold Lemke in the same
    call if that is not certified); otherwise problem ``k`` is solved by ``solve(...,
    warm=row k)`` (see :func:`solve`).  A row with NaN (e.g. of an ``error`` problem), or of a
    problem the previous stack did not solve, is solved cold.  The result's ``basis`` holds
    each answer's basis for the next step.

    ``record_basis``: the result's ``basis`` holds every problem's final basis
    (:func:`final_bases`) also for a cold stack: from Lemke's batched kernel on the ``"cpu"``
    backend at no extra cost (the certificate's pair states, filled in the same call: the warm
    kernel with no basis given runs cold Lemke, the same code as the cold kernel), otherwise by
    one certificate pass per problem afterwards.

    ``certificates``: the result's ``certificates`` holds the whole certificate of every answer
    the kernel certified (Lemke's and PGS/PSOR's kernels on the ``"cpu"`` backend; computed in
    the same call, the numbers :func:`lcpcli.core.certificate.check` gives for that ``z``).
    ``pivot_basis``: the result's ``pivot_basis`` holds each answer's complementary basis as
    Lemke's CPU kernel ended on it (see :attr:`StackResult.pivot_basis`).

    ``on_error``: ``"raise"`` (a problem with NaN or Inf data raises :class:`ProblemError`
    naming its index; problems before it are solved first) or ``"mark"`` (its status is
    ``error``; batch runs use this).
    """
    from lcpcli.solvers.batched import (
        KERNEL_SOLVED,
        choose_backend,
        default_backend,
        default_threads,
        get_backend,
        useful_threads,
    )

    start = time.perf_counter()
    if on_error not in ("raise", "mark"):
        raise OptionError(f"on_error must be 'raise' or 'mark', got {on_error!r}")
    backend = default_backend() if backend is None else backend
    if _on_device(M):  # CuPy / DLPack device arrays
        if backend in ("cuda", "auto"):
            from lcpcli.solvers.backends.cuda import solve_many_device

            return solve_many_device(M, q, method, tol=tol, lower=lower, upper=upper,
                                     n_eq=n_eq, threads=threads, on_error=on_error,
                                     options=options)
        raise OptionError(f"M is in device memory: use backend='cuda' (or 'auto'), or copy the "
                          f"stack to the host for backend='{backend}'")
    M, q, lower, upper, n_eq, spec, kind = _check_stack(M, q, method, lower, upper, n_eq,
                                                        options)
    K, n = q.shape
    if plan is not None and plan.method != spec.name:
        raise OptionError(f"plan= was made for method '{plan.method}', not '{spec.name}'")
    tol = resolve_tol(spec, tol)
    if threads is None:
        threads = useful_threads(default_threads(), K, n)
    elif not (isinstance(threads, int) and threads >= 1):
        raise OptionError(f"threads must be a positive integer, got {threads!r}")
    codes = STATUS_CODES
    messages: dict[int, str] = {}
    methods_of: dict[int, str] = {}
    results: dict[int, Result] = {}
    rows = _warm_rows(warm, K, n)
    k_lower, k_upper, bad = _kernel_bounds(lower, upper)
    if plan is None:
        run_spec, kernel_options = _batched_method(spec, kind, options, M, q, k_lower,
                                                   k_upper)
    else:
        run_spec = None if plan.kernel_method is None else get_method(plan.kernel_method)
        if run_spec is not None and kind not in run_spec.batch.kinds:
            # a plan of another stack: its kernel would ignore these bounds or equations
            raise OptionError(f"plan= runs the batched kernel of '{run_spec.name}', which "
                              f"does not handle {kind.upper()} problems: make the plan with "
                              f"this stack's bounds and n_eq (plan_stack(M, q, ...))")
        kernel_options = plan.kernel_options
    bases = warmed = None  # warm: the cpu Lemke kernel starts from each basis; else one by one
    if rows is not None:
        from lcpcli.solvers.warm_stack import stack_bases, uses_warm_kernel

        if run_spec is not None and uses_warm_kernel(run_spec, lower, K, n,
                                                     choose_backend(backend, K, n)):
            bases = stack_bases(warm, K, n)
        else:
            run_spec, kernel_options = None, {}
    elif record_basis and run_spec is not None:
        from lcpcli.solvers.warm_stack import uses_warm_kernel

        if uses_warm_kernel(run_spec, lower, K, n, choose_backend(backend, K, n)):
            bases = np.full((K, n), -1, np.int8)  # no basis: every problem runs cold Lemke
    name = spec.name
    if run_spec is not None:
        backend_ = get_backend(choose_backend(backend, K, n))
        kernel = backend_.kernel(run_spec.batch.kernel)
        if kernel is None:
            raise OptionError(f"batch backend '{backend}' has no '{run_spec.batch.kernel}' "
                              f"kernel (method '{run_spec.name}')")
        name = run_spec.batch.runs_as or run_spec.name
        out = backend_.outputs(M, K, n, certificates, pivot_basis)  # the kernel's final arrays
        run_spec.prepare_once()
        if bases is not None:
            from lcpcli.solvers.warm_stack import lemke_warm

            bases, warmed = lemke_warm(M, q, bases, tol=tol, options=kernel_options, out=out,
                                       threads=threads, scaling=run_spec.scaling)
        else:
            kernel(M, q, k_lower, k_upper, tol=tol, options=kernel_options, out=out,
                   threads=threads, scaling=run_spec.scaling)
        z, w, iterations, error, residual = out.z, out.w, out.iterations, out.error, \
            out.residual
        status = np.where(out.code == KERNEL_SOLVED, codes[Status.SOLVED],
                          codes[Status.UNSOLVED]).astype(np.int8)
        retry = np.flatnonzero(out.code != KERNEL_SOLVED)
        if bad.size:  # bad bounds: the kernel solved a stand-in; refused below
            retry = np.union1d(retry, bad)
            for extra, empty in ((out.cert, np.nan), (out.pivot_basis, -1)):
                if extra is not None:
                    extra[bad] = empty
            if warmed is not None:
                warmed[bad] = False
    else:
        z, w = np.full((K, n), np.nan), np.full((K, n), np.nan)
        status = np.full(K, codes[Status.UNSOLVED], np.int8)
        iterations, error = np.zeros(K, np.int64), np.full(K, np.inf)
        residual = np.full(K, np.nan)
        retry = np.arange(K)
    for k in retry.tolist():
        try:  # NaN or Inf data: never certified by a kernel, refused here
            problem = Problem.create(M[k], q[k], n_eq=n_eq,
                                     lower=None if lower is None else lower[k],
                                     upper=None if upper is None else upper[k])
        except ProblemError as exc:
            if on_error == "raise":
                raise ProblemError(f"problem {k} of the stack: {exc}") from None
            status[k], error[k], iterations[k] = codes[Status.ERROR], np.inf, 0
            z[k], w[k], residual[k] = np.nan, np.nan, np.nan
            if bases is not None:
                bases[k] = -1
            messages[k] = str(exc)
            continue
        try:
            row = None if rows is None or not np.all(np.isfinite(rows[k])) else rows[k]
            r = solve(problem, spec.name, tol=tol, warm=row, **options)
        except LcpError as exc:
            status[k], error[k], residual[k] = codes[Status.ERROR], np.inf, np.nan
            messages[k] = str(exc)
            continue
        z[k], w[k] = r.z, r.w
        status[k] = codes[r.status]
        iterations[k], error[k], residual[k] = r.iterations, r.error, r.residual
        messages[k] = r.message
        methods_of[k] = r.method
        if bases is not None and r.basis is not None:
            bases[k] = r.basis
        else:
            r.basis  # noqa: B018  (computed now: the Result then no longer holds the problem)
        results[k] = r
    retried = np.zeros(K, bool)
    retried[retry] = run_spec is not None
    out_res = StackResult(z=z, w=w, status=status, iterations=iterations, error=error,
                          residual=residual, method=name, tol=tol, retried=retried,
                          messages=messages, methods=methods_of, batched=run_spec is not None,
                          results=results, basis=bases,
                          warmed=None if warmed is None or rows is None else warmed.astype(bool),
                          certificates=None if run_spec is None else out.cert,
                          pivot_basis=None if run_spec is None else out.pivot_basis)
    if record_basis:
        out_res.basis = final_bases(out_res, M, q, lower=lower, upper=upper, n_eq=n_eq)
    out_res.seconds = time.perf_counter() - start
    return out_res


def _basic_row(problem: Problem, warm: Any) -> np.ndarray:
    """One problem's warm start (checked by :func:`lcpcli.solvers.warm.check_warm`) as a row
    of :func:`solve_many`'s ``warm``: 1 where ``z_i`` is basic, else 0; NaN (cold) for None or
    a Result without a basis.  A Result or a basis in letters gives its basic pairs (the
    ``F`` states, :func:`lcpcli.solvers.warm.warm_basis`, as :func:`solve` takes them);
    booleans and points their nonzero entries."""
    from lcpcli.solvers.warm import warm_basis

    if warm is None or (isinstance(warm, Result) and warm.basis is None):
        return np.full(problem.n, np.nan)
    if isinstance(warm, (Result, str)):
        return (warm_basis(problem, warm) == BETWEEN).astype(np.float64)
    return np.asarray(warm, dtype=bool).astype(np.float64)


def _warm_rows(warm: Any, K: int, n: int) -> np.ndarray | None:
    """The (K, n) warm-start rows of :func:`solve_many` (points, or booleans: bases)."""
    if warm is None:
        return None
    rows = np.asarray(warm.z if isinstance(warm, StackResult) else warm)
    if rows.shape != (K, n):
        raise OptionError(f"warm start of a stack must have shape ({K}, {n}), got {rows.shape}")
    if rows.dtype.kind != "b":  # points: real numbers only (booleans are bases)
        try:
            check_dtype(rows.dtype, "warm start of a stack")
        except ProblemError as exc:
            raise OptionError(str(exc)) from None
    return rows


def final_bases(res: StackResult, M: np.ndarray, q: np.ndarray, *, lower: Any = None,
                upper: Any = None, n_eq: int = 0) -> np.ndarray:
    """(K, n) int8: the final basis of every problem of ``res`` (the codes of
    :attr:`Result.basis`: 0 ``L``, 1 ``U``, 2 ``F``; -1 where ``z`` is not finite, e.g. an
    ``error`` problem).  ``res.basis`` where the stack recorded it (a warm stack), else each
    problem's Result's, else the certificate's pair states of ``z`` on ``M``, ``q`` (and the
    bounds), the one definition of :attr:`Result.basis`."""
    z = np.asarray(res.z)
    K, n = z.shape
    finite = np.isfinite(z).all(axis=1)
    if res.basis is not None:
        out = np.array(res.basis, dtype=np.int8)
    else:
        out = np.full((K, n), -1, np.int8)
        w = np.empty(n)
        for k in np.flatnonzero(finite).tolist():
            r = res.results.get(k)
            if r is not None and r.basis is not None:
                out[k] = r.basis
                continue
            if lower is None and upper is None and _certificate.certify_arrays(
                    M[k], q[k], z[k], n_eq, None, None, w, out[k])[0] != 2:
                continue
            # bounds, or an overflow that the rescaled certificate handles: through Problem
            p = Problem.create(M[k], q[k], n_eq=n_eq, lower=None if lower is None else lower[k],
                               upper=None if upper is None else upper[k])
            check(p, z[k], res.tol, state=out[k])
    out[~finite] = -1
    return out


#: Problems of one size a list needs before :func:`solve_each` stacks them.
STACK_MIN = 8


def solve_each(problems: list[Problem], method: str | None = None, *, tol: float | None = None,
               threads: int | None = None, warms: list[Any] | None = None,
               **options: Any) -> list[Result]:
    """``[solve(p, method, tol=tol, **options) for p in problems]``, faster for many small ones.

    Dense LCPs of one size, at least :data:`STACK_MIN` of them, are stacked and solved by
    :func:`solve_many` (one compiled call in ``threads`` threads); each answer's certificate is
    taken from the kernel's own (``solve_many(certificates=True)``; recomputed where a backend
    does not record it), and the problems the kernel handed back come with the Result of
    their own :func:`solve`.  Other
    problems are solved one by one.  ``seconds`` of a stacked problem is its share of the
    stack's time; ``info["batched"]`` marks them.  ``warms``: one warm start per problem (a
    basis, booleans, or None: cold), as ``solve_many(warm=)`` and ``solve(warm=)`` take them;
    ``info["warm"]`` then says whether the warm start gave the answer.
    """
    from lcpcli.solvers.warm import check_warm

    out: list[Result | None] = [None] * len(problems)
    if warms is not None and len(warms) != len(problems):
        raise OptionError(f"warms= needs one warm start (or None) per problem: "
                          f"{len(warms)} for {len(problems)} problems")
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(problems):
        if not isinstance(p, Problem):
            raise TypeError(f"solve_each takes Problems (lcpcli.Problem.create(M, q)); item {i} "
                            f"is a {type(p).__name__}")
        if warms is not None and warms[i] is not None:
            check_warm(p, warms[i])
        if p.kind == "lcp" and not p.sparse:
            groups.setdefault(p.n, []).append(i)
    for idx in groups.values():
        if len(idx) < STACK_MIN:
            continue
        warm = None
        if warms is not None and any(warms[i] is not None for i in idx):
            # rows as points: 1 where z_i is basic, NaN for a problem without one (cold)
            warm = np.stack([_basic_row(problems[i], warms[i]) for i in idx])
        res = solve_many(_stacked([problems[i].M for i in idx]),
                         np.stack([problems[i].q for i in idx]), method, tol=tol,
                         threads=threads, warm=warm, certificates=True, pivot_basis=True,
                         **options)
        for j, i in enumerate(idx):
            out[i] = stacked_result(res, j, problems[i])
    for i, p in enumerate(problems):
        if out[i] is None:
            warm = None if warms is None else warms[i]
            out[i] = solve(p, method, tol=tol, warm=warm, **options)
            if warm is not None:
                out[i].info["warm"] = bool(out[i].info.get("warm", False))
    return out  # type: ignore[return-value]


def stacked_result(res: StackResult, j: int, p: Problem) -> Result:
    """Problem ``j`` of ``res`` (a :func:`solve_many` stack run with ``certificates=True`` and
    ``pivot_basis=True``) as the :class:`Result` of ``p``, the problem it stacked: the Result of
    its own :func:`solve` when the kernel handed it back, else the kernel's answer with the
    kernel's certificate and ``w`` (recomputed where the backend did not record them);
    ``seconds``: its share of the stack's time; ``info["batched"]``, ``info["basis"]`` (the
    basic z's of the pivoting's final basis) and, for a warm stack, ``info["warm"]``."""
    if j in res.results:  # solved on its own (the kernel handed it back)
        r = res.results[j]
        r.problem_name = p.name
        return r
    rows = res.certificates
    z = res.z[j].copy()
    source = None
    if rows is not None and rows[j, 0] == rows[j, 0]:
        # certified in the kernel: its certificate and w (and pair states, when the
        # kernel recorded them; else computed on first use), as check gives them
        cert, w = from_row(rows[j], res.tol), res.w[j].copy()
        basis = None if res.basis is None else res.basis[j].copy()
        source = p if basis is None else None
    else:
        states = np.empty(p.n, dtype=np.int8)
        cert, w = check(p, z, res.tol, state=states)
        basis = scored(states)
    status = SOLVED if cert.passed else UNSOLVED
    out = Result(status=status, method=res.method_of(j), z=z, w=w,
                 iterations=int(res.iterations[j]), seconds=res.seconds / len(res),
                 certificate=cert, message=res.message(j),
                 termination=CONVERGED if cert.passed else Termination.NUMERICAL,
                 problem_name=p.name, info={"batched": True}, known_basis=basis,
                 basis_source=source)
    if res.pivot_basis is not None and res.pivot_basis[j, 0] >= 0:
        # the basic z's of the pivoting's final basis (as lcpcli.solve's Lemke reports)
        out.info["basis"] = np.flatnonzero(res.pivot_basis[j]).tolist()
    if res.warmed is not None:
        out.info["warm"] = bool(res.warmed[j])
    return out


def _stacked(blocks: list[np.ndarray]) -> np.ndarray:
    """``np.stack(blocks)``: a view, without the copy, when the blocks are the consecutive
    C-contiguous pieces of one buffer in order (contact islands are built so:
    :func:`lcpcli.contact.islands.island_problems`); a copy otherwise."""
    first = blocks[0]
    base, size = first.base, first.nbytes
    if base is not None and base.ndim == 1 and base.dtype == first.dtype:
        start = first.__array_interface__["data"][0]
        if all(b.base is base and b.flags.c_contiguous and b.shape == first.shape
               and b.__array_interface__["data"][0] == start + j * size
               for j, b in enumerate(blocks)):
            offset = start - base.__array_interface__["data"][0]
            return np.ndarray((len(blocks), *first.shape), first.dtype, base, offset)
    return np.stack(blocks)


def _on_device(a: Any) -> bool:
    """Whether ``a`` lives in CUDA memory (CuPy, or DLPack on a CUDA device: torch, JAX)."""
    if hasattr(a, "__cuda_array_interface__"):
        return True
    from lcpcli.solvers.backends.cuda import on_device

    return hasattr(a, "__dlpack_device__") and not isinstance(a, np.ndarray) and on_device(a)


def _stack_array(a: Any, ndim: int, label: str) -> np.ndarray:
    """``a`` as a C-contiguous float64 array of ``ndim`` dimensions (the data rule of
    :mod:`lcpcli.core.numeric`: real numbers only)."""

    arr = np.asarray(a)
    check_dtype(arr.dtype, label)
    if arr.ndim != ndim:
        shape = "(K, n, n)" if ndim == 3 else "(K, n)"
        raise ProblemError(f"{label} of a stack must have shape {shape}, got {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float64)


def _stack_bounds(lower: Any, upper: Any, K: int,
                  n: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Bounds of shape (n,) or (K, n) as (K, n) arrays (a missing one by the one-sided bounds
    rule, :func:`lcpcli.core.problem.default_bound`).  Shared bounds are checked here by the
    rules of one problem's (:func:`lcpcli.core.problem.check_bounds`); per-problem ones are
    checked problem by problem (:func:`_kernel_bounds`)."""

    if lower is None and upper is None:
        return None, None
    given = []
    for value, label in ((lower, "lower"), (upper, "upper")):
        if value is None:
            given.append(default_bound(label, n))
            continue
        arr = np.asarray(value)
        check_dtype(arr.dtype, label)
        arr = arr.astype(np.float64)
        if arr.shape not in ((n,), (K, n)):
            raise ProblemError(f"{label} of a stack must have shape ({n},) or ({K}, {n}), "
                               f"got {arr.shape}")
        given.append(arr)
    if given[0].ndim == 1 and given[1].ndim == 1:  # shared bounds: the whole stack's data
        check_bounds(*given)
    lo, up = (np.ascontiguousarray(np.broadcast_to(arr, (K, n))) for arr in given)
    return lo, up


def _kernel_bounds(lower: np.ndarray | None, upper: np.ndarray | None
                   ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray]:
    """``(lower, upper, bad)``: the problems (rows) of per-problem bounds that break the rules
    (:func:`lcpcli.core.problem.broken_bounds`) as ``bad`` indices, and bounds for the kernels
    and the sampling with those rows replaced by the LCP's ``[0, inf)``.  A bad problem is
    refused on its own (``on_error``), as one with NaN in M or q, by the one-problem rules:
    the caller keeps the given bounds for that."""
    if lower is None:
        return lower, upper, np.zeros(0, np.int64)
    bad = np.flatnonzero(broken_bounds(lower, upper).any(axis=1))
    if bad.size:
        lower, upper = lower.copy(), upper.copy()
        lower[bad], upper[bad] = 0.0, np.inf
    return lower, upper, bad


def _batched_method(spec: Method, kind: str, options: dict[str, Any], M: np.ndarray,
                    q: np.ndarray, lower: np.ndarray | None,
                    upper: np.ndarray | None) -> tuple[Method | None, dict[str, Any]]:
    """The method whose batched kernel runs the stack and the kernel's options, or
    (None, {}) when the stack is solved one problem at a time (see :func:`solve_many`)."""
    given = {option_name(k): v for k, v in options.items()
             if v is not None and v is not False}
    if spec.planner:
        if set(given) - {"max_iter"} or q.shape[0] == 0:
            return None, {}  # order=, z0=: auto's own per-problem logic
        chosen = _auto_choice(M, q, lower, upper)
        if chosen is None:
            return None, {}
        spec = get_method(chosen)
        given = {k: v for k, v in given.items() if k in spec.options}
    batch = spec.batch
    if batch is None or kind not in batch.kinds or set(given) - set(batch.options):
        return None, {}
    return spec, spec.parse_options(given)


def _auto_choice(M: np.ndarray, q: np.ndarray, lower: np.ndarray | None,
                 upper: np.ndarray | None) -> str | None:
    """The method ``auto`` would try first on most of a sample of the stack (problems with
    ``q >= 0`` and no bounds are skipped: z = 0 solves them; so are problems with NaN or Inf
    data), or None."""

    from lcpcli.solvers import policy

    candidates = np.arange(q.shape[0]) if lower is not None else \
        np.flatnonzero((q < 0).any(axis=1))
    if candidates.size == 0:
        return None
    picks = candidates[np.linspace(0, candidates.size - 1,
                                   min(AUTO_SAMPLE, candidates.size)).astype(int)]
    votes: Counter[str] = Counter()
    for k in dict.fromkeys(picks.tolist()):
        if not (np.isfinite(M[k]).all() and np.isfinite(q[k]).all()):
            continue
        problem = Problem.create(M[k], q[k], lower=None if lower is None else lower[k],
                                 upper=None if upper is None else upper[k])
        c = Classifier(problem)
        regime, step = policy.opening(problem, c)  # auto's first step, as auto.run takes it
        if not regime.optimistic:
            step = next(policy.iter_plan(problem, c, regime=regime), None)
        if step is not None:
            votes[step.method] += 1
    return votes.most_common(1)[0][0] if votes else None
