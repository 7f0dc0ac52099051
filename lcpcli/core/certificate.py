"""The certificate of a candidate solution: the project's one definition of residual and error.

Every solver's answer goes through :func:`certify`; nothing is called ``solved`` otherwise.

Definitions (``w = M z + q``, box ``[l, u]`` from :meth:`Problem.bounds`; LCP: ``[0, inf)``):

* natural residual ``r = mid(z - l, z - u, w) = max(z - u, min(z - l, w))``, which is
  ``min(z, w)`` for the LCP, ``w`` for a free (equality) row and the box ``mid`` function otherwise;
* ``residual = ||r||_inf``  (for the LCP: ``||min(z, w)||_inf``);
* ``error`` is the same residual measured in the units of ``w`` and relative to the size of the
  terms that make up ``w``::

      mu    = ||M||_inf                       (max absolute row sum; 1 if M = 0)
      r~    = max(mu (z - u), min(mu (z - l), w))
      error = ||r~||_inf / (mu ||z||_inf + ||q||_inf)      (0 when z = 0 and q = 0)

  It is invariant under scaling (M, q) -> (a M, a q) and (q, z) -> (b q, b z), it is a
  normwise backward error in the sense of linear algebra (rounding in ``M z + q`` alone gives
  about ``n * eps``), and it does not blow up when ``q`` is near zero, unlike
  ``||min(z, w)|| / ||q||``: a tiny ``q`` with a solution of matching size scores small.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

#: Default tolerance on :attr:`Certificate.error` for the verdict ``solved``.
DEFAULT_TOL = 1e-8


@dataclass(frozen=True)
class Certificate:
    """Residuals of a candidate solution (see the module docstring for the definitions)."""

    residual: float
    error: float
    bound_violation: float
    w_violation: float
    complementarity: float
    equality_residual: float
    tol: float
    passed: bool

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def matrix_norm_inf(M: Any) -> float:
    """``||M||_inf`` (max absolute row sum) for a dense array or a scipy.sparse matrix."""
    if hasattr(M, "tocsr"):
        if M.nnz == 0:
            return 0.0
        return float(np.max(np.asarray(abs(M).sum(axis=1)).ravel()))
    return float(np.max(np.sum(np.abs(M), axis=1))) if M.size else 0.0


def certify(problem: Any, z: np.ndarray, tol: float = DEFAULT_TOL, *,
            w: np.ndarray | None = None, norm_M: float | None = None) -> Certificate:
    """Check ``z`` against ``problem`` (w is recomputed from M and q unless given).

    ``passed`` is true when everything is finite and ``error <= tol``.
    """
    z = np.asarray(z, dtype=np.float64)
    if w is None and np.all(np.isfinite(z)):
        w = problem.w(z)
    lo, up = problem.bounds()
    if w is None or not (np.all(np.isfinite(z)) and np.all(np.isfinite(w))):
        inf = float("inf")
        return Certificate(inf, inf, inf, inf, inf, inf, tol, False)
    mu = matrix_norm_inf(problem.M) if norm_M is None else norm_M
    mu = mu if mu > 0 else 1.0
    with np.errstate(invalid="ignore"):
        r = np.maximum(z - up, np.minimum(z - lo, w))
        r_scaled = np.maximum(mu * (z - up), np.minimum(mu * (z - lo), w))
    residual = _norm(r)
    denom = mu * _norm(z) + _norm(problem.q)
    err_num = _norm(r_scaled)
    error = 0.0 if err_num == 0.0 else (err_num / denom if denom > 0 else float("inf"))

    bound_violation = _norm(np.maximum(np.maximum(lo - z, z - up), 0.0))
    lo_fin, up_fin = np.isfinite(lo), np.isfinite(up)
    lower_only = lo_fin & ~up_fin
    upper_only = ~lo_fin & up_fin
    free = ~lo_fin & ~up_fin
    both = lo_fin & up_fin
    w_violation = max(_norm(np.maximum(-w[lower_only], 0.0)),
                      _norm(np.maximum(w[upper_only], 0.0)))
    complementarity = max(
        _norm((z - lo)[lower_only] * w[lower_only]),
        _norm((up - z)[upper_only] * w[upper_only]),
        _norm(np.minimum(np.abs(z - lo), np.abs(up - z))[both] * w[both]),
    )
    equality_residual = _norm(w[free])
    passed = bool(error <= tol)
    return Certificate(residual, float(error), bound_violation, w_violation, complementarity,
                       equality_residual, tol, passed)


def _norm(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if x.size else 0.0
