"""Semismooth Newton methods: ``newton`` (Fischer-Burmeister) and ``newton-min`` (min / mid map).

Problem: ``w = M z + q``, ``z`` in the box ``[l, u]`` of :meth:`Problem.bounds` (LCP ``[0, inf)``;
MLCP: free variables ``(-inf, inf)`` whose rows are plain equations ``w_i = 0``; box LCP: the
given bounds, sign convention ``w >= 0`` at ``l``, ``w <= 0`` at ``u``, ``w = 0`` between).

The problem is written as ``Phi(z) = 0`` componentwise and solved by Newton's method with the
generalized (B-/Clarke) Jacobian ``H = diag(a) + diag(b) M``:

* ``newton``: ``psi(s, t) = s + t - sqrt(s^2 + t^2)`` (minus the Fischer-Burmeister function,
  zero iff ``s, t >= 0, s t = 0``); lower bound only ``Phi = psi(z - l, w)``; upper bound only
  ``Phi = -psi(u - z, -w)``; both bounds ``Phi = -psi(u - z, -psi(z - l, w))`` (Billups'
  composition); free ``Phi = w``.
* ``newton-min``: ``Phi = max(z - u, min(z - l, w))`` = ``z - mid(l, u, z - w)``, the natural
  residual of the certificate.

Globalisation: Armijo backtracking on the merit ``Psi = ||Phi||^2 / 2`` (a full Newton step is
accepted against the largest of the last 5 merits, Grippo-Lampariello-Lucidi's non-monotone
rule; shortened steps must decrease the current merit); when the Newton system
is singular or its solution is not a sufficient descent direction, a Levenberg-Marquardt step
``(H^T H + lam I) d = -H^T Phi`` (``lam`` proportional to ``||Phi||``) is tried, and failing that a
step along ``-grad Psi = -H^T Phi`` (De Luca, Facchinei and Kanzow's scheme).  Sparse M: the Newton
systems are solved by sparse LU (``scipy.sparse.linalg.splu``), never densified.  Shortened
steps follow the quadratic model of the merit (:func:`_backtrack`).  The iteration stops with
termination ``stalled`` when the best merit fell by less than ``STALL_DECREASE`` (relative) over
the last ``STALL_WINDOW`` iterations.  After the iterations an active-set re-solve is tried
(see :func:`lcpcli.solvers.support.refine`).

Matrix classes: ``newton`` converges globally (to a stationary point of the merit, which solves
the problem) for P0 matrices with bounded level sets, e.g. **P-matrices**, and for **monotone
(PSD) problems** with a solution under mild conditions; locally quadratically at nondegenerate
regular solutions; it handles non-symmetric and zero-diagonal matrices, MLCP free rows and box
bounds.  ``newton-min`` is locally fast but not globally convergent (the min merit is not
smooth): it can stall on degenerate or singular problems.  Neither ever claims success: the
answer is certified by the shared certificate and is ``unsolved`` otherwise.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from lcpcli.core.certificate import matrix_norm_inf
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, NUMERICAL, STALLED, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.options import positive_int, vector_option
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import (
    StallWatch,
    certified_error,
    preload_linalg,
    refine,
    sparse_lu,
    start_point,
)

DEFAULT_MAX_ITER = 200
#: Stagnation: stop (termination ``stalled``) when the best merit fell by less than
#: STALL_DECREASE (relative) over the last STALL_WINDOW iterations.
STALL_WINDOW, STALL_DECREASE = 30, 1e-3
#: Armijo constant, backtracking factor, smallest step.
SIGMA, BETA, MIN_STEP = 1e-4, 0.5, 1e-12
#: Descent test for the Newton direction: grad . d <= -RHO ||d||^P.
RHO, P_EXP = 1e-10, 2.1
#: Length of the merit history of the non-monotone test (full steps only; 1 = monotone Armijo).
NONMONOTONE = 5
#: Value of psi's partial derivatives at the kink (0, 0) (an element of the generalized Jacobian).
KINK = 1.0 - 1.0 / np.sqrt(2.0)


def _psi_value(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``psi(s, t)`` alone (the line search needs no partials); see :func:`_psi`."""
    ssum = s + t
    return np.where(ssum > 0, 2.0 * s * t / (ssum + np.hypot(s, t)), ssum - np.hypot(s, t))


def _psi(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``psi(s, t) = s + t - sqrt(s^2 + t^2)`` and its partials (stable form, kink-safe).

    Callers run it under ``np.errstate(all="ignore")`` (one context for the whole iteration:
    a context per call cost more than the arithmetic at small n)."""
    r = np.hypot(s, t)
    val = _psi_value(s, t)
    kink = r == 0
    safe = r + kink  # 1 at the kink, where the partials are KINK
    ds = np.where(kink, KINK, 1.0 - s / safe)
    dt = np.where(kink, KINK, 1.0 - t / safe)
    return val, ds, dt


class _Residual:
    """The componentwise map ``Phi(z, w)`` and the diagonals ``a = dPhi/dz``, ``b = dPhi/dw``."""

    def __init__(self, problem: Any, variant: str) -> None:
        lo, up = problem.bounds()
        self.lo, self.up = lo, up
        self.variant = variant
        lf, uf = np.isfinite(lo), np.isfinite(up)
        self.lower = np.flatnonzero(lf & ~uf)
        self.upper = np.flatnonzero(~lf & uf)
        self.both = np.flatnonzero(lf & uf)
        self.free = np.flatnonzero(~lf & ~uf)
        # a plain LCP (every z_i >= 0, no upper bound): Phi = psi(z, w) in one call
        self.plain = self.lower.size == lo.shape[0] and not np.any(lo)

    def value(self, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``Phi(z, w)`` alone (what the line search needs)."""
        if self.plain and self.variant != "min":
            return _psi_value(z, w)
        return self(z, w)[0]

    def __call__(self, z: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.plain and self.variant != "min":
            return _psi(z, w)
        n = z.shape[0]
        phi, a, b = np.empty(n), np.zeros(n), np.zeros(n)
        lo, up = self.lo, self.up
        if self.variant == "min":
            s = z - lo
            low = s <= w
            v = np.where(low, s, w)
            hi = (z - up) >= v
            phi[:] = np.where(hi, z - up, v)
            zpart = hi | low
            a[:] = np.where(zpart, 1.0, 0.0)
            b[:] = np.where(zpart, 0.0, 1.0)
            fr = self.free
            phi[fr], a[fr], b[fr] = w[fr], 0.0, 1.0
            return phi, a, b
        i = self.lower
        if i.size:
            phi[i], a[i], b[i] = _psi(z[i] - lo[i], w[i])
        i = self.upper
        if i.size:
            v, ds, dt = _psi(up[i] - z[i], -w[i])
            phi[i], a[i], b[i] = -v, ds, dt
        i = self.both
        if i.size:
            g, gs, gt = _psi(z[i] - lo[i], w[i])
            v, ds, dt = _psi(up[i] - z[i], -g)
            phi[i], a[i], b[i] = -v, ds + dt * gs, dt * gt
        i = self.free
        if i.size:
            phi[i], a[i], b[i] = w[i], 0.0, 1.0
        return phi, a, b


def _newton_direction(M: Any, sparse: bool, a: np.ndarray, b: np.ndarray,
                      phi: np.ndarray) -> np.ndarray | None:
    """Solve ``(diag(a) + diag(b) M) d = -phi``; None when the matrix is (numerically) singular."""
    n = phi.shape[0]
    if sparse:
        import scipy.sparse as sp  # scipy is imported on first use (start-up budget)

        lu = sparse_lu(sp.diags(b) @ M + sp.diags(a))
        if lu is None:
            return None
        d = lu.solve(-phi)
    else:
        from scipy.linalg.lapack import dgesv  # LAPACK directly: one call, no wrappers

        H = b[:, None] * M
        H[np.diag_indices(n)] += a
        if not np.all(np.isfinite(H)):
            return None
        lu, _, d, info = dgesv(H, -phi, overwrite_a=True, overwrite_b=True)
        piv = np.abs(lu.diagonal())
        if info != 0 or piv.min() <= 1e-15 * max(float(np.abs(lu).max()), 1e-300):
            return None
    return d if np.all(np.isfinite(d)) else None


def _lm_direction(M: Any, sparse: bool, a: np.ndarray, b: np.ndarray, phi: np.ndarray,
                  grad: np.ndarray, lam: float) -> np.ndarray | None:
    """Levenberg-Marquardt direction ``(H^T H + lam I) d = -H^T phi`` (singular H, e.g. a
    rank-deficient PSD M at a degenerate point); None if it fails."""
    n = phi.shape[0]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if sparse:
                import scipy.sparse as sp  # scipy is imported on first use (start-up budget)
                import scipy.sparse.linalg as spla

                H = (sp.diags(b) @ M + sp.diags(a)).tocsr()
                K = (H.T @ H + lam * sp.identity(n)).tocsc()
                d = spla.splu(K).solve(-grad)
            else:
                from scipy.linalg.lapack import dposv  # LAPACK directly: one call

                H = b[:, None] * M
                H[np.diag_indices(n)] += a
                K = H.T @ H
                K[np.diag_indices(n)] += lam
                _, d, info = dposv(K, -grad)
                if info != 0:
                    return None
    except (np.linalg.LinAlgError, ValueError, RuntimeError):
        return None
    return d if np.all(np.isfinite(d)) else None


def run_newton(problem: Any, *, tol: float, variant: str = "fb", max_iter: int | None = None,
               z0: np.ndarray | None = None) -> Outcome:
    """Semismooth Newton with Armijo line search; ``variant`` is ``"fb"`` or ``"min"``."""
    with np.errstate(all="ignore"):
        return _run_newton(problem, tol, variant, max_iter, z0)


def _descent(d: np.ndarray) -> float:
    """``RHO ||d||^P_EXP``, the descent a direction must promise; Inf where that overflows
    (a direction of size 1e300 on extreme data: a float power raised OverflowError)."""
    return float(RHO * np.power(np.float64(np.linalg.norm(d)), P_EXP))


def _run_newton(problem: Any, tol: float, variant: str, max_iter: int | None,
                z0: np.ndarray | None) -> Outcome:
    name = "Newton-FB" if variant == "fb" else "Newton-min"
    M = problem.M
    sparse = problem.sparse
    if sparse:
        M = M.tocsr()
    lo, up = problem.bounds()
    z = start_point(problem, z0)
    if z0 is not None:
        z = np.clip(z, lo, up)
    resid = _Residual(problem, "min" if variant == "min" else "fb")
    mu = matrix_norm_inf(M)
    mu = mu if mu > 0 else 1.0
    limit = max_iter or DEFAULT_MAX_ITER

    def matvec(x: np.ndarray) -> np.ndarray:
        return np.asarray(M @ x).ravel()

    def rmatvec(x: np.ndarray) -> np.ndarray:
        return np.asarray(M.T @ x).ravel()

    w = matvec(z) + problem.q
    phi, a, b = resid(z, w)
    merit = 0.5 * float(phi @ phi)
    history = [merit]
    watch = StallWatch(STALL_WINDOW, STALL_DECREASE, first=merit)
    grad_steps = 0
    lm_steps = 0
    it = 0
    termination, why = ITERATION_LIMIT, f"iteration limit {limit} reached"
    best_z, best_err = z.copy(), certified_error(problem, z)
    err = best_err
    while True:
        if err <= tol:
            termination, why = CONVERGED, "certified error below tolerance"
            break
        if it >= limit:
            break
        it += 1
        grad = a * phi + rmatvec(b * phi)
        d = _newton_direction(M, sparse, a, b, phi)
        slope = float(grad @ d) if d is not None else 0.0
        if d is None or slope > -_descent(d):
            # mu^2 saturates below the largest double (||M|| near 1e300: OverflowError)
            lam = min(1.0, float(np.sqrt(2.0 * merit))) * min(max(1.0, mu), 1e150) ** 2 * 1e-3
            d = _lm_direction(M, sparse, a, b, phi, grad, max(lam, 1e-14))
            slope = float(grad @ d) if d is not None else 0.0
            if d is not None and slope < -_descent(d):
                lm_steps += 1
            else:
                d = None
        if d is None:
            d = -grad
            slope = -float(grad @ grad)
            grad_steps += 1
            if slope == 0.0:
                termination = NUMERICAL
                why = "stationary point of the merit function that is not a solution"
                break
        dw = matvec(d)
        t = 1.0
        while True:
            zt = z + t * d
            wt = w + t * dw
            phit = resid.value(zt, wt)
            merit_t = 0.5 * float(phit @ phit)
            ref = max(history) if t == 1.0 else merit  # non-monotone test for the full step
            if merit_t <= ref + SIGMA * t * slope:  # False for NaN
                break
            t = _backtrack(t, merit, slope, merit_t)
            if t < MIN_STEP:
                break
        if t < MIN_STEP:
            termination, why = NUMERICAL, "line search failed (no decrease of the merit function)"
            break
        z = zt
        w = matvec(z) + problem.q  # fresh product: no drift from the w + t dw updates
        phi, a, b = resid(z, w)
        merit = 0.5 * float(phi @ phi)
        history.append(merit)
        del history[:-NONMONOTONE]
        if merit < watch.best[-1] or it % STALL_WINDOW == 0:  # a certificate costs ~ an iteration
            err = certified_error(problem, z)
            if err < best_err:
                best_z, best_err = z.copy(), err
        if watch.update(merit):
            termination = STALLED
            why = (f"no progress: the merit function fell by less than {STALL_DECREASE:g} "
                   f"(relative) over the last {STALL_WINDOW} iterations")
            break
    z_out, err_out = best_z, best_err
    if termination != CONVERGED:
        err = certified_error(problem, z)
        if err < err_out:
            z_out, err_out = z, err
    if err_out > 0:
        polished = refine(problem, z_out)
        if polished is not None and polished[1] < err_out:
            z_out, err_out = polished
            if err_out <= tol and termination != CONVERGED:
                why += "; solved by the active-set re-solve"
                termination = CONVERGED
    extra = f", {lm_steps} Levenberg-Marquardt steps" if lm_steps else ""
    extra += f", {grad_steps} gradient steps" if grad_steps else ""
    return Outcome(z_out, it, termination,
                   f"{name}: {why} after {plural(it, 'iteration')}{extra} "
                   f"(certified error {err_out:.2e})",
                   info={"gradient_steps": grad_steps, "lm_steps": lm_steps})


def _backtrack(t: float, merit: float, slope: float, merit_t: float) -> float:
    """The next trial step after ``t`` failed the Armijo test: the minimiser of the quadratic
    through ``merit``, ``slope`` and ``merit_t``, kept in ``[t/10, t/2]`` (``BETA t`` when the
    model gives nothing; Dennis and Schnabel, 6.3.2)."""
    denom = 2.0 * (merit_t - merit - slope * t)
    if not (denom > 0 and np.isfinite(denom)):
        return BETA * t
    return min(BETA * t, max(0.1 * t, -slope * t * t / denom))


def run_fb(problem: Any, *, tol: float, max_iter: int | None = None,
           z0: np.ndarray | None = None) -> Outcome:
    """Newton on the Fischer-Burmeister function (``newton``)."""
    return run_newton(problem, tol=tol, variant="fb", max_iter=max_iter, z0=z0)


def run_min(problem: Any, *, tol: float, max_iter: int | None = None,
            z0: np.ndarray | None = None) -> Outcome:
    """Newton on the min / mid map (``newton-min``)."""
    return run_newton(problem, tol=tol, variant="min", max_iter=max_iter, z0=z0)


_OPTIONS = {
    "max_iter": Option(positive_int, None, f"Newton iteration limit (default {DEFAULT_MAX_ITER})"),
    "z0": Option(vector_option, None, "warm start z (default 0)"),
}

METHODS = [
    Method(
        name="newton",
        preload=preload_linalg,
        run=run_fb,
        summary="semismooth Newton on the Fischer-Burmeister function, Armijo line search "
                "(dense LU or sparse LU)",
        guarantees=(
            Guarantee(when("p_matrix"), "globally convergent (FB merit): the unique solution"),
            Guarantee(when("psd"), "monotone: globally convergent when a solution exists"),
        ),
        notes="non-symmetric, zero diagonal, MLCP free rows and box bounds handled",
        cost=Cost.FACTORING,
        preference=20,
        fallback="semismooth Newton handles any square M (may stop at a stationary point)",
        auto_max_iter=100,
        kinds=("lcp", "mlcp", "box"),
        sparse=True,
        options=dict(_OPTIONS),
        aliases=("newton-fb",),
        scaling="auto",
    ),
    Method(
        name="newton-min",
        preload=preload_linalg,
        run=run_min,
        summary="semismooth Newton on the min / mid map (natural residual), Armijo line search",
        notes="locally fast near a solution; not globally convergent: may stall on "
              "degenerate or singular problems",
        cost=Cost.FACTORING,
        preference=30,
        fallback="min-map Newton, locally fast",
        auto_max_iter=50,
        kinds=("lcp", "mlcp", "box"),
        sparse=True,
        options=dict(_OPTIONS),
        scaling="auto",
    ),
]
