"""The proof behind a ``no_solution`` verdict: a Farkas vector, checked componentwise.

Conventions: ``w = M z + q`` over the box ``[l, u]`` of :meth:`lcpcli.core.problem.Problem.bounds`
(LCP: ``[0, inf)``; MLCP free variables: ``(-inf, inf)``; box LCP: the given bounds).  Any
solution is in particular *feasible* for the relaxation that forgets complementarity::

    l <= z <= u,   w_i >= 0 where only l_i is finite,   w_i <= 0 where only u_i is finite,
                   w_i = 0 where both are infinite (free rows of an MLCP).

A **Farkas vector** ``y`` proves that this relaxation, hence the problem, has no point
(Cottle-Pang-Stone, 2.7 and 4.4): ``y_i >= 0`` where only ``l_i`` is finite, ``y_i <= 0`` where only
``u_i`` is finite, ``y_i`` free on free rows, ``y_i = 0`` where both bounds are finite.  Then every
feasible ``z`` has ``y^T w >= 0``, while ``y^T (M z + q) = g^T z + q^T y`` with ``g = M^T y`` is at
most ``q^T y + sum_i max(g_i l_i, g_i u_i)`` on the box; ``g_i <= 0`` where ``u_i = inf``,
``g_i >= 0`` where ``l_i = -inf`` and a negative total are a contradiction.  For the LCP this is the
classical ``y >= 0, M^T y <= 0, q^T y < 0``.

:func:`check_farkas` accepts ``y`` only when it is an *exact* Farkas vector of the data as
given (every double is a rational number): a sign of ``g = M^T y`` is taken from its floating-
point value when that value is farther from zero than Higham's bound on its rounding,
``PROOF_GAMMA(n) (|M|^T |y|)_i``, and otherwise from the exact sum (:func:`_exact_dots`: each
product split into exact halves, summed correctly rounded by ``math.fsum``; exact rational
arithmetic where the halves could underflow); the total must stay negative by more than
``PROOF_GAMMA(n)`` times its terms.  So a solvable problem, however close to an infeasible one
(the positive definite ``M`` with smallest eigenvalue 1e-12, or 1e-16, the scaled Hilbert
matrix, ``B B^T`` rounded to a nonsingular matrix) is never "proven" infeasible.  This is the
only way to a ``no_solution`` verdict (:func:`confirm`, used by :func:`lcpcli.solve` and
``auto``).

:func:`prove_infeasible` turns a suggestion of infeasibility into such a vector: the given
candidates (e.g. Lemke's secondary-ray direction, which is a Farkas vector for a copositive-plus
``M``: Cottle-Pang-Stone, Theorem 4.4.13), each after one least-squares refinement of its
active constraints, a single row (``M_i <= 0``, ``q_i < 0``), and, on request, a linear program
(HiGHS) on the equilibrated problem.  Whatever it finds is then checked by :func:`check_farkas`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

#: Unit roundoff of float64.
UNIT_ROUNDOFF = 2.0 ** -53
#: Sums below this (far below the normal range of doubles are only the last 2^-900) are
#: recomputed exactly: their terms may have underflowed.
TINY = 2.0 ** -900
#: Largest problem for which :func:`prove_infeasible` runs the linear program.
LP_MAX_N = 3000
#: Largest problem for which a search without a method's hint (``auto``'s last resort,
#: :func:`search_proof`) runs it: the dense linear program costs ~0.8 s at n = 500 and ~7 s
#: at n = 1000 (HiGHS, one core), more than the methods it follows.
UNHINTED_LP_MAX_N = 500


def proof_gamma(n: int) -> float:
    """The proof's relative margin for an ``n``-variable problem: twice Higham's
    ``gamma_{n+2} = (n+2) u / (1 - (n+2) u)``, the rounding bound of one dot product of length
    ``n`` plus the one of the candidate's own last operation."""
    k = (n + 2) * UNIT_ROUNDOFF
    return 2.0 * k / (1.0 - k)


@dataclass(frozen=True)
class FarkasCheck:
    """The outcome of :func:`check_farkas`.

    ``passed``: the proof holds; ``value``: the bound ``q^T y + sum_i max(g_i l_i, g_i u_i)``
    (negative for a proof), ``margin``: its rounding margin (``value < -margin`` is required);
    ``worst``: the 0-based index of the worst sign violation of ``g = M^T y`` relative to its
    margin (-1: none), ``violation``: that ratio (``<= 1`` is accepted); ``reason``: why it
    failed, in words (empty when it passed); ``y``: the vector checked.
    """

    passed: bool
    y: np.ndarray
    value: float
    margin: float
    worst: int
    violation: float
    reason: str
    lcp: bool = True

    def describe(self) -> str:
        """One phrase for ``message`` (``y`` itself is in ``info["farkas_y"]``)."""
        if not self.passed:
            return f"no Farkas certificate ({self.reason})"
        if self.lcp:
            return (f"Farkas certificate: y >= 0 with M^T y <= 0 (componentwise, exactly) "
                    f"and q^T y = {self.value:.3g} < 0 (y scaled by a power of two), so no "
                    f"z >= 0 has Mz + q >= 0")
        return (f"Farkas certificate: y with M^T y within the sign rules of the bounds "
                f"(exactly) and sup of y^T (Mz + q) over the box = {self.value:.3g} < 0, so no "
                f"z in the box makes w feasible")

    def as_dict(self) -> dict[str, Any]:
        """The proof for ``Result.info`` (JSON-safe)."""
        return {"passed": self.passed, "value": _finite(self.value),
                "margin": _finite(self.margin), "worst": self.worst,
                "violation": _finite(self.violation), "reason": self.reason}


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def sides(lo: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(lower_only, upper_only)``: where only ``l_i`` / only ``u_i`` is finite (the rows with
    ``w_i >= 0`` / ``w_i <= 0`` in the relaxation); both false: free row (both infinite) or a
    finite box (both finite)."""
    lo_f, up_f = np.isfinite(lo), np.isfinite(up)
    return lo_f & ~up_f, up_f & ~lo_f


def check_farkas(M: Any, q: np.ndarray, lo: np.ndarray, up: np.ndarray,
                 y: Any) -> FarkasCheck:
    """Check ``y`` as a Farkas vector of the problem ``(M, q)`` over ``[lo, up]``; see the
    module docstring.  ``M`` dense or scipy.sparse.  Never raises on extreme data: a
    non-finite intermediate fails the check (an honest ``unsolved``)."""
    n = q.shape[0]
    y = np.asarray(y, dtype=np.float64).ravel()
    nan = float("nan")

    def fail(reason: str, worst: int = -1, violation: float = nan) -> FarkasCheck:
        return FarkasCheck(False, y, nan, nan, worst, violation, reason)

    if y.shape[0] != n:
        return fail(f"y has length {y.shape[0]}, expected {n}")
    if not np.all(np.isfinite(y)) or not np.any(y != 0):
        return fail("y is zero or not finite")
    lower_only, upper_only = sides(lo, up)
    boxed = np.isfinite(lo) & np.isfinite(up)
    wrong = (lower_only & (y < 0)) | (upper_only & (y > 0)) | (boxed & (y != 0))
    if np.any(wrong):
        i = int(np.flatnonzero(wrong)[0])
        return fail(f"y_{i + 1} = {y[i]:.3g} has the wrong sign for its row", i)
    # a power-of-two normalisation (exact) keeps |M|^T |y| away from overflow
    _, e = np.frexp(np.max(np.abs(y)))
    y = np.ldexp(y, -int(e))
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        g = np.asarray(M.T @ y).ravel()
        a = np.asarray(abs(M).T @ np.abs(y)).ravel()
        qa = np.abs(q) * np.abs(y)
        gamma = proof_gamma(n)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(a))):
            return fail("M^T y overflows")
        # a column whose terms may have underflowed: its sign is decided exactly (a rounding
        # margin below the normal range would be absolute, not relative to the data)
        exact = np.zeros(n, dtype=bool)  # g_i is the exact sum, correctly rounded
        small = np.flatnonzero(a < TINY)
        if small.size:
            live = np.asarray((M != 0).T @ (y != 0).astype(np.float64)).ravel() > 0
            for i in small[live[small]]:
                g[i], a[i] = _exact_column(M, y, i)
                exact[i] = True
        # Higham's bound on the rounding of each computed g_i (none on an exact one)
        m = np.where(exact, 0.0, gamma * a)
        must_nonpos = np.isinf(up)   # z_i unbounded above: g_i <= 0
        must_nonneg = np.isinf(lo)   # z_i unbounded below: g_i >= 0
        worst, ratio = _sign_violation(g, m, must_nonpos, must_nonneg)
        if n and ratio[worst] > 1.0:  # the wrong sign, farther than any rounding reaches
            return fail(f"(M^T y)_{worst + 1} = {g[worst]:.3g} has the wrong sign beyond its "
                        f"rounding margin {m[worst]:.3g}", worst, float(ratio[worst]))
        # a sign the rounding bound cannot decide is decided by the exact sum
        undecided = np.flatnonzero(~exact & ((must_nonpos & (g + m > 0))
                                             | (must_nonneg & (g - m < 0))))
        if undecided.size:
            g[undecided] = _exact_dots(M, y, undecided)
            m[undecided] = 0.0
            worst, ratio = _sign_violation(g, m, must_nonpos, must_nonneg)
            if ratio[worst] > 1.0:
                return fail(f"(M^T y)_{worst + 1} = {g[worst]:.3g} has the wrong sign (its "
                            f"exact value: the data are not exactly infeasible)", worst,
                            float(ratio[worst]))
        # the range of the exact g_i (within the rounding bound), clipped to its sign rule,
        # which every g_i now meets exactly
        gl, gu = g - m, g + m
        gu = np.where(must_nonpos, np.minimum(gu, 0.0), gu)
        gl = np.where(must_nonneg, np.maximum(gl, 0.0), gl)
        # sup over g' in [gl, gu], z in [lo, up] of g' z: at a corner; an infinite z pairs
        # with g' = 0 only (the clipping above)
        corners = []
        for gv in (gl, gu):
            for zv in (lo, up):
                corners.append(np.where(gv == 0.0, 0.0, gv * zv))
        c = np.max(np.stack(corners), axis=0) if n else np.zeros(0)
        c = np.where(np.isnan(c), -np.inf, c)
        if not np.all(np.isfinite(c)) and np.any(c == np.inf):
            return fail("the bound over the box overflows")
        qy = float(q @ y)
        qsum = float(np.sum(qa))
        if qsum < TINY:  # exact, as for the columns (rounding keeps the sign or gives 0)
            qy = float(sum((Fraction(float(qi)) * Fraction(float(yi))
                            for qi, yi in zip(q, y, strict=True) if qi and yi), Fraction(0)))
        value = qy + float(np.sum(c))
        margin = gamma * (qsum + float(np.sum(np.abs(c))))
    ratio_worst = float(ratio[worst]) if n else 0.0
    if not np.isfinite(value) or not np.isfinite(margin):
        return fail("q^T y overflows", worst, ratio_worst)
    if not value < -margin:
        return FarkasCheck(False, y, value, margin, worst, ratio_worst,
                           f"q^T y bound {value:.3g} is not below -{margin:.3g} (its rounding "
                           f"margin)")
    lcp = bool(np.all(lo == 0) and np.all(np.isinf(up)))
    return FarkasCheck(True, y, value, margin, worst, ratio_worst, "", lcp)


def _sign_violation(g: np.ndarray, m: np.ndarray, must_nonpos: np.ndarray,
                    must_nonneg: np.ndarray) -> tuple[int, np.ndarray]:
    """``(worst, ratio)``: each ``g_i``'s wrong-sign part relative to its rounding bound
    ``m_i`` (0 where the sign is right, inf where it is wrong and ``m_i = 0``: an exact value)
    and the index of the largest (-1 when ``n = 0``)."""
    pos = np.where(must_nonpos, np.maximum(g, 0.0), 0.0)
    neg = np.where(must_nonneg, np.maximum(-g, 0.0), 0.0)
    viol = np.maximum(pos, neg)
    ratio = np.where(viol > 0, viol / np.where(m > 0, m, 1.0), 0.0)
    ratio = np.where((viol > 0) & (m == 0), np.inf, ratio)
    return (int(np.argmax(ratio)) if g.size else -1), ratio


#: Veltkamp's splitting constant for float64 (2^27 + 1): ``x = hi + lo`` exactly, each half
#: of at most 26 significant bits, so the product of two halves is exact (no underflow).
_SPLIT = 134217729.0
#: Partial products below this may have been rounded (subnormal range): exact rationals then.
_PRODUCT_FLOOR = 2.0 ** -1021
#: Columns of M made dense at a time by :func:`_exact_dots` (bounded temporaries).
_BLOCK_ENTRIES = 1 << 20


def _halves(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Veltkamp's split of ``x`` (``|x| <= 1``): ``x = hi + lo`` exactly."""
    c = _SPLIT * x
    hi = c - (c - x)
    return hi, x - hi


def _exact_dots(M: Any, y: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``(M^T y)_j`` for ``j`` in ``cols``, each the exact sum correctly rounded (so its sign is
    exact; a nonzero sum below the double range keeps its sign as +-2^-1074).  ``y`` is
    normalised (``max |y_i| < 1``).  Each column is scaled by a power of two (checked exact),
    every product split into four exact products of halves (Dekker) and the lot summed by
    ``math.fsum`` (correctly rounded); a column where a scaling or a partial product could
    lose bits is summed in exact rationals (:func:`_exact_column`)."""
    out = np.empty(cols.size)
    rows = np.flatnonzero(y)
    yh, yl = _halves(y[rows])
    step = max(1, _BLOCK_ENTRIES // max(1, rows.size))
    for start in range(0, cols.size, step):
        block = cols[start:start + step]
        if hasattr(M, "toarray"):
            A = M[rows, :][:, block].toarray()
        else:
            A = np.asarray(M, dtype=np.float64)[np.ix_(rows, block)]
        for k, j in enumerate(block.tolist()):
            a = A[:, k]
            amax = float(np.max(np.abs(a))) if a.size else 0.0
            if amax == 0.0:
                out[start + k] = 0.0
                continue
            e = int(np.frexp(amax)[1])
            s = np.ldexp(a, -e)
            ah, al = _halves(s)
            parts = np.concatenate((ah * yh, ah * yl, al * yh, al * yl))
            live = np.abs(parts[parts != 0.0])
            if not np.array_equal(np.ldexp(s, e), a) or (live.size and live.min() <
                                                         _PRODUCT_FLOOR):
                out[start + k] = _exact_column(M, y, j)[0]
                continue
            v = math.fsum(parts.tolist())
            g = math.ldexp(v, e)
            out[start + k] = g if g != 0.0 or v == 0.0 else math.copysign(2.0 ** -1074, v)
    return out


def _exact_column(M: Any, y: np.ndarray, i: int) -> tuple[float, float]:
    """``((M^T y)_i, (|M|^T |y|)_i)`` from exact rational sums, each correctly rounded; a
    nonzero ``(M^T y)_i`` below the double range keeps its sign as +-2^-1074 (the sign test
    needs it)."""
    col = M[:, [i]].toarray().ravel() if hasattr(M, "toarray") else np.asarray(M[:, i])
    terms = [Fraction(float(mj)) * Fraction(float(yj)) for mj, yj in zip(col, y, strict=True)
             if mj and yj]
    g = sum(terms, Fraction(0))
    a = sum((abs(t) for t in terms), Fraction(0))
    gf, af = float(g), float(a)
    if g != 0 and gf == 0.0:
        gf = 2.0 ** -1074 if g > 0 else -(2.0 ** -1074)
    return gf, af


def _dense(M: Any) -> np.ndarray:
    return M.toarray() if hasattr(M, "toarray") else np.asarray(M, dtype=np.float64)


def _project(y: np.ndarray, lo: np.ndarray, up: np.ndarray, M: Any = None,
             q: np.ndarray | None = None) -> np.ndarray:
    """``y`` with its entries of the wrong sign set to 0, and the negligible ones: with ``M``
    and ``q``, an entry whose every term ``|y_i M_ij|`` is below 2^-45 of its column's
    ``(|M|^T |y|)_j`` and whose ``|y_i q_i|`` is below 2^-45 of ``|q|^T |y|`` (the same entries
    on any row and column scaling of the problem: a Farkas vector mapped back from an
    equilibrated copy may span 2^60 and more); without them, the entries below 2^-45 of
    the largest."""
    lower_only, upper_only = sides(lo, up)
    boxed = np.isfinite(lo) & np.isfinite(up)
    y = np.where((lower_only & (y < 0)) | (upper_only & (y > 0)) | boxed, 0.0, y)
    big = float(np.max(np.abs(y))) if y.size else 0.0
    if M is None or q is None or not big:
        return np.where(np.abs(y) <= 2.0 ** -45 * big, 0.0, y)
    with np.errstate(all="ignore"):
        ay = np.abs(y)
        A = abs(M)
        col = np.asarray(A.T @ ay).ravel()
        qy = float(np.abs(q) @ ay)
        if not (np.all(np.isfinite(col)) and np.isfinite(qy)):
            return np.where(np.abs(y) <= 2.0 ** -45 * big, 0.0, y)
        inv = np.where(col > 0, 1.0 / np.where(col > 0, col, 1.0), 0.0)
        if hasattr(A, "multiply"):  # sparse: the largest share of each row
            share = np.asarray(A.multiply(inv[None, :]).max(axis=1).toarray()).ravel() * ay
        else:
            share = (np.max(A * inv[None, :], axis=1) if A.size else np.zeros(0)) * ay
        qshare = np.abs(q) * ay
        small = (share <= 2.0 ** -45) & (qshare <= 2.0 ** -45 * qy)
    return np.where(small, 0.0, y)


#: How far :func:`_refine` pushes the nearly active ``g_i`` past zero, relative to
#: ``(|M|^T |y|)_i``: far above rounding (the exact check then decides by the computed sign),
#: far below any ``q^T y`` worth proving.
PUSH = 2.0 ** -30


def _refine(M: np.ndarray, y: np.ndarray, lo: np.ndarray, up: np.ndarray,
            push: float = 0.0) -> np.ndarray:
    """One least-squares correction of ``y``'s support so that the sign constraints on
    ``g = M^T y`` that are nearly active (``|g_i|`` below 2^-20 of ``(|M|^T |y|)_i``) hold with
    equality to working accuracy, or (``push > 0``) with ``g_i = -+push (|M|^T |y|)_i``, on the
    side of zero its sign rule asks for (a ray or an LP vertex carries its own rounding or the
    LP's feasibility tolerance; the exact check of :func:`check_farkas` accepts an equality
    only where the data make it exact, while a robustly infeasible problem has proofs strictly
    inside the sign rules).  Floating-point exceptions are quiet (data near the float64 range
    overflow the sums): the corrected vector passes :func:`check_farkas` or is not used."""
    S = np.flatnonzero(y)
    if S.size == 0:
        return y
    with np.errstate(all="ignore"):
        g = M.T @ y
        a = np.abs(M).T @ np.abs(y)
        T = np.flatnonzero(np.abs(g) <= 2.0 ** -20 * a)
        if T.size == 0:
            return y
        # target: 0, or pushed to the side its rule asks for (free rows: 0)
        side = np.where(np.isinf(up[T]) & ~np.isinf(lo[T]), -1.0,
                        np.where(np.isinf(lo[T]) & ~np.isinf(up[T]), 1.0, 0.0))
        target = push * side * a[T]
        A = M[np.ix_(S, T)].T
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = np.linalg.lstsq(A, A @ y[S] - target, rcond=None)[0]
        out = y.copy()
        out[S] = y[S] - d
    return _project(out, lo, up, M)


#: Largest denominator :func:`_rational` tries.
RATIONAL_DENOMINATOR = 2 ** 20


def _rational(y: np.ndarray) -> np.ndarray | None:
    """``y`` (scaled so that its largest entry is 1) replaced by the nearest fractions with
    denominators up to :data:`RATIONAL_DENOMINATOR`, brought to integers (exact doubles), or
    None when they do not fit in 53 bits: on data of small integers or simple fractions, the
    vector whose ``M^T y`` has exact zeros where a floating-point ray has only rounding."""
    big = float(np.max(np.abs(y))) if y.size else 0.0
    if not big or not np.all(np.isfinite(y)):
        return None
    fr = [Fraction(float(v) / big).limit_denominator(RATIONAL_DENOMINATOR) for v in y]
    den = 1
    for f in fr:
        den = den * f.denominator // math.gcd(den, f.denominator)
    ints = [f.numerator * (den // f.denominator) for f in fr]
    if max(abs(i) for i in ints) >= 2 ** 53:
        return None
    return np.array(ints, dtype=np.float64)


def _single_rows(M: Any, q: np.ndarray, lo: np.ndarray, up: np.ndarray) -> Iterable[np.ndarray]:
    """Unit vectors ``e_i`` of LCP-type rows that are infeasible on their own (``M_i <= 0`` and
    ``q_i < 0`` on the nonnegative orthant): the cheapest proofs."""
    if not (np.all(lo == 0) and np.all(np.isinf(up))):
        return
    if hasattr(M, "toarray"):  # sparse: the row maxima, implicit zeros included
        rowmax = np.asarray(M.max(axis=1).toarray()).ravel()
    else:
        rowmax = np.max(M, axis=1) if M.size else np.zeros(0)
    rows = np.flatnonzero((q < 0) & (rowmax <= 0))
    for i in rows[np.argsort(q[rows])][:1]:
        y = np.zeros(q.shape[0])
        y[i] = 1.0
        yield y


def _lp_candidate(problem: Any) -> np.ndarray | None:
    """A Farkas vector from a linear program (HiGHS), or None: minimise the bound
    ``q^T y + sum_i max(g_i l_i, g_i u_i)`` over ``y`` in ``[-1, 1]^n`` with the sign rules of the
    module docstring, on the equilibrated problem (powers of two: exact), mapped back."""
    from scipy.optimize import linprog  # scipy is imported on first use (start-up budget)

    from lcpcli.analysis.scaling import equilibrate

    scaling = equilibrate(problem, False)
    p = scaling.apply(problem) if scaling is not None else problem
    M, q = _dense(p.M), p.q
    lo, up = p.bounds()
    n = q.shape[0]
    lower_only, upper_only = sides(lo, up)
    boxed = np.isfinite(lo) & np.isfinite(up)
    nb = int(np.sum(boxed))
    # variables: y (n), then t (one per boxed index: t_j >= g_j l_j, t_j >= g_j u_j)
    lo_c = np.where(lower_only, lo, 0.0)
    up_c = np.where(upper_only, up, 0.0)
    c = np.concatenate([q + M @ (lo_c + up_c), np.ones(nb)])
    rows, rhs = [], []
    must_nonpos = np.isinf(up) & ~np.isinf(lo)   # g_i <= 0
    must_nonneg = np.isinf(lo) & ~np.isinf(up)   # g_i >= 0
    free = np.isinf(lo) & np.isinf(up)           # g_i = 0
    Mt = M.T
    pad = np.zeros((n, nb))
    if np.any(must_nonpos):
        rows.append(np.hstack([Mt[must_nonpos], pad[must_nonpos]]))
        rhs.append(np.zeros(int(np.sum(must_nonpos))))
    if np.any(must_nonneg):
        rows.append(np.hstack([-Mt[must_nonneg], pad[must_nonneg]]))
        rhs.append(np.zeros(int(np.sum(must_nonneg))))
    if nb:
        B = np.flatnonzero(boxed)
        eye = np.eye(nb)
        rows.append(np.hstack([Mt[B] * lo[B][:, None], -eye]))
        rows.append(np.hstack([Mt[B] * up[B][:, None], -eye]))
        rhs += [np.zeros(nb), np.zeros(nb)]
    A_ub = np.vstack(rows) if rows else None
    b_ub = np.concatenate(rhs) if rhs else None
    A_eq = np.hstack([Mt[free], pad[free]]) if np.any(free) else None
    b_eq = np.zeros(int(np.sum(free))) if np.any(free) else None
    bounds = [(0.0, 1.0) if lower_only[i] else (-1.0, 0.0) if upper_only[i]
              else (0.0, 0.0) if boxed[i] else (-1.0, 1.0) for i in range(n)]
    bounds += [(None, None)] * nb
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds,
                          method="highs")
    except (ValueError, MemoryError):
        return None
    if res.status != 0 or res.x is None or not res.fun < 0:
        return None
    y = np.asarray(res.x[:n], dtype=np.float64)
    return scaling.farkas_back(y) if scaling is not None else y


def preload_proof_search(problem: Any) -> None:
    """The modules :func:`prove_infeasible` with ``search=True`` imports for ``problem`` (the
    linear program's scipy.optimize, when it may run), for a caller that times them apart."""
    if 0 < problem.n <= LP_MAX_N:
        import scipy.optimize  # noqa: F401


def prove_infeasible(problem: Any, candidates: Iterable[Any] = (), *,
                     search: bool = False) -> FarkasCheck | None:
    """A passing :class:`FarkasCheck` for ``problem``, or None; see the module docstring.

    ``candidates``: vectors suggested by a method (in the units of ``w``); ``search``: also
    solve the linear program (for ``n <= LP_MAX_N``) when no candidate passes.
    """
    M, q = problem.M, problem.q
    lo, up = problem.bounds()
    n = problem.n
    if n == 0:
        return None
    last: FarkasCheck | None = None
    tries: list[Any] = [np.asarray(c, dtype=np.float64).ravel() for c in candidates
                        if c is not None]
    tries += list(_single_rows(M, q, lo, up))
    lp_done = False
    while True:
        for raw in tries:
            if raw.shape[0] != n or not np.all(np.isfinite(raw)):
                continue
            y = _project(raw, lo, up, M, q)
            if not np.any(y):
                continue
            last = check_farkas(M, q, lo, up, y)
            if last.passed:
                return last
            if problem.sparse and n > LP_MAX_N:
                continue
            dense = _dense(M)
            # strictly inside the sign rules first, then on them, then on them exactly
            # (the nearest vector of small rationals: exact zeros of M^T y on exact data)
            on = _refine(dense, last.y, lo, up)
            for y2 in (_refine(dense, last.y, lo, up, PUSH), on, _rational(on)):
                if y2 is not None and np.any(y2) and np.all(np.isfinite(y2)):
                    again = check_farkas(M, q, lo, up, y2)
                    if again.passed:
                        return again
        if lp_done or not search or n > LP_MAX_N:
            return None
        lp_done = True
        found = _lp_candidate(problem)
        if found is None:
            return None
        tries = [found]


def search_proof(problem: Any, candidates: Iterable[Any] = (),
                 scaling: Any = None) -> FarkasCheck | None:
    """:func:`prove_infeasible` with its linear program (up to ``n =``
    :data:`UNHINTED_LP_MAX_N`; above it the candidates alone), on the problem as given and,
    when that finds nothing, on its equilibrated copy (``scaling``, else Ruiz's two-sided scaling,
    Curtis and Reid's where Ruiz leaves entries far apart), whose vector, mapped back
    (``y = D_r y~``), is checked on the problem as given: the linear program and the
    least-squares corrections are not scale-free, the check is."""
    from lcpcli.analysis.scaling import GEOMETRIC_SPREAD, equilibrate, geometric, spread

    # extreme data may overflow a scaled copy, the linear program's or a vector mapped back:
    # quietly (a non-finite candidate is skipped, the check decides)
    with np.errstate(all="ignore"):
        found = prove_infeasible(problem, candidates, search=problem.n <= UNHINTED_LP_MAX_N)
        if found is not None or problem.n == 0 or problem.n > UNHINTED_LP_MAX_N:
            return found
        if scaling is None:
            scaling = equilibrate(problem, False)
            if spread(problem, scaling) > GEOMETRIC_SPREAD:
                scaling = geometric(problem, False) or scaling
        if scaling is None:
            return None
        scaled = prove_infeasible(scaling.apply(problem), search=True)
        back = None if scaled is None else scaling.farkas_back(scaled.y)
        return None if back is None else prove_infeasible(problem, [back])


def confirm(problem: Any, outcome: Any) -> FarkasCheck | None:
    """The proof behind an outcome that claims infeasibility (``Outcome.proven_infeasible``):
    its ``info["farkas_y"]`` re-checked on ``problem`` (the user's, unscaled), else a search
    (:func:`prove_infeasible` with the linear program).  None: no proof, hence no
    ``no_solution``."""
    if not outcome.proven_infeasible:
        return None
    y = outcome.info.get("farkas_y")
    if y is not None:
        lo, up = problem.bounds()
        got = check_farkas(problem.M, problem.q, lo, up, np.asarray(y, dtype=np.float64))
        if got.passed:
            return got
    return prove_infeasible(problem, () if y is None else (y,), search=True)
