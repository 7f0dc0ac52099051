"""Primal-dual interior-point method (Mehrotra predictor-corrector) for monotone LCPs.

Problem: LCP(q, M), ``w = M z + q``, ``0 <= z _|_ w >= 0``.  The iterates keep ``z > 0`` and
``w > 0`` as independent variables (an *infeasible* interior-point method: the residual
``r = M z + q - w`` is driven to zero with the complementarity gap ``mu = z^T w / n``).  Each
iteration solves, with ``D = diag(w / z)``, two systems with the same matrix ``M + D``
(Cholesky when M is symmetric, LU otherwise; sparse LU for a scipy.sparse M):

* predictor (affine scaling): ``(M + D) dz = -w - r``, ``dw = M dz + r``;
* corrector: centring ``sigma = (mu_aff / mu)^3`` and the second-order term ``dz_aff dw_aff``.

The step keeps 0.99995 of the distance to the boundary.  Final rounding: once the gap is small,
the active set ``{i : z_i > w_i}`` is guessed and ``M_BB z_B = -q_B`` re-solved (least squares
when singular, as for rank-deficient PSD matrices); the rounded point is kept when it scores
better, so that the certificate (which recomputes ``w = M z + q``) can pass at the roundoff level.

Stagnation: when the best merit ``max(gap, ||r||_inf)`` fell by less than ``STALL_DECREASE``
(relative) over the last ``STALL_WINDOW`` iterations, the method stops with termination
``stalled`` (a given ``--max-iter`` is then not run out to no purpose).

Matrix classes: **monotone LCPs (M positive semidefinite, not necessarily symmetric)**, where it
converges in a number of iterations that grows slowly with n; a problem without a solution makes
the iterates diverge, which is reported as ``unsolved`` (never as a proof).  It may also work on
P-matrices and other sufficient matrices, with no guarantee.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from lcpcli.analysis.classify import SYM_TOL, is_symmetric
from lcpcli.core.certificate import matrix_norm_inf
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, NUMERICAL, STALLED, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.options import positive_int
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import StallWatch, certified_error, preload_linalg, refine

DEFAULT_MAX_ITER = 100
#: Fraction of the step to the boundary that is taken.
STEP_FRACTION = 0.99995
#: Try the active-set rounding when the certified error of the iterate is below this.
ROUND_BELOW = 1e-3
#: Stagnation (termination ``stalled``): the best merit ``max(gap, ||r||_inf)`` fell by less
#: than STALL_DECREASE (relative) over the last STALL_WINDOW iterations.
STALL_WINDOW, STALL_DECREASE = 20, 1e-3


class _Factor:
    """A factorisation of ``M + diag(d)`` (dense Cholesky/LU or sparse LU)."""

    def __init__(self, M: Any, d: np.ndarray, sparse: bool, symmetric: bool) -> None:
        if sparse:
            import scipy.sparse as sp  # scipy is imported on first use (start-up budget)
            import scipy.sparse.linalg as spla

            K = (M + sp.diags(d)).tocsc()
            self._solve = spla.splu(K).solve
            return
        import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

        K = M.copy()
        K[np.diag_indices_from(K)] += d
        if symmetric:
            try:
                c = sla.cho_factor(K, check_finite=False)
                self._solve = lambda b: sla.cho_solve(c, b, check_finite=False)
                return
            except np.linalg.LinAlgError:
                pass
        lu = sla.lu_factor(K, check_finite=False)
        self._solve = lambda b: sla.lu_solve(lu, b, check_finite=False)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._solve(b)


def _max_step(x: np.ndarray, dx: np.ndarray) -> float:
    """Largest ``a <= 1`` with ``x + a dx >= 0`` (x > 0)."""
    neg = dx < 0
    if not np.any(neg):
        return 1.0
    return float(min(1.0, np.min(-x[neg] / dx[neg])))  # a tiny dx_i: Inf, no bound


def run(problem: Any, *, tol: float, max_iter: int | None = None) -> Outcome:
    """Mehrotra predictor-corrector on a monotone LCP; see the module docstring.  Floating-point
    exceptions are quiet (not numpy warnings, which the CLI would print): a step that is not
    finite ends the run (termination ``numerical``), as does a divergence."""
    with np.errstate(all="ignore"):
        return _run(problem, tol, max_iter)


def _run(problem: Any, tol: float, max_iter: int | None) -> Outcome:
    n = problem.n
    q = problem.q
    if n == 0 or np.min(q) >= 0:
        return Outcome(np.zeros(n), 0, CONVERGED, "q >= 0: z = 0 solves the problem")
    sparse = problem.sparse
    M = problem.M.tocsr() if sparse else np.ascontiguousarray(problem.M, dtype=np.float64)
    symmetric = is_symmetric(M, SYM_TOL)
    lo, up = problem.bounds()
    mu_M = matrix_norm_inf(M)
    mu_M = mu_M if mu_M > 0 else 1.0
    qn = float(np.max(np.abs(q)))
    limit = max_iter or DEFAULT_MAX_ITER

    def matvec(x: np.ndarray) -> np.ndarray:
        return np.asarray(M @ x).ravel()

    # starting point: z = w = s e with s balancing the sizes of M and q
    s = max(1.0, np.sqrt(qn / mu_M)) if qn > 0 else 1.0
    z = np.full(n, s)
    w = np.maximum(matvec(z) + q, s)
    best_z, best_err = np.zeros(n), certified_error(problem, np.zeros(n))
    termination, why = ITERATION_LIMIT, f"iteration limit {limit} reached"
    it = 0
    rounded = False
    zmax0 = float(np.max(z))
    watch = StallWatch(STALL_WINDOW, STALL_DECREASE)
    while True:
        wz = matvec(z) + q
        err = certified_error(problem, z)
        if err < best_err:
            best_z, best_err, rounded = z.copy(), err, False
        if best_err <= tol:
            termination, why = CONVERGED, "certified error below tolerance"
            break
        if err <= ROUND_BELOW:
            polished = refine(problem, z)
            if polished is not None and polished[1] < best_err:
                best_z, best_err, rounded = polished[0], polished[1], True
            if best_err <= tol:
                termination, why = CONVERGED, "certified error below tolerance after rounding"
                break
        if it >= limit:
            break
        if float(np.max(z)) > 1e12 * max(zmax0, 1.0):
            termination = NUMERICAL
            why = "iterates diverge (the problem may have no solution, or M is not monotone)"
            break
        r = wz - w
        gap = float(z @ w) / n
        merit = max(gap, float(np.max(np.abs(r))))
        if watch.update(merit):
            termination = STALLED
            why = (f"no progress: the merit max(gap, ||r||) fell by less than "
                   f"{STALL_DECREASE:g} (relative) over the last {STALL_WINDOW} iterations")
            break
        it += 1
        d = w / z
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                K = _Factor(M, d, sparse, symmetric)
                dz_a = K.solve(-w - r)
        except (np.linalg.LinAlgError, ValueError, RuntimeError):
            termination, why = NUMERICAL, "singular Newton system"
            break
        dw_a = matvec(dz_a) + r
        a_aff = min(_max_step(z, dz_a), _max_step(w, dw_a))
        gap_aff = float((z + a_aff * dz_a) @ (w + a_aff * dw_a)) / n
        ratio = gap_aff / gap if gap > 0 else 0.0
        # Python floats: a ratio past 1 (or NaN) centres fully, and is never cubed (its cube
        # may overflow: OverflowError, where numpy would give inf)
        sigma = ratio ** 3 if ratio < 1.0 else 1.0
        rhs = (-z * w - dz_a * dw_a + sigma * gap) / z - r
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dz = K.solve(rhs)
        dw = matvec(dz) + r
        if not (np.all(np.isfinite(dz)) and np.all(np.isfinite(dw))):
            termination, why = NUMERICAL, "non-finite step"
            break
        alpha = min(1.0, STEP_FRACTION * min(_max_step(z, dz), _max_step(w, dw)))
        if alpha <= 1e-14:
            termination, why = NUMERICAL, "zero step length (stalled at the boundary)"
            break
        z = np.maximum(z + alpha * dz, 1e-300)
        w = np.maximum(w + alpha * dw, 1e-300)
    note = ", active-set rounding" if rounded else ""
    return Outcome(best_z, it, termination,
                   f"interior point: {why} after {plural(it, 'iteration')}{note} "
                   f"(certified error {best_err:.2e})")


METHODS = [
    Method(
        name="ip",
        preload=preload_linalg,
        run=run,
        summary="primal-dual interior point, Mehrotra predictor-corrector, with active-set "
                "rounding (dense or sparse)",
        guarantees=(Guarantee(when("psd"), "monotone LCP: converges when a solution exists"),),
        cost=Cost.FACTORING,
        preference=10,  # faster than newton on PSD problems (benchmarks/results/methods.json)
        fallback="no guarantee outside monotone problems",
        fallback_preference=40,  # after the Newton methods
        auto_max_iter=DEFAULT_MAX_ITER,
        kinds=("lcp",),
        sparse=True,
        options={
            "max_iter": Option(positive_int, None,
                               f"iteration limit (default {DEFAULT_MAX_ITER})"),
        },
        aliases=("interior-point",),
        scaling="auto",
    ),
]
