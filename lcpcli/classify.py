"""Matrix-class tests and infeasibility proofs used by the solvers (pure functions).

Conventions: LCP(q, M) with ``w = M z + q``; tolerances are relative to the data's norms.
"""

from __future__ import annotations

import numpy as np

#: Relative tolerance of the class tests (eigenvalues, signs) against the matrix norm.
CLASS_TOL = 1e-12


def symmetric_part(M: np.ndarray) -> np.ndarray:
    """``(M + M^T) / 2``."""
    return 0.5 * (M + M.T)


def is_symmetric(M: np.ndarray, tol: float = CLASS_TOL) -> bool:
    """``||M - M^T||_max <= tol * ||M||_max``."""
    scale = float(np.max(np.abs(M))) if M.size else 0.0
    return bool(np.max(np.abs(M - M.T), initial=0.0) <= tol * max(scale, 1e-300))


def min_eig_sym(M: np.ndarray) -> tuple[float, float]:
    """(smallest eigenvalue of the symmetric part, largest absolute eigenvalue)."""
    ev = np.linalg.eigvalsh(symmetric_part(M))
    return float(ev[0]), float(np.max(np.abs(ev))) if ev.size else 0.0


def is_psd(M: np.ndarray, tol: float = 1e-10) -> bool:
    """Positive semidefinite in the LCP sense: ``x^T M x >= 0`` for all x (symmetric part)."""
    if M.size == 0:
        return True
    lo, big = min_eig_sym(M)
    return lo >= -tol * max(big, 1e-300) * max(1, M.shape[0]) ** 0.5


def farkas_certificate(M: np.ndarray, q: np.ndarray,
                       candidate: np.ndarray | None = None) -> np.ndarray | None:
    """A vector ``y >= 0`` with ``M^T y <= 0`` and ``q^T y < 0``, or None.

    Such a ``y`` proves that no ``z >= 0`` has ``M z + q >= 0`` (for any ``z >= 0``,
    ``y^T (M z + q) = (M^T y)^T z + q^T y < 0``), hence that the LCP has no solution.
    Tried: the given candidate (e.g. Lemke's ray direction) and each unit vector ``e_i``
    (a row with ``M_i <= 0`` and ``q_i < 0``).  Checked with roundoff-level tolerances.
    """
    n = q.shape[0]
    norm_m = float(np.max(np.abs(M))) if M.size else 0.0
    norm_q = float(np.max(np.abs(q))) if q.size else 0.0

    def ok(y: np.ndarray) -> bool:
        if not np.all(np.isfinite(y)) or np.any(y < 0) or not np.any(y > 0):
            return False
        y1 = float(np.sum(y))
        return bool(np.max(M.T @ y) <= 1e-12 * n * norm_m * y1
                    and q @ y < -1e-9 * norm_q * y1)

    if candidate is not None:
        y = np.where(np.abs(candidate) <= 1e-14 * np.max(np.abs(candidate), initial=0.0),
                     0.0, candidate)
        if ok(y):
            return y
    rows = np.flatnonzero((q < 0) & np.all(M <= 0, axis=1))
    if rows.size:
        y = np.zeros(n)
        y[rows[np.argmin(q[rows])]] = 1.0
        return y
    return None
