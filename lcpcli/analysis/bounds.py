"""Forward error bounds: how far a certified answer can be from the exact solution.

Conventions: LCP(q, M) with ``w = M z + q``; ``r(z) = min(z, M z + q)`` is the natural residual,
``z*`` the exact solution (unique when M is a P-matrix).  The certificate bounds the *backward*
error; when the matrix is proven to be a P-matrix of one of the classes below, this module turns
the residual into a bound on ``||z - z*||_inf``, computed in double precision (an estimate of the
bound, not an interval-verified enclosure).  The rounding of ``w`` itself is accounted for by
adding ``(n + 1) eps ||(|M| |z| + |q|)||`` to ``||r||``.

* **H-matrix with positive diagonal** (e.g. strictly diagonally dominant): Chen and Xiang
  (Math. Program. 106, 2006) show ``||z - z*||_inf <= max_{d in [0,1]^n} ||(I - D + DM)^-1||_inf
  ||r(z)||_inf`` for any P-matrix, and for this class ``max_d ||(I - D + DM)^-1||_inf <=
  ||C^-1 max(Lambda, I)||_inf`` with ``C`` the comparison matrix (``|m_ii|`` on the diagonal,
  ``-|m_ij|`` off it) and ``Lambda = diag(m_ii)``.  ``C^-1 >= 0``, so the norm is
  ``max(C^-1 v)`` with ``v_i = max(m_ii, 1)``: one linear solve, which also proves the class
  (``x = C^-1 v > 0`` and ``C x > 0`` make ``C`` a nonsingular M-matrix).  Exact for diagonal M.
* **Positive definite** (``x^T M x >= lambda ||x||^2``, ``lambda`` the smallest eigenvalue of
  ``(M + M^T)/2``): with ``u = z - r``, the pair ``(u, w - r)`` is complementary and nonnegative,
  so ``u`` solves LCP(``q + (M - I) r``, M) exactly; for two solutions of a monotone LCP with
  data ``q`` and ``q'``, ``(u - z*)^T M (u - z*) <= -(u - z*)^T (q' - q)``, hence
  ``||u - z*||_2 <= ||(M - I) r||_2 / lambda`` and
  ``||z - z*||_inf <= ||z - z*||_2 <= (1 + ||M - I||_2 / lambda) ||r||_2``
  (``||M - I||_2 <= sqrt(||M - I||_1 ||M - I||_inf)`` is used).

Dense problems up to :data:`MAX_N` only (the bounds cost O(n^3)); None otherwise, and for
matrices in neither class.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: Largest n for which a bound is computed (an O(n^3) solve or eigenvalue problem).
MAX_N = 2000
#: Data whose largest entry lies outside [2^-RANGE, 2^RANGE] is scaled by a power of two first.
RANGE = 400
EPS = np.finfo(np.float64).eps


@dataclass(frozen=True)
class ForwardBound:
    """``||z - z*||_inf <= bound``; ``relative = bound / ||z||_inf``; ``how`` names the theorem."""

    bound: float
    relative: float
    how: str

    def as_dict(self) -> dict[str, Any]:
        return {"bound": self.bound, "relative": self.relative, "how": self.how}


def forward_error_bound(problem: Any, z: np.ndarray) -> ForwardBound | None:
    """A bound on ``||z - z*||_inf`` for an LCP whose M is proven to be a P-matrix (see the
    module docstring); None when no class applies or the problem is too large."""
    if problem.kind != "lcp" or problem.n == 0 or problem.n > MAX_N:
        return None
    z = np.asarray(z, dtype=np.float64)
    if not np.all(np.isfinite(z)):
        return None
    M, q = _in_range(problem.dense_M(), problem.q)
    n = problem.n
    with np.errstate(over="ignore", invalid="ignore"):
        w = M @ z + q
        r = np.minimum(z, w)
        slack = (n + 1) * EPS * float(np.max(np.abs(M) @ np.abs(z) + np.abs(q)))
        if not (np.all(np.isfinite(r)) and np.isfinite(slack)):
            return None
        r_inf = float(np.max(np.abs(r))) + slack
        r_2 = float(np.linalg.norm(r)) + np.sqrt(n) * slack  # inf past the range: no bound
    zn = float(np.max(np.abs(z)))
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return _bound(M, n, zn, r_inf, r_2)
    except np.linalg.LinAlgError:  # e.g. an eigenvalue iteration that did not converge
        return None


def _in_range(M: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(2^-e M, 2^-e q)`` with ``2^e`` near the largest entry when that entry lies outside
    ``[2^-RANGE, 2^RANGE]`` (else M and q themselves): LCP(2^-e q, 2^-e M) has the same
    solutions, so a bound for it bounds the same ``||z - z*||``, and ``M + M^T`` or ``|M| |z|``
    cannot overflow on it."""
    peak = max(float(np.max(np.abs(M))), float(np.max(np.abs(q))))
    if peak == 0.0 or 2.0 ** -RANGE <= peak <= 2.0 ** RANGE:
        return M, q
    e = int(np.frexp(peak)[1])
    return np.ldexp(M, -e), np.ldexp(q, -e)


def _bound(M: np.ndarray, n: int, zn: float, r_inf: float, r_2: float) -> ForwardBound | None:
    beta = _h_matrix_constant(M)
    if beta is not None:
        b = beta * r_inf
        return ForwardBound(b, b / zn if zn > 0 else np.inf,
                            "H-matrix with positive diagonal (Chen-Xiang)")
    lam = _pd_margin(M)
    if lam is not None:
        A = M - np.eye(n)
        norm2 = float(np.sqrt(np.max(np.sum(np.abs(A), axis=0)) *
                              np.max(np.sum(np.abs(A), axis=1))))
        b = (1.0 + norm2 / lam) * r_2
        return ForwardBound(b, b / zn if zn > 0 else np.inf,
                            "positive definite (monotone perturbation bound)")
    return None


def _h_matrix_constant(M: np.ndarray) -> float | None:
    """``||C^-1 max(Lambda, I)||_inf`` when M is an H-matrix with positive diagonal, else None."""
    d = np.diag(M)
    if np.any(d <= 0):
        return None
    C = -np.abs(M)
    np.fill_diagonal(C, d)
    v = np.maximum(d, 1.0)
    try:
        x = np.linalg.solve(C, v)
    except np.linalg.LinAlgError:
        return None
    if not (np.all(np.isfinite(x)) and np.all(x > 0)):
        return None
    Cx = C @ x
    if not np.all(Cx > 0.5 * v):  # x > 0 with C x > 0 proves C is a nonsingular M-matrix
        return None
    return float(np.max(x))


def _pd_margin(M: np.ndarray) -> float | None:
    """The smallest eigenvalue of ``(M + M^T)/2`` when it is safely positive, else None."""
    S = 0.5 * (M + M.T)
    lam = np.linalg.eigvalsh(S)
    scale = float(np.max(np.abs(lam))) if lam.size else 0.0
    lo = float(lam[0])
    if lo <= 1e3 * M.shape[0] * EPS * scale:  # not distinguishable from singular
        return None
    return lo
