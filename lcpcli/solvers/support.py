"""Numerical helpers shared by the solver methods (not a method module: no ``METHODS``).

Conventions: ``w = M z + q``, the box ``[lo, up]`` from :meth:`Problem.bounds`.  The scaled error
computed here is the certificate's formula (:mod:`lcpcli.core.certificate`), evaluated cheaply
inside the iterations to decide when to stop; the verdict is always given by the shared
certificate.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from lcpcli.core.errors import OptionError


def start_point(problem: Any, z0: np.ndarray | None, default: float = 0.0) -> np.ndarray:
    """The warm start ``z0`` checked against ``problem`` (OptionError on a length mismatch)."""
    n = problem.n
    if z0 is None:
        return np.full(n, default)
    z = np.asarray(z0, dtype=np.float64).ravel()
    if z.shape[0] != n:
        raise OptionError(f"warm start z0 has length {z.shape[0]}, the problem has n = {n}")
    if not np.all(np.isfinite(z)):
        raise OptionError("warm start z0 contains NaN or Inf")
    return z.copy()


def scaled_error(z: np.ndarray, w: np.ndarray, lo: np.ndarray, up: np.ndarray, mu: float,
                 qnorm: float) -> float:
    """The certificate's scaled error of ``(z, w)`` (``mu = ||M||_inf``, ``qnorm = ||q||_inf``)."""
    mu = mu if mu > 0 else 1.0
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.maximum(mu * (z - up), np.minimum(mu * (z - lo), w))
    num = float(np.max(np.abs(r))) if r.size else 0.0
    if num == 0.0:
        return 0.0
    denom = mu * (float(np.max(np.abs(z))) if z.size else 0.0) + qnorm
    if not np.isfinite(num):
        return float("inf")
    return num / denom if denom > 0 else float("inf")


def diagonal(M: Any) -> np.ndarray:
    """The diagonal of a dense or scipy.sparse matrix, as a float array."""
    return np.asarray(M.diagonal(), dtype=np.float64).ravel()


def active_set_polish(problem: Any, z: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Guess the active set from ``(z, w)`` and re-solve the equations it implies.

    Each variable is put at a bound (``z_i = l_i`` where ``z_i - l_i <= w_i``, ``z_i = u_i`` where
    ``z_i - u_i >= w_i``) or declared basic (``w_i = 0``); free variables are always basic.  The
    basic block ``M_BB z_B = -(q_B + M_BN z_N)`` is solved (dense LU / sparse LU, least squares
    when singular) and the result clipped to the box.  Returns the candidate; the caller keeps it
    only if it scores better (this is the final rounding step of the interior-point and Newton
    methods).
    """
    lo, up = problem.bounds()
    if w is None:
        w = problem.w(z)
    with np.errstate(invalid="ignore"):
        at_lo = (z - lo) <= w
        at_up = (z - up) >= w
    at_up &= ~at_lo | (np.abs(z - up) < np.abs(z - lo))
    at_lo &= ~at_up
    basic = ~(at_lo | at_up)
    zc = np.where(at_lo, lo, np.where(at_up, up, z))
    zc = np.where(np.isfinite(zc), zc, z)
    B = np.flatnonzero(basic)
    if B.size == 0:
        return zc
    N = np.flatnonzero(~basic)
    M = problem.M
    if problem.sparse:
        import scipy.sparse.linalg as spla  # scipy is imported on first use (start-up budget)

        Mc = M.tocsc()
        MBB = Mc[B][:, B].tocsc()
        rhs = -problem.q[B]
        if N.size:
            rhs = rhs - np.asarray(Mc[B][:, N] @ zc[N]).ravel()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                lu = spla.splu(MBB)
                zb = lu.solve(rhs)
                zb = zb + lu.solve(rhs - MBB @ zb)
        except RuntimeError:  # singular
            zb = spla.lsqr(MBB, rhs, atol=1e-14, btol=1e-14, iter_lim=10 * B.size)[0]
    else:
        MBB = M[np.ix_(B, B)]
        rhs = -problem.q[B]
        if N.size:
            rhs = rhs - M[np.ix_(B, N)] @ zc[N]
        try:
            import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                lu = sla.lu_factor(MBB, check_finite=False)
            if np.min(np.abs(np.diag(lu[0]))) <= 1e-14 * max(np.max(np.abs(MBB)), 1e-300):
                raise np.linalg.LinAlgError("singular")
            zb = sla.lu_solve(lu, rhs, check_finite=False)
            zb = zb + sla.lu_solve(lu, rhs - MBB @ zb, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            zb = np.linalg.lstsq(MBB, rhs, rcond=None)[0]
    zc[B] = zb
    return np.clip(zc, lo, up)


def better(problem: Any, candidates: list[np.ndarray], mu: float) -> tuple[np.ndarray, float]:
    """The candidate with the smallest scaled error, and that error."""
    lo, up = problem.bounds()
    qn = float(np.max(np.abs(problem.q))) if problem.n else 0.0
    best, best_err = candidates[0], float("inf")
    for z in candidates:
        if not np.all(np.isfinite(z)):
            continue
        e = scaled_error(z, problem.w(z), lo, up, mu, qn)
        if e < best_err:
            best, best_err = z, e
    return best, best_err

