"""Projected Gauss-Seidel (``pgs``) and projected SOR (``psor``) for LCPs and box LCPs.

Problem: ``w = M z + q`` with ``z`` in the box ``[l, u]`` (LCP: ``[0, inf)``); one sweep sets, for
i = 1..n in order, ``z_i <- proj_[l_i, u_i](z_i - omega (M z + q)_i / M_ii)`` (``omega = 1``: PGS).
For a box LCP the projection is onto ``[lower_i, upper_i]`` (the box form's sign convention:
``w >= 0`` at the lower bound, ``w <= 0`` at the upper bound, ``w = 0`` between).

Matrix classes: converges for **symmetric positive semidefinite M with a positive diagonal**
(and ``0 < omega < 2``) whenever the problem has a solution (it is then a block coordinate
descent on the quadratic ``z^T M z / 2 + q^T z`` over the box); also for strictly diagonally
dominant / H-matrices with positive diagonal (a contraction).  Outside these classes it may stall or
cycle, which ends at the iteration limit and is reported as ``unsolved``.  A zero or negative
diagonal entry makes the update undefined: the method stops at once with an ``unsolved`` verdict
saying so.

Storage: a dense ``numpy`` M or a ``scipy.sparse`` CSR M (the sweep runs over the CSR arrays,
O(nnz) per sweep, never densified).  Warm start: option ``z0`` (projected onto the box first).
Stopping: a normwise scaled error (estimated during the sweep, confirmed by one exact product
``M z``), its target tightened tenfold until the componentwise certificate passes.  The sweeps
run in blocks of ``STALL_BLOCK``; when the best normwise error after each block fell by less
than ``STALL_DECREASE`` (relative) over the last ``STALL_WINDOW`` blocks the method stops with
termination ``stalled`` (a cycle, e.g. PGS on a non-symmetric P-matrix, or a fixed point
that is not a solution) instead of running to the sweep limit.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.analysis.classify import diagonal
from lcpcli.core.certificate import matrix_norm_inf
from lcpcli.core.numeric import binary_exponents
from lcpcli.core.result import (
    CONVERGED,
    ITERATION_LIMIT,
    NOT_APPLICABLE,
    NUMERICAL,
    STALLED,
    Outcome,
)
from lcpcli.core.text import plural
from lcpcli.solvers.kernels import pgs as K
from lcpcli.solvers.options import bool_option, omega_option, positive_int, vector_option
from lcpcli.solvers.registry import BatchSpec, Cost, Guarantee, Method, Option, Requirement, when
from lcpcli.solvers.support import StallWatch, certified_error, start_point

#: Sweep limit when none is given.
DEFAULT_MAX_ITER = 10_000
#: Default relaxation of ``psor``.
DEFAULT_OMEGA = 1.3
#: Stagnation (termination ``stalled``): the sweeps run in blocks of STALL_BLOCK; stop when the
#: best normwise error after a block fell by less than STALL_DECREASE (relative) over the last
#: STALL_WINDOW blocks (1,000 sweeps).
STALL_BLOCK, STALL_WINDOW, STALL_DECREASE = 50, 20, 1e-3


def batch_params(n: int, options: Mapping[str, Any]) -> dict[str, Any]:
    """The batched ``sor`` kernel's parameters (:attr:`BatchSpec.params`; n does not enter):
    the relaxation ``omega`` (default 1, Gauss-Seidel) and the sweep limit (default
    :data:`DEFAULT_MAX_ITER`)."""
    return {"omega": float(options.get("omega") or 1.0),
            "max_iter": int(options.get("max_iter") or DEFAULT_MAX_ITER)}


def run_sor(problem: Any, *, tol: float, omega: float = 1.0, max_iter: int | None = None,
            z0: np.ndarray | None = None, name: str = "PGS", trace: bool = False) -> Outcome:
    """Run projected SOR with relaxation ``omega`` (1 = Gauss-Seidel); see the module docstring.

    ``trace=True`` runs the numpy replica :mod:`lcpcli.solvers.trace.pgs` instead of the
    kernels (same sweeps) and records a sweep table of the whole run in ``Outcome.trace``.
    """
    if trace:
        from lcpcli.solvers.trace.pgs import SweepRecorder

        recorder = SweepRecorder()
        out = _run_sor(problem, tol=tol, omega=omega, max_iter=max_iter, z0=z0, name=name,
                       kernel=recorder)
        out.trace = recorder.trace  # not applicable: no sweep, nothing recorded
        return out
    return _run_sor(problem, tol=tol, omega=omega, max_iter=max_iter, z0=z0, name=name)


def _run_sor(problem: Any, *, tol: float, omega: float, max_iter: int | None,
             z0: np.ndarray | None, name: str, kernel: Any = None) -> Outcome:
    n = problem.n
    lo, up = (np.ascontiguousarray(b, dtype=np.float64) for b in problem.bounds())
    z = np.clip(start_point(problem, z0), lo, up)
    M = problem.M
    diag = diagonal(M)
    bad = np.flatnonzero(~(diag > 0) & (lo < up))
    if bad.size:
        i = int(bad[0])
        return Outcome(z, 0, NOT_APPLICABLE,
                       f"{name} needs a positive diagonal: M[{i + 1},{i + 1}] = {diag[i]:g} "
                       f"({bad.size} such entr{'y' if bad.size == 1 else 'ies'}); "
                       f"the update z_i -= r_i / M_ii is undefined")
    diag = np.where(diag > 0, diag, 1.0)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    if kernel is None:  # traces show the user's numbers
        M, q, diag = _rows_in_range(M, q, diag)
    mu = matrix_norm_inf(M)
    mu = mu if mu > 0 else 1.0
    qnorm = float(np.max(np.abs(q))) if n else 0.0
    limit = max_iter or DEFAULT_MAX_ITER
    if kernel is not None:  # the traced replica takes the dense or CSR matrix itself
        Mx = M.tocsr() if problem.sparse else np.ascontiguousarray(M, dtype=np.float64)

        def sweep(budget: int, target: float) -> tuple[int, int, float]:
            return kernel(Mx, q, diag, lo, up, z, float(omega), budget, target, mu, qnorm)
    elif problem.sparse:
        A = M.tocsr()
        indptr, indices = A.indptr.astype(np.int64), A.indices.astype(np.int64)
        data = np.ascontiguousarray(A.data, dtype=np.float64)

        def sweep(budget: int, target: float) -> tuple[int, int, float]:
            return K.pgs_csr(indptr, indices, data, q, diag, lo, up, z, float(omega), budget,
                             target, mu, qnorm)
    else:
        Md = np.ascontiguousarray(M, dtype=np.float64)

        def sweep(budget: int, target: float) -> tuple[int, int, float]:
            return K.pgs_dense(Md, q, diag, lo, up, z, float(omega), budget, target, mu, qnorm)

    # the kernel stops on a cheap normwise estimate; the certificate is componentwise, so keep
    # sweeping with a tighter internal target until the certificate itself is met
    sweeps, target = 0, tol
    watch = StallWatch(STALL_WINDOW, STALL_DECREASE)  # the normwise error after each block
    stuck = False
    while True:
        status, done, err = sweep(min(limit - sweeps, STALL_BLOCK), target)
        sweeps += int(done)
        if status == K.LIMIT and sweeps < limit:
            if not watch.update(err):
                continue
            stuck = True
            err = certified_error(problem, z)
            break
        if status != K.CONVERGED:
            break
        err = certified_error(problem, z)
        if err <= tol or sweeps >= limit or target < 1e-15:
            status = K.CONVERGED if err <= tol else K.LIMIT
            break
        target *= 0.1
    label = name if omega == 1.0 else f"{name} (omega = {omega:g})"
    if status == K.CONVERGED:
        return Outcome(z, int(sweeps), CONVERGED,
                       f"{label}: certified error {err:.2e} after {plural(sweeps, 'sweep')}")
    if status == K.DIVERGED:
        return Outcome(z, int(sweeps), NUMERICAL,
                       f"{label} diverged (non-finite iterate after {plural(sweeps, 'sweep')})")
    if stuck:
        return Outcome(z, int(sweeps), STALLED,
                       f"{label}: no progress: the normwise error fell by less than "
                       f"{STALL_DECREASE:g} (relative) over the last "
                       f"{STALL_WINDOW * STALL_BLOCK:,} sweeps, after "
                       f"{plural(sweeps, 'sweep')} (certified error {err:.2e}; M may be "
                       f"outside the method's class, or the problem has no solution)")
    if sweeps < limit:  # the target was tightened to rounding level: more sweeps cannot help
        return Outcome(z, int(sweeps), NUMERICAL,
                       f"{label}: normwise error at rounding level after "
                       f"{plural(sweeps, 'sweep')}, but certified error {err:.2e} > tol")
    return Outcome(z, int(sweeps), ITERATION_LIMIT,
                   f"{label}: sweep limit {limit} reached with error {err:.2e} "
                   f"(raise --max-iter, or M may be outside the method's class)")


#: Rows whose largest entry (of M and q) lies outside [2^-ROW_RANGE, 2^ROW_RANGE], or rows whose
#: largest entries differ by more than 2^ROW_SPREAD, are first scaled by powers of two.
ROW_RANGE, ROW_SPREAD = 500, 100


def _rows_in_range(M: Any, q: np.ndarray, diag: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray]:
    """``(D M, D q, D diag)`` with ``D`` the powers of two that bring each row's largest entry
    near 1, when the rows are out of range (see :data:`ROW_RANGE`); else the arguments.

    Every sweep of (P)SOR is the same on the row-scaled copy (row ``i``'s update divides
    ``(M z + q)_i`` by ``M_ii``), but its normwise stopping test and the sums ``M z + q`` stay
    finite and meaningful: on ``diag(1e308, 1)`` the unscaled test ``||r|| <= tol (mu ||z|| +
    ||q||)`` overflows to Inf and passes at once, and a row of 1e-300 next to rows of 1 is
    never looked at."""
    if M.shape[0] == 0:
        return M, q, diag
    absq = np.abs(q)
    if hasattr(M, "tocsr"):
        A = M.tocsr()
        peak = np.maximum(absq, np.asarray(abs(A).max(axis=1).todense()).ravel())
    else:
        peak = np.maximum(absq, np.max(np.abs(M), axis=1))
    e = binary_exponents(peak)
    if e.max() <= ROW_RANGE and e.min() >= -ROW_RANGE and e.max() - e.min() <= ROW_SPREAD:
        return M, q, diag
    # D = 2^-e in two exact steps (2^1074, for a subnormal row, is not a double)
    half = np.ldexp(1.0, (-(e // 2)).astype(np.int32))
    rest = np.ldexp(1.0, (-(e - e // 2)).astype(np.int32))
    if hasattr(M, "tocsr"):
        import scipy.sparse as sp  # only for sparse data out of range

        Ms = sp.diags(rest) @ (sp.diags(half) @ A)
        Ms = Ms.tocsr()
    else:
        Ms = np.ascontiguousarray((M * half[:, None]) * rest[:, None])
    return Ms, np.ascontiguousarray(q * half * rest), diag * half * rest


def run_pgs(problem: Any, *, tol: float, max_iter: int | None = None,
            z0: np.ndarray | None = None, trace: bool = False) -> Outcome:
    """Projected Gauss-Seidel (``omega = 1``)."""
    return run_sor(problem, tol=tol, omega=1.0, max_iter=max_iter, z0=z0, name="PGS",
                   trace=trace)


def run_psor(problem: Any, *, tol: float, omega: float = DEFAULT_OMEGA,
             max_iter: int | None = None, z0: np.ndarray | None = None,
             trace: bool = False) -> Outcome:
    """Projected SOR with relaxation ``omega`` in (0, 2)."""
    return run_sor(problem, tol=tol, omega=omega, max_iter=max_iter, z0=z0, name="PSOR",
                   trace=trace)


#: Auto's sweep cap when the user gave none (a fallback should fail fast).
AUTO_MAX_ITER = 1000
_SYM = ("symmetric", "positive_diagonal")
_NEEDS = (Requirement(when("positive_diagonal"), "the update divides by M_ii"),)
_COMMON = {
    "max_iter": Option(positive_int, None, f"sweep limit (default {DEFAULT_MAX_ITER})"),
    "z0": Option(vector_option, None, "warm start z (projected onto the bounds)"),
    "trace": Option(bool_option, False, "record a sweep table (numpy replica of the kernel, "
                                         "same sweeps; slow for large n)"),
}

METHODS = [
    Method(
        name="pgs",
        run=run_pgs,
        summary="projected Gauss-Seidel (dense or sparse CSR, warm start, box projection)",
        guarantees=(
            Guarantee(when(*_SYM, "pd"), "converges (linearly)"),
            Guarantee(when("h_matrix"), "a contraction: converges"),
            Guarantee(when(*_SYM, "psd"), "converges when a solution exists (slowly if M is "
                                          "singular)", slow=True),
        ),
        needs=_NEEDS,
        cost=Cost.SWEEPING,
        preference=20,
        fallback="projected Gauss-Seidel, last resort",
        auto_max_iter=AUTO_MAX_ITER,
        kinds=("lcp", "box"),
        sparse=True,
        options=dict(_COMMON),
        batch=BatchSpec("sor", ("max_iter",), kinds=("lcp", "box"), params=batch_params),
    ),
    Method(
        name="psor",
        run=run_psor,
        summary="projected SOR with relaxation omega (dense or sparse CSR, warm start)",
        guarantees=(
            Guarantee(when(*_SYM, "pd"), "converges for 0 < omega < 2 (linearly)"),
            Guarantee(when(*_SYM, "psd"), "converges when a solution exists, 0 < omega < 2 "
                                          "(slowly if M is singular)", slow=True),
        ),
        needs=_NEEDS,
        cost=Cost.SWEEPING,
        preference=10,
        auto_max_iter=AUTO_MAX_ITER,
        kinds=("lcp", "box"),
        sparse=True,
        options={"omega": Option(omega_option, DEFAULT_OMEGA,
                                 f"relaxation, 0 < omega < 2 (default {DEFAULT_OMEGA})"),
                 **_COMMON},
        batch=BatchSpec("sor", ("omega", "max_iter"), kinds=("lcp", "box"),
                        params=batch_params),
    ),
]
