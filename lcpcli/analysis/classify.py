"""Matrix-class tests, the class report and infeasibility proofs used by the solvers.

Conventions: LCP(q, M) with ``w = M z + q``; 0-based indices.  Every test is scale-aware: it
gives the same answer on ``2^k M`` for any k in [-1000, 1000] (magnitudes are taken on a copy
scaled by a power of two, which is exact), and the properties that a positive diagonal scaling
preserves are tested on a canonical scaling, so that

* positive diagonal, Z-matrix, H-matrix with positive diagonal and P-matrix give the same answer
  on ``D1 M D2`` (any positive diagonal D1, D2);
* symmetry and definiteness of ``(M + M^T)/2`` give the same answer on ``D M D``.

Tolerances are relative to the entries they compare (see each test), never absolute.

The class report (:class:`ClassReport`) is filled on demand by a :class:`Classifier`: the O(n)
and O(n^2) tests first (diagonal signs, symmetry, sign pattern, diagonal dominance, density),
the O(n^3) ones (a Cholesky attempt for definiteness, the H-matrix solve, P-matrix tests) only
when asked for.  ``None`` in the report means "not tested" or, after testing, "undecided".
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from dataclasses import dataclass, fields
from fractions import Fraction
from itertools import chain, combinations, islice
from operator import attrgetter
from typing import Any

import numpy as np

from lcpcli.analysis._scaling import dense_minima, is_symmetric_dense
from lcpcli.core.problem import is_sparse
from lcpcli.core.tolerances import P_TEST_PIVOT_TOL

#: Relative tolerance of the symmetry test: ``|m_ij - m_ji| <= SYM_TOL (max(|m_ij|, |m_ji|)
#: + sqrt(|m_ii m_jj|))`` for every pair (invariant under ``D M D`` and global scaling).
SYM_TOL = 1e-10
#: Relative margin of the definiteness test on the unit-diagonal ``E = D S D`` of the
#: symmetric part S: PD when ``E - delta I`` has a Cholesky factor, PSD when ``E + delta I`` has
#: one, with ``delta = DEF_TOL sqrt(n) ||E||_inf``.
DEF_TOL = 1e-10
#: Dense sizes up to which the O(n^3) tests (definiteness, H-matrix, P-matrix) are run at all.
DENSE_TEST_MAX_N = 6000
#: Sparse sizes up to which the sparse-LU tests are run.
SPARSE_TEST_MAX_N = 300_000
#: Sizes up to which the P-matrix property is decided exactly (all 2^n - 1 principal minors).
EXACT_P_MAX_N = 10
#: Index sets whose pivot the float search could not show positive that
#: :func:`not_p_witness` checks in rationals, at most.
WITNESS_TRIES = 256
#: Sizes up to which a P-matrix test that the float tests leave open is decided by computing
#: all 2^n - 1 principal minors in rational arithmetic.
EXACT_ALL_MINORS_MAX_N = 6
#: Largest principal block whose determinant :func:`exact_minor` computes in rationals (a
#: witness that M is not a P-matrix is checked exactly, never by a threshold).
EXACT_MINOR_MAX_N = 60

PD, PSD, INDEFINITE = "pd", "psd", "indefinite"


# ---------------------------------------------------------------------------- helpers
_is_sparse = is_sparse  # core.problem's test (one definition)


def max_abs(M: Any) -> float:
    """``max |m_ij|`` of a dense or scipy.sparse matrix (0 for an empty one); never overflows."""
    if _is_sparse(M):
        return float(np.max(np.abs(M.data))) if M.nnz else 0.0
    return float(np.max(np.abs(M))) if M.size else 0.0


def normalised(M: Any) -> Any:
    """``M`` times the power of two that brings ``max |m_ij|`` into [0.5, 1) (exact), as float64.

    Products and sums of the result cannot overflow for n < 2^500; entries below 2^-1022 of
    the largest one may become subnormal or zero, which no magnitude test here depends on.
    """
    big = max_abs(M)
    if big == 0.0 or not np.isfinite(big):
        return M.astype(np.float64) if _is_sparse(M) else np.asarray(M, dtype=np.float64)
    e = int(np.frexp(big)[1])
    if _is_sparse(M):
        out = M.tocsr().astype(np.float64, copy=True)
        out.data = np.ldexp(out.data, -e)
        return out
    if -400 <= e <= 400:  # already safe: |m_ij| in [2^-401, 2^400): products stay finite
        return np.asarray(M, dtype=np.float64)
    return np.ldexp(np.asarray(M, dtype=np.float64), -e)


def diagonal(M: Any) -> np.ndarray:
    """The diagonal of a dense or scipy.sparse matrix, as float64."""
    return np.asarray(M.diagonal(), dtype=np.float64).ravel()


def symmetric_part(M: Any) -> Any:
    """``(M + M^T) / 2`` (dense or scipy.sparse CSR)."""
    if _is_sparse(M):
        return ((M + M.T) * 0.5).tocsr()
    return 0.5 * (M + M.T)


# ---------------------------------------------------------------------------- symmetry
def is_symmetric(M: Any, tol: float) -> bool:
    """Is M (dense or scipy.sparse) symmetric to the relative tolerance ``tol``?  (The one
    symmetry test of the package; every caller states its tolerance.)

    Entry pair (i, j) passes when ``|m_ij - m_ji| <= tol (max(|m_ij|, |m_ji|) +
    sqrt(|m_ii| |m_jj|))``: relative to the pair itself and to the diagonal (which bounds
    ``|m_ij|`` for PSD matrices, and is where the rounding of a product ``A W A^T`` lives).
    The same answer on ``D M D`` for any positive diagonal D and on ``2^k M``.

    ``tol = SYM_TOL`` (:data:`SYM_TOL`): symmetric up to rounding, the class report's and
    the methods' question ("is the symmetric part all of M?").  ``tol = 0``: exactly
    symmetric, every pair equal (what a congruence ``D M D`` keeps, and what a symmetric
    factorisation of M itself needs); decided by one early-exit pass (compiled for dense M).
    """
    if M.shape[0] != M.shape[1]:
        return False
    if tol == 0.0:
        if not isinstance(M, np.ndarray) and _is_sparse(M):
            return (M != M.T).nnz == 0
        return is_symmetric_dense(M)
    A = normalised(M)
    sd = np.sqrt(np.abs(diagonal(A)))
    if _is_sparse(A):
        D = (A - A.T).tocoo()
        D.eliminate_zeros()
        if D.nnz == 0:
            return True
        absA = abs(A)
        pair = np.asarray(absA.maximum(absA.T).tocsr()[D.row, D.col]).ravel()
        return bool(np.all(np.abs(D.data) <= tol * (pair + sd[D.row] * sd[D.col])))
    with np.errstate(over="ignore", invalid="ignore"):
        asym = np.abs(A - A.T)
        worst = float(asym.max()) if asym.size else 0.0
        if worst == 0.0:
            return True
        if worst > tol * (max_abs(A) + np.float64(sd.max()) ** 2):  # fails for every pair's scale
            return False
        scale = np.maximum(np.abs(A), np.abs(A.T)) + np.outer(sd, sd)
        return bool(np.all(asym <= tol * scale))


# ---------------------------------------------------------------------------- definiteness
@dataclass(frozen=True)
class Definiteness:
    """The definiteness of ``(M + M^T)/2``: ``kind`` is ``"pd"``, ``"psd"``, ``"indefinite"``
    or None (not tested: too large); ``how`` says how it was decided; ``factor_fill`` is the
    fill ratio nnz(L + U) / nnz(S) of the sparse factorisation (sparse M only)."""

    kind: str | None
    how: str
    factor_fill: float | None = None


def _sparse_factor_positive(E: Any, shift: float) -> tuple[bool | None, float | None]:
    """Is the symmetric sparse ``E + shift I`` positive definite?  LU without pivoting in a
    symmetric fill-reducing order: all pivots positive iff PD.  (None if the factorisation
    needed pivoting or ran out of memory) and the fill ratio of the factorisation."""
    import scipy.sparse as sp  # scipy is imported on first use (start-up budget)
    import scipy.sparse.linalg as spla

    n = E.shape[0]
    K = (E + shift * sp.identity(n, format="csr")).tocsc()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lu = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular pivot
        return False, None
    except MemoryError:
        return None, None
    fill = (lu.L.nnz + lu.U.nnz) / max(K.nnz, 1)
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None, fill
    return bool(np.all(lu.U.diagonal() > 0)), fill


def _dense_cholesky_ok(E: np.ndarray, shift: float) -> bool:
    import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

    K = E.copy()
    K[np.diag_indices_from(K)] += shift
    try:
        sla.cholesky(K, check_finite=False)
    except np.linalg.LinAlgError:
        return False
    return True


def definiteness(M: Any) -> Definiteness:
    """Is ``S = (M + M^T)/2`` positive definite, semidefinite or indefinite?

    S is first scaled to a unit diagonal, ``E = D S D`` with ``D = diag(s_ii)^(-1/2)`` (so the
    answer is the same on ``D' M D'``; exactly by powers of two first,
    :func:`_diagonal_binades`, so that diagonal entries 2000 binades apart both count; an
    entry of E past the float64 range means indefinite); a negative ``s_ii``, or a zero one
    with a nonzero entry in its row, means indefinite at once.  Then: PD when
    ``E - delta I`` has a Cholesky factor, PSD when ``E + delta I`` has one,
    ``delta = DEF_TOL sqrt(n) ||E||_inf`` (sparse M: the same with a sparse LU in a symmetric
    order).  No eigenvalues.
    """
    n = M.shape[0]
    if n == 0:
        return Definiteness(PD, "empty matrix")
    sparse = _is_sparse(M)
    limit = SPARSE_TEST_MAX_N if sparse else DENSE_TEST_MAX_N
    if n > limit:
        return Definiteness(None, f"not tested (n > {limit:,})")
    if max_abs(M) < 2.0 ** 1023:  # M + M^T cannot overflow
        S = symmetric_part(M)
    else:  # halves first (what they lose below 2^-1074 is far below the largest entry)
        S = (M * 0.5 + M.T * 0.5).tocsr() if sparse else 0.5 * M + 0.5 * M.T
    S = _diagonal_binades(S)  # its diagonal in [0.5, 2): D S D keeps the inertia
    s = diagonal(S)
    if np.any(s < 0):
        i = int(np.argmin(s))
        return Definiteness(INDEFINITE, f"(M + M^T)/2 has a negative diagonal entry (index {i})")
    zero = s == 0
    if zero.any():
        if sparse:
            row_nz = np.asarray((abs(S) > 0).sum(axis=1)).ravel()[zero]
        else:
            row_nz = np.count_nonzero(S[zero], axis=1)
        if np.any(row_nz > 0):
            return Definiteness(INDEFINITE, "(M + M^T)/2 has a zero diagonal entry with a "
                                            "nonzero entry in its row")
    keep = np.flatnonzero(~zero)
    if keep.size == 0:
        return Definiteness(PSD, "(M + M^T)/2 is zero")
    r = 1.0 / np.sqrt(s[keep])
    if sparse:
        import scipy.sparse as sp  # scipy is imported on first use (start-up budget)

        Dk = sp.diags(r)
        E = (Dk @ S.tocsr()[keep][:, keep] @ Dk).tocsr()
        norm = float(np.max(np.asarray(abs(E).sum(axis=1)).ravel()))
    else:
        E = S[np.ix_(keep, keep)] if keep.size < n else S
        E = E * r[:, None] * r[None, :]
        norm = float(np.max(np.sum(np.abs(E), axis=1)))
    if not np.isfinite(norm):  # an |e_ij| past the float64 range: 1 - e_ij^2 < 0
        return Definiteness(INDEFINITE, "the unit-diagonal D (M + M^T)/2 D has an entry "
                                        "beyond double precision (a 2 x 2 minor is negative)")
    delta = DEF_TOL * np.sqrt(n) * norm
    how = "sparse LU (symmetric order, no pivoting)" if sparse else "Cholesky"
    how += " of the unit-diagonal D (M + M^T)/2 D"
    fill = None
    if sparse:
        pd, fill = _sparse_factor_positive(E, -delta)
    else:
        pd = _dense_cholesky_ok(E, -delta)
    if pd and keep.size == n:
        return Definiteness(PD, f"{how} - delta I", fill)
    if sparse:
        psd, fill2 = _sparse_factor_positive(E, delta)
        fill = fill if fill is not None else fill2
        if psd is None or pd is None:
            return Definiteness(None, "sparse factorisation needed pivoting (inconclusive)", fill)
    else:
        psd = _dense_cholesky_ok(E, delta)
    return Definiteness(PSD if psd else INDEFINITE, f"{how} + delta I", fill)


def is_psd(M: Any) -> bool:
    """Positive semidefinite in the LCP sense (``x^T M x >= 0`` for all x), by
    :func:`definiteness`; False when untested (too large)."""
    return definiteness(M).kind in (PD, PSD)


# ---------------------------------------------------------------------------- H and P matrices
def _unit_rows(M: Any) -> Any:
    """``diag(m_ii)^-1 M`` (unit diagonal; M has a positive diagonal): each row divided by its
    own diagonal entry (not on a copy normalised by M's largest entry, where a diagonal entry
    2^-1000 below it is flushed to 0); a quotient past the float64 range becomes inf (that
    row is then far from dominant, as it is)."""
    d = diagonal(M)
    with np.errstate(over="ignore", under="ignore"):
        if _is_sparse(M):
            A = M.tocsr().astype(np.float64, copy=True)
            A.data /= np.repeat(d, np.diff(A.indptr))
            return A
        return np.asarray(M, dtype=np.float64) / d[:, None]


def h_matrix_positive_diagonal(M: Any) -> bool | None:
    """Is M an H-matrix with positive diagonal (a sufficient test for a P-matrix)?

    Row-scaled to a unit diagonal (``B = diag(m_ii)^-1 |offdiag M|``), M is an H-matrix iff
    the comparison matrix ``C = I - B`` is a nonsingular M-matrix, iff some ``x > 0`` has
    ``C x > 0``.  ``x = e`` (strict diagonal dominance) is tried, then Collatz-Wielandt bounds,
    then ``x = C^-1 e``; the answer is the sign test on ``x`` and ``C x`` (the same on
    ``D1 M D2``), and False when ``rho(B)`` is within :data:`RHO_MARGIN` of 1 (singular to
    rounding).  None when too large to test.
    """
    n = M.shape[0]
    if n == 0:
        return True
    d = diagonal(M)
    if np.any(~(d > 0)):
        return False
    sparse = _is_sparse(M)
    if n > (SPARSE_TEST_MAX_N if sparse else DENSE_TEST_MAX_N):
        return None
    A = _unit_rows(M)
    if sparse:
        import scipy.sparse as sp  # scipy is imported on first use (start-up budget)
        import scipy.sparse.linalg as spla

        B = abs(A).tocsr()
        B.setdiag(0.0)
        B.eliminate_zeros()
        if np.all(np.asarray(B.sum(axis=1)).ravel() < 1.0):
            return True
        C = (sp.identity(n, format="csr") - B).tocsc()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = spla.splu(C).solve(np.ones(n))
        except RuntimeError:
            return False
    else:
        C = -np.abs(A)
        C[np.diag_indices(n)] = 1.0
        if np.all(np.sum(C, axis=1) > 0):  # 1 - sum_j |b_ij| > 0: strictly diagonally dominant
            return True
        decided = _collatz_wielandt(-C + np.eye(n))
        if decided is not None:
            return decided
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = np.linalg.solve(C, np.ones(n))
        except np.linalg.LinAlgError:
            return False
    if not (np.all(np.isfinite(x)) and np.all(x > 0)):
        return False
    return bool(np.all(np.asarray(C @ x).ravel() > 0.5))


#: Power iterations tried on the comparison matrix before the O(n^3) solve.
CW_ITERATIONS = 30
#: ``rho(B)`` within this of 1 counts as 1 (a singular comparison matrix: not an H-matrix).
#: Rounding decides such cases, and it differs between M and its scaled copies ``D1 M D2``
#: (which have the same rho); the safe answer is "not known to be H".
RHO_MARGIN = 1e-10


def _collatz_wielandt(B: np.ndarray) -> bool | None:
    """Is ``rho(B) < 1`` for ``B >= 0`` (zero diagonal)?  Collatz-Wielandt bounds
    ``min_i (Bx)_i / x_i <= rho(B) <= max_i (Bx)_i / x_i`` for any ``x > 0``, with x from
    power iterations of ``I + B``: True when the upper bound is < 1 (then ``x > 0`` and
    ``(I - B) x > 0``), False when the lower bound is >= 1, None if undecided."""
    x = np.ones(B.shape[0])
    with np.errstate(over="ignore", invalid="ignore"):  # entries of B past float64: inf
        for _ in range(CW_ITERATIONS):
            y = B @ x
            ratio = y / x
            if not np.all(np.isfinite(ratio)):
                return None  # undecided: the solve of (I - B) x = e decides
            if ratio.max() < 1.0 - RHO_MARGIN:
                return True
            if ratio.min() >= 1.0 - RHO_MARGIN:
                return False
            x = x + y
            x /= x.max()
            if not np.all(x > 0):
                return None
    return None


def _diagonal_binades(A: Any) -> Any:
    """``A`` (dense or CSR, float64) times ``2^-(h_i + h_j)``, ``h_i`` half the binary exponent
    of ``a_ii`` (0 where ``a_ii = 0``): exact, and every nonzero diagonal entry then in
    [0.5, 2), however far apart they were (a normalisation by the largest entry flushes a
    diagonal entry 2^-1000 below it to 0).  The unit-diagonal scalings start from it.  An
    entry pushed past the float64 range becomes inf (it is that much larger than its
    diagonal entries), one pushed below it 0."""
    h = np.frexp(diagonal(A))[1] // 2
    with np.errstate(over="ignore", under="ignore"):
        if _is_sparse(A):
            B = A.tocsr().astype(np.float64, copy=True)
            rows = np.repeat(np.arange(B.shape[0]), np.diff(B.indptr))
            B.data = np.ldexp(B.data, (-(h[rows] + h[B.indices])).astype(np.int32))
            return B
        return np.ldexp(np.asarray(A, dtype=np.float64),
                        (-(h[:, None] + h[None, :])).astype(np.int32))


def _unit_diagonal_symmetric(A: np.ndarray) -> np.ndarray:
    """``diag(a_ii)^(-1/2) A diag(a_ii)^(-1/2)`` (A dense float64 with a positive diagonal),
    from :func:`_diagonal_binades` (an entry past the float64 range becomes inf: ``k_ij`` that
    large refutes what the tests look for)."""
    B = _diagonal_binades(A)
    r = 1.0 / np.sqrt(np.diagonal(B))
    with np.errstate(over="ignore", invalid="ignore"):
        return B * r[:, None] * r[None, :]


def _balanced(K: np.ndarray) -> np.ndarray:
    """The diagonal similarity ``G^-1 K G`` closest to symmetric: ``log g`` solves the least
    squares problem ``log g_i - log g_j = log|k_ij / k_ji| / 2`` over the pairs with both
    entries nonzero (a graph Laplacian system).  It is K itself when K is symmetric, exactly
    symmetric when K is diagonally similar to a symmetric matrix, and the same matrix (up to
    rounding) for every ``D^-1 K D``."""
    n = K.shape[0]
    A = np.abs(K)
    with np.errstate(divide="ignore", invalid="ignore"):
        both = (A > 0) & (A.T > 0)
        np.fill_diagonal(both, False)
        R = np.where(both, 0.5 * np.log(np.where(both, A, 1.0) / np.where(both, A.T, 1.0)), 0.0)
    W = both.astype(np.float64)
    L = -W
    L[np.diag_indices(n)] = W.sum(axis=1)
    b = R.sum(axis=1)
    try:
        f = np.linalg.solve(L + 1.0 / n, b)  # + e e^T / n: fixes the free constant
    except np.linalg.LinAlgError:  # disconnected pairs graph
        f = np.linalg.lstsq(L, b, rcond=None)[0]
    g = np.exp(f - np.mean(f))
    return K * g[None, :] / g[:, None]


def _minor_pivots_positive(K: np.ndarray) -> bool:
    """All principal minors of K positive?  Depth-first over the index sets, one principal
    pivot (a Schur complement step) per set: ``det(K_{I+j}) / det(K_I)`` is the pivot, and a
    pivot counts as positive when it exceeds ``P_TEST_PIVOT_TOL`` times the magnitude of the
    terms it was computed from (a scale-free test: the same on ``D1 K D2``)."""
    return _first_small_pivot(K) is None


def _first_small_pivot(K: np.ndarray) -> list[int] | None:
    """The index set (0-based, sorted) of the first principal minor that
    :func:`_minor_pivots_positive` cannot show positive, or None when all are shown positive."""
    return next(_small_pivot_sets(K), None)


def _small_pivot_sets(K: np.ndarray) -> Iterator[list[int]]:
    """Every index set (0-based, sorted) whose pivot in the depth-first search of
    :func:`_minor_pivots_positive` is not shown positive, in the order met (the search goes
    on past each one without pivoting on it)."""
    n = K.shape[0]

    def visit(S: np.ndarray, T: np.ndarray, idx: list[int],
              chain: list[int]) -> Iterator[list[int]]:
        # S: Schur complement on the indices ``idx`` still free (after pivoting on ``chain``);
        # T: magnitude of its terms
        for pos in range(len(idx)):
            p = S[pos, pos]
            if not p > P_TEST_PIVOT_TOL * T[pos, pos]:
                yield sorted(chain + [idx[pos]])
                continue
            rest = list(range(pos + 1, len(idx)))
            if rest:
                col, row = S[rest, pos], S[pos, rest]
                with np.errstate(over="ignore", invalid="ignore"):  # inf, NaN: not shown
                    S2 = S[np.ix_(rest, rest)] - np.outer(col, row) / p
                    T2 = T[np.ix_(rest, rest)] + np.outer(np.abs(col), np.abs(row)) / p
                yield from visit(S2, T2, [idx[k] for k in rest], chain + [idx[pos]])

    yield from visit(K.copy(), np.abs(K), list(range(n)), [])


def exact_minor(M: Any, idx: list[int]) -> Fraction:
    """The principal minor ``det M[idx, idx]``, exactly: every double is a rational, and the
    elimination is done in :class:`fractions.Fraction` (``len(idx) <= EXACT_MINOR_MAX_N``)."""
    A = np.asarray(M[np.ix_(idx, idx)].toarray() if _is_sparse(M) else M[np.ix_(idx, idx)],
                   dtype=np.float64)
    k = len(idx)
    if k > EXACT_MINOR_MAX_N:
        raise ValueError(f"exact minor of order {k} > {EXACT_MINOR_MAX_N}")
    R = [[Fraction(float(x)) for x in row] for row in A]
    det = Fraction(1)
    for c in range(k):
        piv = next((r for r in range(c, k) if R[r][c] != 0), None)
        if piv is None:
            return Fraction(0)
        if piv != c:
            R[c], R[piv] = R[piv], R[c]
            det = -det
        p = R[c][c]
        det *= p
        for r in range(c + 1, k):
            f = R[r][c] / p
            if f:
                R[r] = [a - f * b for a, b in zip(R[r], R[c], strict=True)]
    return det


def not_p_witness(M: Any, candidates: list[list[int]] | None = None) -> list[int] | None:
    """A principal index set (0-based) whose minor is exactly ``<= 0``, or None: the only
    ground on which a message may say "M is not a P-matrix" (a small pivot may be rounding).

    Tried: the given candidate sets, the diagonal, the 2 x 2 minors the float test flags, and
    (``n <= EXACT_P_MAX_N``) the set where the depth-first pivot search stops.  Each is checked
    by :func:`exact_minor`."""
    n = M.shape[0]
    tried: list[list[int]] = [sorted(set(c)) for c in (candidates or []) if c]
    d = diagonal(M)
    bad = np.flatnonzero(~(d > 0))
    if bad.size:
        return [int(bad[0])]  # a 1 x 1 minor: the entry itself, exact
    dense = not _is_sparse(M) or n <= EXACT_P_MAX_N
    if dense and n <= DENSE_TEST_MAX_N:
        A = np.asarray(M.toarray() if _is_sparse(M) else M, dtype=np.float64)
        K = _unit_diagonal_symmetric(A)
        with np.errstate(over="ignore", invalid="ignore"):  # k_ij may be inf (see there)
            prod = K * K.T
            prod[np.diag_indices(n)] = 0.0
            flagged = np.argwhere(np.triu(1.0 - prod <= P_TEST_PIVOT_TOL * (1.0 + np.abs(prod)),
                                          1))
        tried += [[int(i), int(j)] for i, j in flagged[:64]]
    searched: Iterator[list[int]] = iter(())
    if dense and n <= EXACT_P_MAX_N:
        searched = islice(_small_pivot_sets(K), WITNESS_TRIES)
    for idx in chain(tried, searched):
        if len(idx) <= EXACT_MINOR_MAX_N and exact_minor(M, idx) <= 0:
            return idx
    return None


def _witness_text(M: Any, idx: list[int]) -> str:
    """``"the principal minor on {1, 3} is -2 <= 0 (exact)"`` (1-based indices)."""
    value = exact_minor(M, idx)
    names = ", ".join(str(i + 1) for i in idx)
    try:
        shown = f"{float(value):.3g}"
    except OverflowError:  # beyond the double range (a minor of order k of data ~ 1e300)
        shown = f"-2^{value.numerator.bit_length() - value.denominator.bit_length()}"
    return f"the principal minor on {{{names}}} is {shown} <= 0 (exact)"


def is_p_matrix_exact(M: Any) -> bool:
    """All 2^n - 1 principal minors positive (meant for n <= EXACT_P_MAX_N), by scale-free
    pivot tests on the unit-diagonal scaling of M (no determinant thresholds)."""
    A = np.asarray(M.toarray() if _is_sparse(M) else M, dtype=np.float64)
    if A.shape[0] == 0:
        return True
    d = np.diagonal(A)
    if np.any(~(d > 0)):
        return False
    return _minor_pivots_positive(_unit_diagonal_symmetric(A))


def _refuted(M: Any, candidates: list[list[int]],
             suspicion: str = "a principal minor is within rounding of 0 or below") -> tuple[
                 bool | None, str]:
    """``(False, witness)`` when :func:`not_p_witness` finds an exactly non-positive principal
    minor; ``(None, "undecided: ...")`` otherwise (a float test's suspicion is no proof)."""
    idx = not_p_witness(M, candidates)
    if idx is not None:
        return False, _witness_text(M, idx)
    exact = exact_p_matrix(M)
    if exact is True:
        return True, "all principal minors positive (exact rational arithmetic)"
    if isinstance(exact, list):
        return False, _witness_text(M, exact)
    return None, f"undecided: {suspicion}, but no principal minor is exactly <= 0"


def exact_p_matrix(M: Any) -> bool | list[int] | None:
    """For ``n <= EXACT_ALL_MINORS_MAX_N``: True when all ``2^n - 1`` principal minors are
    positive in rational arithmetic, else the index set (0-based) of one that is not; None for
    larger n (not tried)."""
    n = M.shape[0]
    if n > EXACT_ALL_MINORS_MAX_N:
        return None
    for k in range(1, n + 1):
        for sub in combinations(range(n), k):
            if exact_minor(M, list(sub)) <= 0:
                return list(sub)
    return True


def p_matrix(M: Any, pd: bool | None = None, h_matrix: bool | None = None,
             symmetric: bool | None = None) -> tuple[bool | None, str]:
    """``(is M a P-matrix?, how it was decided)``; None when no test decides.

    "Not P" is said only with a witness, a principal minor exactly ``<= 0``
    (:func:`not_p_witness`); a float test that merely suspects one gives None ("undecided").
    In order: a non-positive diagonal entry or 2 x 2 principal minor (not P); PD symmetric part
    (``pd``, if known); for a symmetric M (``symmetric``), P iff PD; H-matrix with positive
    diagonal (``h_matrix``, computed if not given); PD symmetric part after a diagonal scaling
    ``G^-1 D M D G`` (unit diagonal, balanced); all principal minors when n <= EXACT_P_MAX_N.
    The answer is the same on ``D1 M D2``.
    """
    n = M.shape[0]
    if n == 0:
        return True, "empty matrix"
    d = diagonal(M)
    if np.any(~(d > 0)):
        return False, "a diagonal entry (a 1 x 1 principal minor) is <= 0"
    sparse = _is_sparse(M)
    if n > (SPARSE_TEST_MAX_N if sparse else DENSE_TEST_MAX_N):
        return None, "not tested (too large)"
    if not sparse or n <= EXACT_P_MAX_N:
        A = np.asarray(M.toarray() if sparse else M, dtype=np.float64)
        K = _unit_diagonal_symmetric(A)
        prod = K * K.T  # k_ij k_ji: the 2 x 2 minors are 1 - k_ij k_ji (unit diagonal)
        prod[np.diag_indices(n)] = 0.0
        bad = 1.0 - prod <= P_TEST_PIVOT_TOL * (1.0 + np.abs(prod))
        if np.any(bad):
            return _refuted(M, [[int(v) for v in ij] for ij in np.argwhere(bad)[:64]])
    if pd:
        return True, "positive definite (symmetric part PD)"
    if symmetric and pd is False:
        return _refuted(M, [], "symmetric and not shown positive definite")
    h = h_matrix_positive_diagonal(M) if h_matrix is None else h_matrix
    if h:
        return True, "H-matrix with positive diagonal"
    if n <= EXACT_P_MAX_N:
        found = _first_small_pivot(K)
        if found is None:
            return True, "all principal minors checked"
        return _refuted(M, [found])
    if not sparse:
        B = _balanced(K)
        pd_b = definiteness(B).kind == PD
        if pd_b:
            return True, "positive definite after a positive diagonal scaling"
        if is_symmetric(B, SYM_TOL):  # P iff PD for a symmetric matrix
            return _refuted(M, [], "diagonally similar to a symmetric matrix not shown PD")
    return None, "unknown (no sufficient test applies)"


# ---------------------------------------------------------------------------- class report
@dataclass(init=False)
class ClassReport:
    """What is known about ``problem.M`` (``lcpcli info`` prints it; ``auto`` plans on it).

    ``None`` means "not tested" (or, for ``p_matrix`` and the O(n^3) tests after testing,
    "undecided": ``p_matrix_reason`` / ``definiteness_test`` say which).  The boolean fields
    are the *properties* a method's guarantee may name (:data:`PROPERTIES`).
    """

    kind: str
    n: int
    n_eq: int
    sparse: bool
    # counts (O(n^2) dense)
    nnz: int | None = None
    density: float | None = None
    q_nonnegative: bool | None = None
    # O(n) tests
    diagonal_min: float | None = None
    zero_diagonal: int | None = None
    positive_diagonal: bool | None = None
    # O(n^2) tests (O(nnz) sparse)
    symmetric: bool | None = None
    nonnegative: bool | None = None
    z_matrix: bool | None = None
    diagonally_dominant: bool | None = None
    # O(n^3) tests (sparse: sparse LU)
    definiteness: str | None = None
    definiteness_test: str = "not tested"
    factor_fill: float | None = None
    h_matrix: bool | None = None
    p_matrix: bool | None = None
    p_matrix_reason: str = "not tested"

    def __init__(self, kind: str, n: int, n_eq: int, sparse: bool) -> None:
        # the four facts known at the start; every other field reads its class default
        # (None: not tested) until a test sets it (a generated __init__ would assign all 23)
        self.kind, self.n, self.n_eq, self.sparse = kind, n, n_eq, sparse

    @property
    def pd(self) -> bool | None:
        """Symmetric part positive definite (None: not tested)."""
        return None if self.definiteness is None else self.definiteness == PD

    @property
    def psd(self) -> bool | None:
        """Symmetric part positive semidefinite, i.e. M monotone / copositive-plus."""
        return None if self.definiteness is None else self.definiteness in (PD, PSD)

    @property
    def copositive_plus(self) -> bool | None:
        """True when PSD (a sufficient test); None otherwise (copositivity is not tested)."""
        return True if self.psd else None

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe dict (non-finite floats as None) with the derived ``pd``/``psd`` too."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = None if isinstance(v, float) and not np.isfinite(v) else v
        out["pd"], out["psd"], out["copositive_plus"] = self.pd, self.psd, self.copositive_plus
        out["h_matrix_positive_diagonal"] = out.pop("h_matrix")
        return out

    def describe(self) -> str:
        """A short phrase naming what is known, e.g. ``dense, n=4, non-symmetric, 4 zero
        diagonal entries``."""
        head = f"{'sparse' if self.sparse else 'dense'}, n={self.n}"
        if self.symmetric is None and self.definiteness is None and not self.p_matrix \
                and not self.h_matrix and not self.z_matrix and not self.zero_diagonal:
            return head  # nothing else known (auto's first attempt on a small problem)
        parts = [head]
        if self.symmetric is not None:
            parts.append("symmetric" if self.symmetric else "non-symmetric")
        if self.definiteness is not None:
            parts.append({PD: "PD", PSD: "PSD", INDEFINITE: "indefinite"}[self.definiteness])
        if self.p_matrix:
            parts.append("P-matrix")
        elif self.h_matrix:
            parts.append("H-matrix")
        if self.z_matrix:
            parts.append("Z-matrix")
        if self.zero_diagonal:
            parts.append(f"{self.zero_diagonal} zero diagonal entries")
        return ", ".join(parts)


#: The boolean properties a condition may name, with a label for tables and messages.
PROPERTIES: dict[str, str] = {
    "sparse": "sparse",
    "symmetric": "symmetric",
    "positive_diagonal": "positive diagonal",
    "nonnegative": "nonnegative",
    "z_matrix": "Z-matrix",
    "diagonally_dominant": "strictly diagonally dominant",
    "pd": "PD",
    "psd": "PSD",
    "h_matrix": "H-matrix with positive diagonal",
    "p_matrix": "P-matrix",
}

#: The report fields that the O(n) diagonal test (``Classifier._diagonal_test``) may set and
#: that conditions read (``definiteness`` through ``pd`` and ``psd``): a plan made on that test
#: alone is a function of these (the key of auto's opening memo, :mod:`lcpcli.solvers.memo`).
DIAGONAL_FACTS = ("positive_diagonal", "h_matrix", "p_matrix", "definiteness")
#: The other fields that test sets: numbers and words that no condition reads.
DIAGONAL_WORDS = ("diagonal_min", "zero_diagonal", "p_matrix_reason", "definiteness_test")
#: ``diagonal_facts(report)``: the values of :data:`DIAGONAL_FACTS`, as a tuple.
diagonal_facts = attrgetter(*DIAGONAL_FACTS)


def _positive_diagonal(r: ClassReport, dmin: float) -> None:
    """The fields the O(n) diagonal test sets when every diagonal entry is positive (the
    smallest is ``dmin > 0``; n >= 1): the usual case, decided by ``dmin`` alone."""
    r.diagonal_min, r.positive_diagonal, r.zero_diagonal = float(dmin), True, 0


def positive_diagonal_report(kind: str, n: int, n_eq: int, dmin: float) -> ClassReport:
    """The report of a dense M (kind, n >= 1, n_eq) after the O(n) diagonal test alone found
    every diagonal entry positive, the smallest ``dmin``: what ``Classifier(problem)``
    holds after :meth:`Classifier.minima`, built from these facts without the problem (auto's
    ``info["classification"]`` when its first attempt, planned on that test alone, solved)."""
    r = ClassReport(kind, n, n_eq, False)
    _positive_diagonal(r, dmin)
    return r


#: :func:`diagonal_facts` of every report whose diagonal test found a positive diagonal (they
#: depend on nothing else): the opening of such a problem is keyed without its report.
POSITIVE_DIAGONAL_FACTS = diagonal_facts(positive_diagonal_report("lcp", 1, 0, 1.0))

#: The properties decided by O(n) or O(n^2) tests (O(nnz) for a sparse M).
CHEAP = frozenset({"sparse", "symmetric", "positive_diagonal", "nonnegative", "z_matrix",
                   "diagonally_dominant"})


class Classifier:
    """Fills a :class:`ClassReport` of ``problem.M`` test by test, each at most once.

    :meth:`known` answers from what has been computed plus the O(n) diagonal test (and what
    it implies: a non-positive diagonal entry refutes P, H and PD); :meth:`cheap` also runs
    the O(n^2) test of a property that has one; :meth:`get` runs the tests a property needs;
    :meth:`complete` runs them all.
    """

    __slots__ = ("problem", "report", "_done", "_minima")

    def __init__(self, problem: Any, minima: tuple[float, float] | None = None) -> None:
        """``minima``: :meth:`minima` already computed (``dense_minima`` of a dense M, by a
        caller that needed them first): the diagonal test is run on them now, as
        :meth:`minima` would."""
        self.problem = problem
        self.report = ClassReport(problem.kind, problem.n, problem.n_eq, problem.sparse)
        self._done: set[str] = set()
        self._minima: tuple[float, float] | None = None
        if minima is not None:
            self._minima = minima
            self._done.add("_diagonal")
            self._diagonal_test(minima[0])

    @property
    def tests_run(self) -> frozenset[str]:
        """The tests run so far (names of the test methods)."""
        return frozenset(self._done)

    def minima(self) -> tuple[float, float]:
        """``(min_i m_ii, min_i q_i)`` (inf for n = 0), computed once (one compiled pass for a
        dense M: these are the first facts ``auto`` looks at), with the O(n) diagonal test
        that they decide."""
        if self._minima is None:
            M, q = self.problem.M, self.problem.q
            if not self.report.sparse:
                self._minima = dense_minima(M, q)
            else:
                d = diagonal(M)
                self._minima = (float(d.min()) if d.size else np.inf,
                                float(q.min()) if q.size else np.inf)
            self._done.add("_diagonal")
            self._diagonal_test(self._minima[0])
        return self._minima

    #: The test (method name) that decides each property, in the order :meth:`complete` runs.
    _TESTS = {
        "nnz": "_counts", "positive_diagonal": "_diagonal", "symmetric": "_symmetry",
        "nonnegative": "_signs", "z_matrix": "_signs", "diagonally_dominant": "_signs",
        "pd": "_definiteness", "psd": "_definiteness", "h_matrix": "_h_matrix",
        "p_matrix": "_p_matrix",
    }

    # -- tests (each fills its fields of the report)
    def _counts(self) -> None:
        r, M, n = self.report, self.problem.M, self.report.n
        r.nnz = int(M.nnz) if r.sparse else int(np.count_nonzero(M))
        r.density = r.nnz / max(n * n, 1)
        r.q_nonnegative = bool(n == 0 or np.min(self.problem.q) >= 0)

    def _diagonal(self) -> None:
        self.minima()  # which runs the test

    def _diagonal_test(self, dmin: float) -> None:
        r = self.report
        if dmin > 0 and r.n:  # the usual case, in one step
            _positive_diagonal(r, dmin)
            return
        r.diagonal_min = float(dmin) if r.n else None
        r.positive_diagonal = r.n == 0 or dmin > 0
        r.zero_diagonal = 0
        if not r.positive_diagonal:  # a 1 x 1 principal minor (of M and of S) is <= 0
            M = self.problem.M
            d = diagonal(M) if r.sparse else M.diagonal()
            r.zero_diagonal = int(np.count_nonzero(d == 0))
            r.h_matrix = False
            r.p_matrix, r.p_matrix_reason = False, ("a diagonal entry (a 1 x 1 principal "
                                                    "minor) is <= 0")
            if np.any(d < 0):
                r.definiteness = INDEFINITE
                r.definiteness_test = "(M + M^T)/2 has a negative diagonal entry"
            elif self._zero_diagonal_row_nonzero(d == 0):
                r.definiteness = INDEFINITE
                r.definiteness_test = ("(M + M^T)/2 has a zero diagonal entry with a nonzero "
                                       "entry in its row")

    def _zero_diagonal_row_nonzero(self, zero: np.ndarray) -> bool:
        """Does a zero diagonal entry of S = (M + M^T)/2 have a nonzero in its row?  (Then S
        is indefinite; O(n) per zero entry.)"""
        idx = np.flatnonzero(zero)
        M = self.problem.M
        if self.problem.sparse:  # count in the sparse rows: never densified (O(nnz))
            M = M.tocsr()
            return bool((M[idx] + M.T.tocsr()[idx]).count_nonzero())
        rows = M[idx] + M[:, idx].T
        return bool(np.any(rows != 0))

    def _symmetry(self) -> None:
        self.report.symmetric = is_symmetric(self.problem.M, SYM_TOL)

    def _signs(self) -> None:
        r = self.report
        M = self.problem.M
        A = normalised(M)  # sums of |m_ij| cannot overflow
        if self.problem.sparse:
            off = M.tocoo()
            offvals = off.data[off.row != off.col]
            r.nonnegative = bool(np.all(off.data >= 0))
            absrow = np.asarray(abs(A).sum(axis=1)).ravel()
        else:
            offvals = M[~np.eye(M.shape[0], dtype=bool)]
            r.nonnegative = bool(np.all(M >= 0))
            absrow = np.sum(np.abs(A), axis=1)
        r.z_matrix = bool(np.all(offvals <= 0))
        d = diagonal(A)
        r.diagonally_dominant = bool(d.size == 0 or (np.all(d > 0) and np.all(2 * d > absrow)))
        if r.diagonally_dominant:  # strict row dominance with a positive diagonal
            r.h_matrix = True
            r.p_matrix, r.p_matrix_reason = True, ("strictly diagonally dominant with "
                                                   "positive diagonal")

    def _definiteness(self) -> None:
        r = self.report
        if r.definiteness is not None:
            return
        res = definiteness(self.problem.M)
        r.definiteness, r.definiteness_test, r.factor_fill = res.kind, res.how, res.factor_fill

    def _h_matrix(self) -> None:
        r = self.report
        self.run("positive_diagonal")
        if r.h_matrix is None:
            self.run("diagonally_dominant")
        if r.h_matrix is None:
            r.h_matrix = h_matrix_positive_diagonal(self.problem.M)

    def _p_matrix(self) -> None:
        r = self.report
        self.run("positive_diagonal")
        if r.p_matrix is None:
            self.run("diagonally_dominant")
        if r.p_matrix is None:
            self.run("pd")  # PD => P, and the definiteness is wanted by other tests anyway
            self.run("h_matrix")
            self.run("symmetric")
            r.p_matrix, r.p_matrix_reason = p_matrix(self.problem.M, pd=r.pd,
                                                     h_matrix=r.h_matrix, symmetric=r.symmetric)

    # -- queries
    #: The tests that factorise or pivot (O(n^3)): floating-point exceptions inside them are
    #: not numpy warnings (an entry past the float64 range, an inf or NaN from it, ends in the
    #: test's own checks as "not shown"; the CLI would print each warning).
    _QUIET = frozenset({"_definiteness", "_h_matrix", "_p_matrix"})

    def run(self, prop: str) -> None:
        """Run the test that decides ``prop`` (once)."""
        name = self._TESTS[prop]
        if name not in self._done:
            self._done.add(name)
            if name in self._QUIET:
                with np.errstate(all="ignore"):
                    getattr(self, name)()
            else:
                getattr(self, name)()

    def known(self, prop: str) -> bool | None:
        """``prop`` from the tests already run (after the O(n) diagonal test); None if open."""
        if prop == "sparse":
            return self.report.sparse
        self.run("positive_diagonal")
        return getattr(self.report, prop)

    def cheap(self, prop: str) -> bool | None:
        """``prop`` if its test is O(n^2) or cheaper (run if needed), else :meth:`known`."""
        value = getattr(self.report, prop)
        if value is not None:
            return value
        if prop in CHEAP:
            return self.get(prop)
        return self.known(prop)

    def get(self, prop: str) -> bool | None:
        """``prop``, running its test if needed; None only when the test cannot decide."""
        if prop == "sparse":
            return self.report.sparse
        value = self.known(prop)
        if value is None:
            self.run(prop)
            value = getattr(self.report, prop)
        return value

    def complete(self) -> ClassReport:
        """Run every test; return the report."""
        for prop in self._TESTS:
            self.run(prop)
        return self.report


def classify(problem: Any) -> ClassReport:
    """The complete class report of ``problem.M`` (every test run)."""
    return Classifier(problem).complete()
