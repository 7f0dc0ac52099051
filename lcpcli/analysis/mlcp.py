"""Mixed LCPs: block split, Schur-complement reduction, block principal pivots, polishing.

Conventions (those of :mod:`lcpcli.core.problem`): ``w = M z + q``; an MLCP has ``n_eq`` free
variables ``u`` first, ``M = [[A, C], [D, B]]``, ``q = [a; b]``::

    A u + C v + a = 0,        0 <= v  _|_  D u + B v + b >= 0.

**Schur reduction** (``A`` invertible and well conditioned): ``u = -A^-1 (a + C v)`` turns the
MLCP into the LCP in ``v``::

    w_v = (B - D A^-1 C) v + (b - D A^-1 a),      0 <= v _|_ w_v >= 0,

and ``u`` is recovered from ``v``.  ``A`` is factorised once by LU; its condition number is
estimated (LAPACK ``gecon``) and the reduction is refused above ``cond_max``.

**Block principal pivot** (``A`` singular or ill conditioned, e.g. Siconos' diodeBridge, cond
3e18): pick a set ``J`` of complementarity indices such that the principal block
``M[S, S]``, ``S = eq + J``, is invertible and well conditioned, and pivot on it: the free
variables ``u`` and the ``v_J`` become basic, ``w_J`` nonbasic.  What is left is an LCP of size
``m`` in the pairs ``(x_j, y_j)`` with ``x_j = v_j`` (``j`` not in ``J``) or ``x_j = w_j``
(``j`` in ``J``): ``y = M' x + q'``.  ``J`` empty is the Schur reduction.  Principal pivoting
preserves the P-matrix and positive semidefinite classes, so Lemke's guarantees carry over.

All answers are certified on the ORIGINAL problem by :func:`lcpcli.core.certificate.certify`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError

#: Default largest accepted condition estimate of the pivot block.
COND_MAX = 1e12


@dataclass(frozen=True)
class Blocks:
    """``M = [[A, C], [D, B]]``, ``q = [a; b]`` of an MLCP (dense copies)."""

    A: np.ndarray
    C: np.ndarray
    D: np.ndarray
    B: np.ndarray
    a: np.ndarray
    b: np.ndarray


def split(problem: Any) -> Blocks:
    """The blocks of an MLCP (the first ``n_eq`` rows/columns are the equalities)."""
    n = int(problem.n_eq)
    M = np.asarray(problem.dense_M(), dtype=np.float64)
    q = problem.q
    return Blocks(M[:n, :n].copy(), M[:n, n:].copy(), M[n:, :n].copy(), M[n:, n:].copy(),
                  q[:n].copy(), q[n:].copy())


def condition_estimate(lu_piv: tuple[np.ndarray, np.ndarray], anorm: float) -> float:
    """1-norm condition estimate of a matrix from its LU factors (LAPACK ``dgecon``)."""
    from scipy.linalg.lapack import dgecon  # scipy is imported on first use (start-up budget)

    lu = lu_piv[0]
    if lu.size == 0:
        return 1.0
    if not np.all(np.isfinite(lu)) or np.any(np.diag(lu) == 0.0):
        return float("inf")
    rcond, info = dgecon(lu, anorm, norm="1")
    return float("inf") if info != 0 or rcond <= 0 else 1.0 / float(rcond)


def equilibrate(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column scalings ``r``, ``c`` (powers of 2) with ``diag(r) K diag(c)`` of unit
    max-norm rows and columns; zero rows/columns get scale 1."""
    if K.size == 0:
        return np.ones(K.shape[0]), np.ones(K.shape[1])
    r = _unit_scale(np.max(np.abs(K), axis=1))
    c = _unit_scale(np.max(np.abs(K * r[:, None]), axis=0))
    return r, c


def _unit_scale(peaks: np.ndarray) -> np.ndarray:
    """``2^-k`` with ``2^k`` the power of two nearest each positive peak (1 for a zero peak),
    ``k`` kept within [-1022, 1023] so that the scale is a double: a subnormal peak (5e-324:
    ``2^1074`` overflowed to inf and the block became NaN) is scaled by ``2^1022``."""
    k = np.round(np.log2(np.where(peaks > 0, peaks, 1.0)))
    return 2.0 ** -np.clip(k, -1022, 1023)


@dataclass(frozen=True)
class Factor:
    """LU factors of the equilibrated matrix ``diag(r) K diag(c)`` and its condition estimate.

    ``solve(b)`` returns ``K^-1 b`` (``b`` a vector or a matrix of columns).
    """

    lu_piv: tuple[np.ndarray, np.ndarray]
    r: np.ndarray
    c: np.ndarray
    cond: float

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        from scipy.linalg import lu_solve  # scipy is imported on first use (start-up budget)

        rhs = np.asarray(rhs, dtype=np.float64)
        if rhs.ndim == 1:
            return self.c * lu_solve(self.lu_piv, self.r * rhs, check_finite=False)
        x = lu_solve(self.lu_piv, self.r[:, None] * rhs, check_finite=False)
        return self.c[:, None] * x


def factor(K: np.ndarray) -> Factor:
    """Equilibrate ``K`` (powers of 2, exact), factor it by LU and estimate its condition.

    The condition estimate is that of the equilibrated matrix (what the solve's accuracy
    depends on): badly scaled but otherwise sound blocks (Siconos' Buck converter: rows of
    size 1e4 and 7e-5) are not refused.  ``cond`` is inf when a pivot is exactly zero.
    """
    from scipy.linalg import lu_factor  # scipy is imported on first use (start-up budget)

    r, c = equilibrate(K)
    Ks = K * r[:, None] * c[None, :]
    anorm = float(np.max(np.sum(np.abs(Ks), axis=0))) if Ks.size else 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lu_piv = lu_factor(Ks, check_finite=False)
    return Factor(lu_piv, r, c, condition_estimate(lu_piv, anorm))


@dataclass
class Reduction:
    """A block principal pivot of an MLCP/LCP on ``S = eq + J`` and the LCP left over.

    ``lcp_M``, ``lcp_q`` define ``y = lcp_M x + lcp_q`` over the ``m`` complementarity pairs;
    ``swapped[j]`` is true when ``x_j = w_j`` (``j`` in ``J``), false when ``x_j = v_j``.
    """

    n_eq: int
    J: np.ndarray
    fac: Factor
    cond: float
    lcp_M: np.ndarray
    lcp_q: np.ndarray
    swapped: np.ndarray
    S: np.ndarray
    T: np.ndarray


def reduce(M: np.ndarray, q: np.ndarray, n_eq: int, J: Any = ()) -> Reduction:
    """Pivot on the principal block ``S = eq + (n_eq + J)`` (``J`` 0-based within the m rows).

    With ``S`` basic and ``T`` the rest, ``z_S = -M_SS^-1 (q_S + M_ST z_T - w_S)`` and the rows
    of ``T`` become ``w_T = (M_TT - M_TS M_SS^-1 M_ST) z_T + M_TS M_SS^-1 w_S + ...``.
    Raises :class:`ProblemError` when ``M_SS`` is exactly singular, or when the reduced LCP
    leaves the double range (a pivot near the smallest subnormal: its inverse overflows).
    """
    with np.errstate(all="ignore"):
        red = _reduce(M, q, n_eq, J)
    if not (np.all(np.isfinite(red.lcp_M)) and np.all(np.isfinite(red.lcp_q))):
        raise ProblemError("the reduced problem leaves the double range (a pivot block whose "
                           "inverse overflows)")
    return red


def _reduce(M: np.ndarray, q: np.ndarray, n_eq: int, J: Any) -> Reduction:
    N = q.shape[0]
    m = N - n_eq
    J = np.asarray(sorted(int(j) for j in J), dtype=np.int64)
    S = np.concatenate([np.arange(n_eq), n_eq + J]).astype(np.int64)
    T = np.setdiff1d(np.arange(n_eq, N), S).astype(np.int64)
    fac = factor(M[np.ix_(S, S)])
    if not np.isfinite(fac.cond):
        raise ProblemError("the pivot block is singular")
    inv_MST = fac.solve(M[np.ix_(S, T)])  # M_SS^-1 M_ST
    inv_qS = fac.solve(q[S])              # M_SS^-1 q_S
    # columns of M_SS^-1 for the J part (the w_J that become nonbasic)
    k = S.shape[0]
    eJ = np.zeros((k, J.shape[0]))
    eJ[n_eq + np.arange(J.shape[0]), np.arange(J.shape[0])] = 1.0
    inv_eJ = fac.solve(eJ) if J.size else eJ
    # variables of the reduced LCP, in complementarity order j = 0..m-1:
    #   x_j = v_j (j in T) or w_j (j in J);  y_j = w_j (j in T) or v_j (j in J)
    # z_S = -inv_qS + G x  with  G[:, T] = -inv_MST,  G[:, J] = inv_eJ
    tt = T - n_eq
    G = np.zeros((k, m))
    G[:, tt] = -inv_MST
    G[:, J] = inv_eJ
    lcp_M = np.zeros((m, m))
    lcp_q = np.zeros(m)
    M_TS = M[np.ix_(T, S)]
    lcp_M[tt] = M_TS @ G
    lcp_M[np.ix_(tt, tt)] += M[np.ix_(T, T)]
    lcp_q[tt] = q[T] - M_TS @ inv_qS
    lcp_M[J] = G[n_eq:]
    lcp_q[J] = -inv_qS[n_eq:]
    swapped = np.zeros(m, dtype=bool)
    swapped[J] = True
    return Reduction(n_eq, J, fac, fac.cond, lcp_M, lcp_q, swapped, S, T)


def recover(M: np.ndarray, q: np.ndarray, red: Reduction, x: np.ndarray) -> np.ndarray:
    """The full ``z`` (``u`` and ``v``) from a solution ``x`` of the reduced LCP."""
    N = q.shape[0]
    n_eq = red.n_eq
    z = np.zeros(N)
    T = red.T
    zT = np.asarray(x)[T - n_eq] if T.size else np.zeros(0)
    z[T] = zT
    rhs = -q[red.S] - (M[np.ix_(red.S, T)] @ zT if T.size else 0.0)
    if red.J.size:
        rhs[n_eq:] += np.asarray(x)[red.J]  # w_J = x_J
    with np.errstate(all="ignore"):  # past the double range: inf, which the certificate refuses
        z[red.S] = red.fac.solve(rhs)
    return z


def schur(problem: Any, cond_max: float = COND_MAX) -> Reduction:
    """Schur reduction of an MLCP (``J`` empty); ProblemError when ``A`` is singular or worse
    conditioned than ``cond_max``."""
    M = np.asarray(problem.dense_M(), dtype=np.float64)
    red = reduce(M, problem.q, problem.n_eq)
    if red.cond > cond_max:
        raise ProblemError(f"A is ill-conditioned (condition estimate {red.cond:.2e} > "
                           f"{cond_max:.1e})")
    return red


def choose_pivot_set(M: np.ndarray, n_eq: int, cond_max: float = COND_MAX,
                     max_add: int | None = None, shortlist: int = 4) -> tuple[np.ndarray, float]:
    """A set ``J`` of complementarity indices making ``M[eq+J, eq+J]`` well conditioned.

    Greedy: starting from ``J`` empty, while the (equilibrated) block is singular or its
    condition exceeds ``cond_max``, add one index.  Candidates are ranked by how well they
    border the block's near-null spaces (``||U0^T M[S, j]|| * ||M[j, S] V0||``, from one SVD);
    the first of the best ``shortlist`` that lowers the rank deficiency is taken, otherwise
    (conditioning phase) the one giving the best (deficiency, condition) of the enlarged
    block.  Returns ``(J, cond)``; ``cond`` is inf when the block stays singular and
    may exceed ``cond_max`` when no index helps (the caller then decides).
    """
    N = M.shape[0]
    m = N - n_eq
    J: list[int] = []
    eq = list(range(n_eq))

    def analyse(idx: list[int], with_vectors: bool = False) -> tuple[int, float, Any]:
        S = eq + [n_eq + j for j in idx]
        if not S:
            return 0, 1.0, None
        K = M[np.ix_(S, S)]
        r, c = equilibrate(K)
        with np.errstate(all="ignore"):
            Ks = K * r[:, None] * c[None, :]
        if not np.all(np.isfinite(Ks)):  # past the double range: the block counts as singular
            return len(S), float("inf"), None
        try:
            if with_vectors:
                U, s, Vt = np.linalg.svd(Ks)
            else:
                s = np.linalg.svd(Ks, compute_uv=False)
        except np.linalg.LinAlgError:  # no usable SVD: the block counts as singular
            return len(S), float("inf"), None
        if s[0] == 0.0:
            deficiency, cond = len(S), float("inf")
        else:
            rank = int(np.sum(s > s[0] * 1e-13 * len(S)))
            deficiency = len(S) - rank
            cond = s[0] / s[-1] if s[-1] > 0 else float("inf")
        if not with_vectors:
            return deficiency, cond, None
        small = s <= max(s[0], 1e-300) / cond_max
        small[-1] = True
        return deficiency, cond, (S, r, c, U[:, small], Vt[small].T)

    deficiency, cond, vec = analyse(J, True)
    limit = m if max_add is None else max_add
    while (deficiency > 0 or cond > cond_max) and len(J) < limit and vec is not None:
        S, r, c, U0, V0 = vec
        rest = np.array([j for j in range(m) if j not in J], dtype=np.int64)
        if rest.size == 0:
            break
        cols = (M[np.ix_(S, n_eq + rest)] * r[:, None])          # new columns, row-scaled
        rows = (M[np.ix_(n_eq + rest, S)] * c[None, :])          # new rows, column-scaled
        cn = np.maximum(np.max(np.abs(cols), axis=0), 1e-300)
        rn = np.maximum(np.max(np.abs(rows), axis=1), 1e-300)
        with np.errstate(all="ignore"):  # entries near the double range: inf scores rank first
            sc = (np.linalg.norm(U0.T @ cols, axis=0) / cn) * \
                (np.linalg.norm(rows @ V0, axis=1) / rn)
            sc += 1e-3 * (np.linalg.norm(U0.T @ cols, axis=0) / cn
                          + np.linalg.norm(rows @ V0, axis=1) / rn)
        order = rest[np.argsort(-sc, kind="stable")][:shortlist]
        best: tuple[int, float] | None = None
        best_j = -1
        for j in order:
            d, cnd, _ = analyse(J + [int(j)])
            if best is None or (d, cnd) < best:
                best, best_j = (d, cnd), int(j)
            if (d == 0 and cnd <= cond_max) or 0 < d < deficiency:
                break  # progress on the best-ranked candidate: skip the rest of the shortlist
        if best is None or best >= (deficiency, cond):
            break
        J.append(best_j)
        deficiency, cond, vec = analyse(J, True)
    if deficiency > 0:
        cond = float("inf")
    return np.asarray(sorted(J), dtype=np.int64), float(cond)


def polish(problem: Any, z: np.ndarray, *, rel_gap: float = 1e-9) -> np.ndarray:
    """Re-solve the linear system of the candidate's active set on the original problem.

    Variables strictly inside their bounds (free ones always) are basic: ``w_S = 0`` gives
    ``M_SS z_S = -(q_S + M_SN z_N)`` with the others at their bounds.  Solved by LU (least
    squares if singular) with one refinement step; the better of the candidate and the
    re-solve by the certificate's natural residual is returned.
    """
    z = np.asarray(z, dtype=np.float64)
    if not np.all(np.isfinite(z)):
        return z
    lo, up = problem.bounds()
    n = problem.n
    scale = max(1.0, float(np.max(np.abs(z), initial=0.0)))
    at_lo = np.isfinite(lo) & (z - lo <= rel_gap * scale)
    at_up = np.isfinite(up) & (up - z <= rel_gap * scale)
    Sm = ~(at_lo | at_up)
    S = np.flatnonzero(Sm)
    Nn = np.flatnonzero(~Sm)
    zc = z.copy()
    zc[at_lo] = lo[at_lo]
    zc[at_up & ~at_lo] = up[at_up & ~at_lo]
    if S.size:
        M = np.asarray(problem.dense_M(), dtype=np.float64)
        K = M[np.ix_(S, S)]
        rhs = -problem.q[S] - (M[np.ix_(S, Nn)] @ zc[Nn] if Nn.size else 0.0)
        try:
            with np.errstate(all="ignore"):
                zs = np.linalg.solve(K, rhs)
                zs = zs + np.linalg.solve(K, rhs - K @ zs)
        except np.linalg.LinAlgError:
            zs = np.linalg.lstsq(K, rhs, rcond=None)[0]
        zc[S] = zs
    if not np.all(np.isfinite(zc)) or n == 0:
        return z
    M = problem.M
    return zc if _natural(M, problem.q, lo, up, zc) <= _natural(M, problem.q, lo, up, z) else z


def _natural(M: Any, q: np.ndarray, lo: np.ndarray, up: np.ndarray, z: np.ndarray) -> float:
    """``||mid(z - l, z - u, w)||_inf`` (the certificate's natural residual, unscaled; Inf
    when ``w`` leaves the double range)."""
    with np.errstate(over="ignore", invalid="ignore"):
        w = np.asarray(M @ z).ravel() + q
        r = np.maximum(z - up, np.minimum(z - lo, w))
    return float(np.max(np.abs(r))) if r.size else 0.0
