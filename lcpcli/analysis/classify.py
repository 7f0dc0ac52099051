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


def is_symmetric(M, tol: float = CLASS_TOL) -> bool:  # type: ignore[no-untyped-def]
    """``||M - M^T||_max <= tol * ||M||_max`` (dense or scipy.sparse M)."""
    if hasattr(M, "tocsr"):
        if M.nnz == 0:
            return True
        D = (M - M.T).tocsr()
        scale = float(abs(M).max())
        return bool(D.nnz == 0 or float(abs(D).max()) <= tol * max(scale, 1e-300))
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


# ---------------------------------------------------------------------- class report (auto, info)
#: Dense sizes up to which the eigenvalues of the symmetric part are computed (else Cholesky).
EIG_MAX_N = 300
#: Dense sizes up to which the O(n^3) tests (definiteness, H-matrix) are run at all.
DENSE_TEST_MAX_N = 6000
#: Sparse sizes up to which the sparse-LU tests are run.
SPARSE_TEST_MAX_N = 300_000
#: Sizes up to which the P-matrix property is decided exactly (all 2^n principal minors).
EXACT_P_MAX_N = 10


def _sym_part_any(M):  # type: ignore[no-untyped-def]
    return (M + M.T) * 0.5


#: Fill of the last sparse factorisation in :func:`definiteness` (nnz(L + U) / nnz(S)).
_LAST_FILL: list[float] = []


def _sparse_definite(S, shift: float) -> bool | None:  # type: ignore[no-untyped-def]
    """Is the symmetric sparse ``S + shift I`` positive definite?  (LU without pivoting in a
    symmetric fill-reducing order: all pivots positive iff PD.)  None if the test failed.
    The fill ratio of the factorisation is recorded (it predicts the cost of sparse LU in the
    Newton and interior-point methods)."""
    import warnings

    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    n = S.shape[0]
    K = (S + shift * sp.identity(n, format="csr")).tocsc()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lu = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular pivot
        return False
    except MemoryError:
        return None
    _LAST_FILL.append((lu.L.nnz + lu.U.nnz) / max(K.nnz, 1))
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    d = lu.U.diagonal()
    return bool(np.all(d > 0))


def definiteness(M) -> tuple[str | None, float | None, str]:  # type: ignore[no-untyped-def]
    """``("pd" | "psd" | "indefinite" | None, min eigenvalue or None, how)`` of the symmetric part.

    Dense n <= EIG_MAX_N: eigenvalues; larger: Cholesky of ``S`` and of ``S + delta I`` with
    ``delta = 1e-10 sqrt(n) ||S||`` (numerically PSD); sparse: the same with sparse LU.
    ``None`` when the problem is too large to test.
    """
    n = M.shape[0]
    if n == 0:
        return "pd", None, "empty"
    if hasattr(M, "tocsr"):
        if n > SPARSE_TEST_MAX_N:
            return None, None, f"not tested (n > {SPARSE_TEST_MAX_N})"
        S = _sym_part_any(M.tocsr()).tocsr()
        norm = float(abs(S).sum(axis=1).max()) if S.nnz else 0.0
        if norm == 0:
            return "psd", 0.0, "zero matrix"
        delta = 1e-10 * np.sqrt(n) * norm
        pd = _sparse_definite(S, -delta)
        if pd:
            return "pd", None, "sparse LDL^T-type factorisation of S - delta I"
        psd = _sparse_definite(S, delta)
        if psd is None or pd is None:
            return None, None, "sparse factorisation needed pivoting (inconclusive)"
        return ("psd" if psd else "indefinite"), None, "sparse factorisation of S + delta I"
    if n <= EIG_MAX_N:
        lo, big = min_eig_sym(M)
        margin = 1e-10 * max(big, 1e-300) * max(1, n) ** 0.5
        kind = "pd" if lo > margin else ("psd" if lo >= -margin else "indefinite")
        return kind, lo, "eigenvalues of (M + M^T)/2"
    if n > DENSE_TEST_MAX_N:
        return None, None, f"not tested (n > {DENSE_TEST_MAX_N})"
    import scipy.linalg as sla

    S = symmetric_part(M)
    norm = float(np.max(np.sum(np.abs(S), axis=1)))
    if norm == 0:
        return "psd", 0.0, "zero matrix"
    delta = 1e-10 * np.sqrt(n) * norm
    for shift, kind in ((-delta, "pd"), (delta, "psd")):
        K = S.copy()
        K[np.diag_indices(n)] += shift
        try:
            sla.cholesky(K, check_finite=False)
            return kind, None, "Cholesky of (M + M^T)/2 -/+ delta I"
        except np.linalg.LinAlgError:
            continue
    return "indefinite", None, "Cholesky of (M + M^T)/2 + delta I failed"


def h_matrix_positive_diagonal(M) -> bool | None:  # type: ignore[no-untyped-def]
    """Is M an H-matrix with positive diagonal (a sufficient test for a P-matrix)?

    The comparison matrix ``C`` (``|m_ii|`` on the diagonal, ``-|m_ij|`` off it) is a Z-matrix;
    it is a nonsingular M-matrix iff some ``x > 0`` has ``C x > 0``; ``x = C^{-1} e`` is tried.
    None when too large to test.
    """
    n = M.shape[0]
    d = np.asarray(M.diagonal()).ravel()
    if n == 0:
        return True
    if np.any(d <= 0):
        return False
    if hasattr(M, "tocsr"):
        if n > SPARSE_TEST_MAX_N:
            return None
        import warnings

        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        A = abs(M.tocsr())
        C = (sp.diags(2 * d) - A).tocsc()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = spla.splu(C).solve(np.ones(n))
        except RuntimeError:
            return False
        Cx = C @ x
    else:
        if n > DENSE_TEST_MAX_N:
            return None
        A = np.abs(M)
        # strictly diagonally dominant rows: the common case, no solve needed
        if np.all(2 * d > A.sum(axis=1)):
            return True
        C = -A
        C[np.diag_indices(n)] = d
        try:
            x = np.linalg.solve(C, np.ones(n))
        except np.linalg.LinAlgError:
            return False
        Cx = C @ x
    return bool(np.all(np.isfinite(x)) and np.all(x > 0) and np.all(Cx > 1e-12))


def is_p_matrix_exact(M: np.ndarray) -> bool:
    """All 2^n - 1 principal minors positive (only for n <= EXACT_P_MAX_N)."""
    import itertools

    n = M.shape[0]
    scale = max(float(np.max(np.abs(M))), 1e-300) if M.size else 1.0
    for k in range(1, n + 1):
        for idx in itertools.combinations(range(n), k):
            if np.linalg.det(M[np.ix_(idx, idx)]) <= 1e-12 * scale**k:
                return False
    return True


def classify(problem, thorough: bool = True) -> dict:  # type: ignore[no-untyped-def]
    """A cheap class report of ``problem.M`` (keys documented in docs/methods.md).

    Every test is a sufficient one unless said otherwise; ``None`` means "not tested"
    (too large, or with ``thorough=False`` not needed: the H-matrix test is skipped when M is
    already known PD) and ``p_matrix_reason`` / ``definiteness_test`` say how each was decided.
    """
    M = problem.M
    n = problem.n
    sparse = problem.sparse
    d = np.asarray(M.diagonal(), dtype=float).ravel()
    out: dict = {
        "kind": problem.kind,
        "n": n,
        "n_eq": problem.n_eq,
        "sparse": sparse,
        "nnz": int(M.nnz) if sparse else int(np.count_nonzero(M)),
    }
    out["density"] = out["nnz"] / max(n * n, 1)
    out["q_nonnegative"] = bool(n == 0 or np.min(problem.q) >= 0)
    out["symmetric"] = is_symmetric(M)
    out["diagonal_min"] = float(np.min(d)) if n else 0.0
    out["zero_diagonal"] = int(np.sum(d == 0))
    out["positive_diagonal"] = bool(n == 0 or np.min(d) > 0)
    if sparse:
        off = M.tocoo()
        mask = off.row != off.col
        offvals = off.data[mask]
        absrow = np.asarray(abs(M).sum(axis=1)).ravel()
        out["nonnegative"] = bool(np.all(off.data >= 0))
    else:
        offvals = M[~np.eye(n, dtype=bool)]
        absrow = np.sum(np.abs(M), axis=1)
        out["nonnegative"] = bool(np.all(M >= 0))
    out["z_matrix"] = bool(np.all(offvals <= 0))
    out["diagonally_dominant"] = bool(n == 0 or (out["positive_diagonal"]
                                                 and np.all(2 * d > absrow)))
    _LAST_FILL.clear()
    kind, lam, how = definiteness(M)
    out["factor_fill"] = float(_LAST_FILL[-1]) if (sparse and _LAST_FILL) else None
    if out["diagonally_dominant"]:
        out["h_matrix_positive_diagonal"] = True
    elif not out["positive_diagonal"]:
        out["h_matrix_positive_diagonal"] = False
    elif not thorough and kind == "pd":
        out["h_matrix_positive_diagonal"] = None
    else:
        out["h_matrix_positive_diagonal"] = h_matrix_positive_diagonal(M)
    out["definiteness"] = kind
    out["min_eig_sym"] = lam
    out["definiteness_test"] = how
    out["psd"] = None if kind is None else kind in ("pd", "psd")
    out["pd"] = None if kind is None else kind == "pd"
    # P-matrix: sufficient tests first, exact test for tiny n, necessary test (diagonal > 0)
    if kind == "pd":
        p, why = True, "positive definite (symmetric part PD)"
    elif out["h_matrix_positive_diagonal"]:
        p, why = True, ("strictly diagonally dominant with positive diagonal"
                        if out["diagonally_dominant"] else "H-matrix with positive diagonal")
    elif not out["positive_diagonal"]:
        p, why = False, "a diagonal entry (a 1 x 1 principal minor) is <= 0"
    elif n <= EXACT_P_MAX_N and (thorough or not out["psd"]):
        p = is_p_matrix_exact(problem.dense_M())
        why = "all principal minors checked" + ("" if p else ": one is <= 0")
    else:
        p, why = None, "unknown (no sufficient test applies)"
    out["p_matrix"] = p
    out["p_matrix_reason"] = why
    out["copositive_plus"] = True if out["psd"] else None
    return out
