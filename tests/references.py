"""Independent references for the tests (deliberately simple, slow and exact where possible)."""

from __future__ import annotations

import itertools
from fractions import Fraction
from typing import Any

import numpy as np


def brute_force_solutions(M: np.ndarray, q: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """All solutions found by trying every support set (n <= 10): z_S = -M_SS^-1 q_S."""
    n = len(q)
    found: list[np.ndarray] = []
    for k in range(n + 1):
        for S in itertools.combinations(range(n), k):
            z = np.zeros(n)
            if S:
                idx = list(S)
                A = M[np.ix_(idx, idx)]
                if abs(np.linalg.det(A)) < 1e-12:
                    continue
                z[idx] = np.linalg.solve(A, -q[idx])
            w = M @ z + q
            scale = 1 + np.abs(q).max()
            feasible = z.min() >= -tol * scale and w.min() >= -tol * scale
            if feasible and not any(np.allclose(z, f, atol=1e-7 * scale) for f in found):
                found.append(z)
    return found


def exact_lemke_sequence(M: np.ndarray, q: np.ndarray, max_pivots: int = 5000):
    """Lexicographic Lemke (covering vector ones) in exact rational arithmetic.

    Returns (status, [(entering, leaving, row), ...], z) with the kernel's variable codes:
    0..n-1 = w, n..2n-1 = z, 2n = z0.  Same rule as the kernel: initial pivot on the largest
    index among the most negative q_i; z0 leaves whenever it ties; otherwise the lexicographic
    minimum of (rows of the basis inverse) / pivot element.
    """
    n = len(q)
    T = [[Fraction(int(M[i, j])) for j in range(n)] + [Fraction(1)] for i in range(n)]
    qb = [Fraction(int(x)) for x in q]
    basic = list(range(n))
    where = {i: i for i in range(n)}
    for j in range(n + 1):
        where[n + j] = -(j + 1)

    def pivot(r: int, c: int) -> None:
        p = T[r][c]
        rowr = [-x / p for x in T[r]]
        rowr[c] = 1 / p
        qr = -qb[r] / p
        for i in range(n):
            if i == r or T[i][c] == 0:
                continue
            f = T[i][c]
            qb[i] += f * qr
            for j in range(n + 1):
                T[i][j] += f * rowr[j]
            T[i][c] = f / p
        T[r] = rowr
        qb[r] = qr

    def key(i: int, k: int) -> Fraction:
        loc = where[k]
        if loc >= 0:
            return Fraction(1 if loc == i else 0)
        return -T[i][-loc - 1]

    seq = []
    best = min(qb)
    if best >= 0:
        return "trivial", seq, np.zeros(n)
    r = max(i for i in range(n) if qb[i] == best)
    entering, c = 2 * n, n
    leaving = basic[r]
    pivot(r, c)
    basic[r], where[entering], where[leaving] = entering, r, -(c + 1)
    seq.append((entering, leaving, r))
    while len(seq) < max_pivots:
        entering = leaving + n if leaving < n else leaving - n
        c = -where[entering] - 1
        cand = [i for i in range(n) if T[i][c] < 0]
        if not cand:
            return "ray", seq, None
        tmin = min(qb[i] / -T[i][c] for i in cand)
        cand = [i for i in cand if qb[i] / -T[i][c] == tmin]
        z0_rows = [i for i in cand if basic[i] == 2 * n]
        if z0_rows:
            r = z0_rows[0]
        else:
            k = 0
            while len(cand) > 1:
                vals = {i: key(i, k) / -T[i][c] for i in cand}
                m = min(vals.values())
                cand = [i for i in cand if vals[i] == m]
                k += 1
            r = cand[0]
        leaving = basic[r]
        pivot(r, c)
        basic[r], where[entering], where[leaving] = entering, r, -(c + 1)
        seq.append((entering, leaving, r))
        if leaving == 2 * n:
            z = np.zeros(n)
            for i, b in enumerate(basic):
                if n <= b < 2 * n:
                    z[b - n] = float(qb[i])
            return "ok", seq, z
    return "max_pivots", seq, None


def _dense_data(M: Any, q: Any, x: Any, lo: Any, up: Any, n_eq: int) -> tuple[np.ndarray, ...]:
    """Dense float copies of ``M, q, x`` and the bounds (LCP bounds, the first ``n_eq``
    variables free, when none are given)."""
    M = np.asarray(M.toarray() if hasattr(M, "toarray") else M, dtype=float)
    q = np.asarray(q, dtype=float)
    n = q.size
    if lo is None:
        lo = np.where(np.arange(n) < n_eq, -np.inf, 0.0)
        up = np.full(n, np.inf)
    return M, q, np.asarray(x, dtype=float), lo, up


#: Costs of two states within this relative distance are a tie at the rounding level (see
#: ``prefer`` of :func:`componentwise_error`).
NEAR_TIE = 2.0 ** -40


def componentwise_error(M: Any, q: np.ndarray, z: np.ndarray, lo: np.ndarray | None = None,
                        up: np.ndarray | None = None, n_eq: int = 0,
                        w: np.ndarray | None = None,
                        prefer: np.ndarray | None = None) -> float:
    """The certificate's ``error``, re-implemented independently (dense numpy, plain loops).

    Same definition as :mod:`lcpcli.core.certificate`, written differently on purpose: every
    pair's states are enumerated explicitly, and the blocks of coupled rows are found by a
    breadth-first search over an explicit graph instead of union-find.  Slow; for tests only.
    ``w``: use this ``M z + q`` (e.g. the exact one, rounded once) instead of the one computed
    here in floating point.  ``prefer``: a state per pair (the kernel's codes: 0 ``L``, 1 ``U``,
    2 ``F``), taken when its cost is within :data:`NEAR_TIE` (relative) of the best: two
    states whose costs differ by an ulp are a tie that either rounding may break, and the state
    decides which rows anchor a block's growth (the error then differs by more than the ulp).
    A preferred state that costs more than that is not taken.
    """
    M, q, z, lo, up = _dense_data(M, q, z, lo, up, n_eq)
    n = q.size
    if not np.all(np.isfinite(z)):
        return float("inf")
    with np.errstate(all="ignore"):
        w_given = w
        w = M @ z + q if w is None else np.asarray(w, dtype=float)
        terms = np.abs(M) * np.abs(z)[None, :]
        a = terms.sum(axis=1)
        s = a + np.abs(q)
    nonzero = s[s > 0]
    in_range = nonzero.size == 0 or (nonzero.max() < 2.0 ** 960 and nonzero.min() > 2.0 ** -960)
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(s)) and in_range):
        # the data leave the comfortable range: everything below is a ratio within one row, so
        # each row is computed exactly (rationals) and divided by a power of two near its scale
        M, q, w, terms, a, s = _rows_scaled_exactly(M, q, z, w_given)
    # an equation carries data where q_i is nonzero in the units its row is judged in (a q_i
    # below 2^-1074 of its row's scale is 0 there: its growth would be a ratio of roundings)
    has_data = q != 0

    def rel(v: float, si: float) -> float:
        if v == 0:
            return 0.0
        return float("inf") if si == 0 else v / si

    def move(j: int, x: float) -> float:
        if x == 0:
            return 0.0
        col = np.abs(M[:, j])
        if not col.any():
            return float("inf")
        kappa = 0.0  # the largest relative change per unit move (same rounding as the kernel)
        with np.errstate(over="ignore"):  # past the range: inf, as the kernel's
            for i in np.flatnonzero(col):
                kappa = max(kappa, float("inf") if s[i] == 0 else col[i] * (1.0 / s[i]))
            return x * kappa

    eps = np.zeros(n)
    equation = np.zeros(n, dtype=bool)   # the pair is scored in its state "w_i = 0"
    for i in range(n):
        costs = {}
        outside = max(lo[i] - z[i], z[i] - up[i], 0.0)
        costs["F"] = max(move(i, outside), rel(abs(w[i]), s[i]))
        if np.isfinite(lo[i]):
            costs["L"] = max(move(i, abs(z[i] - lo[i])), rel(max(-w[i], 0.0), s[i]))
        if np.isfinite(up[i]):
            costs["U"] = max(move(i, abs(z[i] - up[i])), rel(max(w[i], 0.0), s[i]))
        # ties: the state needing no move of z_i (on its bound: that bound; else F)
        order = ["L", "F", "U"] if z[i] == lo[i] else (["U", "F", "L"] if z[i] == up[i]
                                                       else ["F", "L", "U"])
        best = min(order, key=lambda k: (costs.get(k, np.inf), order.index(k)))
        if prefer is not None:
            want = "LUF"[int(prefer[i])]
            if want in costs and costs[want] <= costs[best] * (1.0 + NEAR_TIE):
                best = want
        eps[i] = costs[best]
        equation[i] = best == "F"
    # rows linked through a column z_j != 0 where z_j's share of the row, |M_ij z_j| / s_i, is
    # within 2^-10 of its largest share in any row
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(terms > 0, terms / s[:, None], 0.0)
    top = share.max(axis=0) if n else np.zeros(0)
    link = (terms > 0) & (share >= 2.0 ** -10 * top[None, :])
    block = -np.ones(n, dtype=int)
    for start in range(n):
        if block[start] >= 0 or a[start] == 0:
            continue
        block[start] = start
        queue = [start]
        while queue:
            i = queue.pop()
            for j in np.flatnonzero(link[i]):
                for k in np.flatnonzero(link[:, j]):
                    if block[k] < 0:
                        block[k] = start
                        queue.append(k)
    growth = np.ones(n)
    den = np.abs(q) + np.abs(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(den == 0, np.inf, a / np.where(den == 0, 1.0, den))
    for b in set(block[block >= 0].tolist()):
        rows = np.flatnonzero(block == b)
        anchors = rows[equation[rows] & has_data[rows]]  # equations with data (q_i != 0)
        anchored = float(g[anchors].min()) if anchors.size else np.inf
        for i in rows:
            if np.isfinite(anchored):
                growth[i] = max(1.0, anchored)
            else:  # no equation with data: a data row answers for itself
                growth[i] = max(1.0, float(g[i])) if has_data[i] else 1.0
    err = [0.0 if eps[i] == 0 else eps[i] * growth[i] for i in range(n)]
    return float(max(err)) if n else 0.0


def _to_float(x: Fraction) -> float:
    """A rational as the nearest double, +-Inf beyond the range."""
    try:
        return float(x)
    except OverflowError:
        return float("inf") if x > 0 else float("-inf")


def _rows_scaled_exactly(M: np.ndarray, q: np.ndarray, z: np.ndarray, w: np.ndarray | None
                         ) -> tuple[np.ndarray, ...]:
    """``M, q, w, |M||z|, a, s`` of :func:`componentwise_error`, each row computed in exact
    rational arithmetic and divided by the power of two nearest below its scale ``s_i`` (exact;
    entries negligible against ``s_i`` may round to 0 or a subnormal)."""
    n = q.size
    out = [np.zeros_like(M), np.zeros(n), np.zeros(n), np.zeros_like(M), np.zeros(n), np.zeros(n)]
    Z = [Fraction(float(v)) for v in z]
    for i in range(n):
        row = [Fraction(float(v)) for v in M[i]]
        Q = Fraction(float(q[i]))
        T = [abs(m * x) for m, x in zip(row, Z, strict=True)]
        A = sum(T, Fraction(0))
        S = A + abs(Q)
        W = sum((m * x for m, x in zip(row, Z, strict=True)), Q) if w is None else \
            Fraction(float(w[i]))
        e = S.numerator.bit_length() - S.denominator.bit_length() if S else 0
        unit = Fraction(2) ** e
        out[0][i] = [_to_float(m / unit) for m in row]
        out[1][i] = _to_float(Q / unit)
        out[2][i] = _to_float(W / unit)
        out[3][i] = [_to_float(t / unit) for t in T]
        out[4][i] = _to_float(A / unit)
        out[5][i] = _to_float(S / unit)
    return tuple(out)


def farkas_certifies(M: Any, q: np.ndarray, y: Any, lo: np.ndarray | None = None,
                     up: np.ndarray | None = None, n_eq: int = 0) -> bool:
    """Whether ``y`` proves that ``w = M z + q`` has no feasible point over the box (the
    no_solution proof of :mod:`lcpcli.analysis.proof`), re-implemented independently in exact
    rational arithmetic (every double is a rational), one pair at a time, with no margin: a
    proof of the data as given.

    Sign rules: ``y_i >= 0`` where only ``lo_i`` is finite, ``<= 0`` where only ``up_i`` is,
    free where neither is, 0 where both are; then ``g = M^T y`` must be ``<= 0`` where ``up_i``
    is infinite and ``>= 0`` where ``lo_i`` is, and ``q^T y + sum_i max(g_i lo_i, g_i up_i)``
    (finite bounds only) must be negative.
    """
    M, q, y, lo, up = _dense_data(M, q, y, lo, up, n_eq)
    n = q.size
    if y.shape != (n,) or not np.all(np.isfinite(y)) or not np.any(y != 0):
        return False
    Y = [Fraction(float(v)) for v in y]
    total = sum((Fraction(float(q[i])) * Y[i] for i in range(n)), Fraction(0))
    for i in range(n):
        lo_f, up_f = bool(np.isfinite(lo[i])), bool(np.isfinite(up[i]))
        if (lo_f and not up_f and Y[i] < 0) or (up_f and not lo_f and Y[i] > 0) \
                or (lo_f and up_f and Y[i] != 0):
            return False
        g = sum((Fraction(float(M[j, i])) * Y[j] for j in range(n)), Fraction(0))
        if (not up_f and g > 0) or (not lo_f and g < 0):
            return False
        ends = [g * Fraction(float(b)) for b in (lo[i], up[i]) if np.isfinite(b)]
        total += max(ends) if ends else Fraction(0)
    return total < 0


def _exact_inverse(A: list[list[Fraction]]) -> list[list[Fraction]] | None:
    """The inverse of a square matrix of rationals by Gauss-Jordan elimination (None when
    singular)."""
    m = len(A)
    T = [list(row) + [Fraction(int(i == k)) for k in range(m)] for i, row in enumerate(A)]
    for c in range(m):
        p = next((r for r in range(c, m) if T[r][c] != 0), None)
        if p is None:
            return None
        T[c], T[p] = T[p], T[c]
        piv = T[c][c]
        T[c] = [x / piv for x in T[c]]
        for r in range(m):
            if r != c and T[r][c] != 0:
                f = T[r][c]
                T[r] = [x - f * y for x, y in zip(T[r], T[c], strict=True)]
    return [row[m:] for row in T]


def pivot_variable(name: str, n: int) -> tuple[str, int]:
    """``("w", i)`` or ``("z", j)`` (0-based; the artificial variable ``z0`` is ``("z", n)``)
    of a canonical 1-based name ``w1..wn``, ``z1..zn``, ``z0``."""
    kind, idx = name[0], int(name[1:])
    if kind == "z" and idx in (0, n + 1):
        return ("z", n)
    return (kind, idx - 1)


def principal_pivot_exact(Maug: Any, q: Any, dependent: list[str], independent: list[str]
                          ) -> tuple[list[Fraction], list[list[Fraction]]] | None:
    """The pivoted system ``w' = q' + M' z'`` of ``w = q + Maug z`` (``Maug`` n x (n+1), its
    last column the artificial variable ``z0``), exactly, by Gauss-Jordan on the whole system
    written as ``A x = q`` with ``A = [I, -Maug]`` and ``x = (w, z)`` (Cottle-Pang-Stone 2.3,
    principal pivoting as a change of basis): ``x_D = A_D^-1 q - A_D^-1 A_I x_I``.  Independent
    of Dai & Drumwright's index sets.  Names are canonical and 1-based; returns ``(q', M')``
    (rows in ``dependent`` order, columns of ``M'`` in ``independent`` order), or None when
    ``A_D`` is singular (the tuples are not a basis)."""
    n = len(q)
    Mf = [[Fraction(float(Maug[i][j])) for j in range(n + 1)] for i in range(n)]

    def column(name: str) -> list[Fraction]:
        kind, j = pivot_variable(name, n)
        if kind == "w":
            return [Fraction(int(i == j)) for i in range(n)]
        return [-Mf[i][j] for i in range(n)]

    cols = [column(v) for v in dependent]
    inv = _exact_inverse([[cols[k][i] for k in range(n)] for i in range(n)])
    if inv is None:
        return None

    def apply(b: list[Fraction]) -> list[Fraction]:
        return [sum((inv[i][k] * b[k] for k in range(n)), Fraction(0)) for i in range(n)]

    qp = apply([Fraction(float(x)) for x in q])
    Mp_cols = [apply([-x for x in column(v)]) for v in independent]
    return qp, [[Mp_cols[c][r] for c in range(len(independent))] for r in range(n)]
