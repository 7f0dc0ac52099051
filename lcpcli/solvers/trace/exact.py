"""Exact traces (``--exact``): the replicas run on fractions, as the textbooks print them.

Murty's and Cottle-Pang-Stone's examples use small integer data, and every tableau of a pivoting
method is then made of rationals (``4/3``, not ``1.33333``).  The replicas of
:mod:`lcpcli.solvers.trace` are generic over the number type, so the same code run on object
arrays of :class:`fractions.Fraction` gives the exact trace; this module decides when the data
allow it (:func:`rational_array`, :func:`exact_data`), runs the replicas that way
(:func:`exact_trace`), and recomputes the numbers of a principal pivoting transform
(:func:`exact_transform`) and of a complementary cone (:func:`exact_cone`) exactly.

The trace is a teaching view: the answer, its verdict and its certificate always come from the
ordinary floating-point solve.  Tolerances keep their meaning (exact zeros are zeros).
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction
from typing import Any

import numpy as np

#: Automatic exact traces: at most this many variables ...
AUTO_MAX_N = 8
#: ... and every entry a fraction with a denominator up to this ...
MAX_DENOMINATOR = 1000
#: ... and a magnitude up to this.
MAX_ABS = 1000
#: The methods whose trace can be exact (pivoting methods; sweeps are iterative).
EXACT_METHODS = ("lemke", "lemke-tableau", "lemke-revised", "murty", "dantzig")


def rational(x: float, max_den: int = MAX_DENOMINATOR) -> Fraction | None:
    """The fraction with denominator ``<= max_den`` whose float is exactly ``x`` (``0.1`` ->
    ``1/10``, ``4/3`` read as ``1.3333333333333333`` -> ``4/3``), or None."""
    if not np.isfinite(x):
        return None
    fr = Fraction(float(x)).limit_denominator(max_den)
    return fr if float(fr) == float(x) else None


def rational_array(a: Any, max_den: int = MAX_DENOMINATOR,
                   max_abs: float = MAX_ABS) -> np.ndarray | None:
    """``a`` as an object array of fractions when every entry is such a fraction of magnitude
    at most ``max_abs``; otherwise None."""
    arr = np.asarray(a, dtype=np.float64)
    out = np.empty(arr.shape, dtype=object)
    for idx, x in np.ndenumerate(arr):
        fr = rational(float(x), max_den)
        if fr is None or abs(fr) > max_abs:
            return None
        out[idx] = fr
    return out


def _bounds(a: Any) -> np.ndarray | None:
    """Box bounds as fractions, the infinite ones kept as ``inf``."""
    arr = np.asarray(a, dtype=np.float64)
    out = np.empty(arr.shape, dtype=object)
    for idx, x in np.ndenumerate(arr):
        if np.isinf(x):
            out[idx] = float(x)
            continue
        fr = rational(float(x))
        if fr is None or abs(fr) > MAX_ABS:
            return None
        out[idx] = fr
    return out


@dataclasses.dataclass
class ExactData:
    """A problem's data as fractions (``lo``/``up``: bounds, infinite ones as floats)."""

    M: np.ndarray
    q: np.ndarray
    lo: np.ndarray
    up: np.ndarray


def exact_data(problem: Any, max_n: int | None = None, max_den: int = MAX_DENOMINATOR,
               max_abs: float = MAX_ABS) -> ExactData | None:
    """The problem's ``M``, ``q`` and bounds as fractions, or None when an entry is not a
    fraction with a denominator up to ``max_den`` and a magnitude up to ``max_abs`` (or
    ``n > max_n``)."""
    if max_n is not None and problem.n > max_n:
        return None
    M = rational_array(problem.dense_M(), max_den, max_abs)
    q = rational_array(problem.q, max_den, max_abs)
    if M is None or q is None:
        return None
    lo, up = problem.bounds()
    elo, eup = _bounds(lo), _bounds(up)
    if elo is None or eup is None:
        return None
    return ExactData(M, q, elo, eup)


#: With ``--exact`` given: any n, denominators and magnitudes up to these.
FLAG_MAX_DENOMINATOR = 10**6
FLAG_MAX_ABS = 10**9


def wants_exact(problem: Any, flag: bool | None) -> ExactData | None:
    """The exact data when ``--exact`` is given (``flag`` True: any n, denominators up to
    :data:`FLAG_MAX_DENOMINATOR`), or by default (``flag`` None) when the problem is small
    (``n <= AUTO_MAX_N``, denominators and magnitudes up to 1000); None otherwise
    (``--no-exact``, or data that are not such fractions)."""
    if flag is False:
        return None
    if flag:
        return exact_data(problem, None, FLAG_MAX_DENOMINATOR, FLAG_MAX_ABS)
    return exact_data(problem, AUTO_MAX_N)


# ------------------------------------------------------------------------------ algebra
def gauss_jordan(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray | None, Any]:
    """``(A^-1 B, det A)`` in exact arithmetic (``None`` and 0 when ``A`` is singular)."""
    n = A.shape[0]
    T = np.concatenate([np.array(A, dtype=object), np.array(B, dtype=object)], axis=1)
    det: Any = Fraction(1)
    for c in range(n):
        piv = next((r for r in range(c, n) if T[r, c] != 0), None)
        if piv is None:
            return None, Fraction(0)
        if piv != c:
            T[[c, piv]] = T[[piv, c]]
            det = -det
        p = T[c, c]
        det *= p
        T[c] = T[c] / p
        for r in range(n):
            if r != c and T[r, c] != 0:
                T[r] = T[r] - T[r, c] * T[c]
    return T[:, n:], det


def inverse(A: np.ndarray) -> np.ndarray:
    """``A^-1`` exactly (raises :class:`numpy.linalg.LinAlgError` when singular)."""
    n = A.shape[0]
    eye = np.array([[Fraction(int(i == j)) for j in range(n)] for i in range(n)], dtype=object)
    inv, _ = gauss_jordan(A, eye.reshape(n, n))
    if inv is None:
        raise np.linalg.LinAlgError("singular matrix")
    return inv


def solve(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``A^-1 b`` exactly, or None when ``A`` is singular."""
    x, _ = gauss_jordan(A, np.asarray(b, dtype=object).reshape(-1, 1))
    return None if x is None else x[:, 0]


# ------------------------------------------------------------------------------ traces
def exact_trace(problem: Any, method: str, data: ExactData, *, covering: Any = None,
                max_iter: int | None = None, z0: Any = None) -> list[dict[str, Any]]:
    """The trace of ``method`` (one of :data:`EXACT_METHODS`) run on fractions.

    Same replica, same rule, same tolerances as the floating-point trace, the numbers exact.
    """
    from lcpcli.core.tolerances import PIVOT_TOL, TIE_TOL

    n = problem.n
    if method in ("lemke", "lemke-tableau", "lemke-revised"):
        from lcpcli.solvers.methods.lemke import covering_vector, default_max_iter
        from lcpcli.solvers.options import vector_option
        from lcpcli.solvers.trace.lemke import lemke_traced

        d = covering_vector(n, vector_option(covering))
        ed = rational_array(np.ones(n) if d is None else d)
        if ed is None:
            raise ValueError("the covering vector is not made of small fractions")
        *_, trace = lemke_traced(data.M, data.q, ed, max_iter or default_max_iter(n),
                                 PIVOT_TOL, TIE_TOL)
        return trace
    if method == "murty":
        from lcpcli.solvers.methods.lemke import default_max_iter
        from lcpcli.solvers.methods.murty import NEG_TOL
        from lcpcli.solvers.support import start_point
        from lcpcli.solvers.trace.murty import murty_traced

        basic = np.arange(n, dtype=np.int64)
        if z0 is not None and not (n and min(data.q) >= 0):  # q >= 0: z = 0 (as the method)
            start = start_point(problem, z0)
            basic = np.where(start > 0, basic + n, basic).astype(np.int64)
        *_, trace = murty_traced(data.M, data.q, max_iter or default_max_iter(n), PIVOT_TOL,
                                 NEG_TOL, basic)
        return trace
    if method == "dantzig":
        from lcpcli.solvers.methods.dantzig import processing_order
        from lcpcli.solvers.trace.dantzig import dantzig_traced

        lo, up = problem.bounds()
        *_, trace = dantzig_traced(data.M, data.q, data.lo, data.up, processing_order(lo, up),
                                   max_iter or max(1000, 50 * n))
        return trace
    raise ValueError(f"no exact trace for method {method!r} (exact: {', '.join(EXACT_METHODS)})")


def same_pivots(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    """Whether two traces make the same steps (entering and leaving variables, events)."""
    def steps(t: list[dict[str, Any]]) -> list[tuple[Any, ...]]:
        return [(s.get("entering"), s.get("leaving"), s.get("event"), s.get("rule"))
                for s in t]

    return steps(a) == steps(b)


# ------------------------------------------------------------------------------ pivot, cones
def exact_transform(t: Any, Maug: np.ndarray, q: np.ndarray) -> Any:
    """The transform ``t`` (:class:`lcpcli.analysis.pivoting.PivotTransform`) with its numbers
    recomputed in fractions from ``Maug`` and ``q`` (object arrays): the blocks, ``q'`` (eqs
    2-3), the driving column (eqs 5-8) and the full ``M'``, by the same formulas."""
    n = t.n
    alpha, beta, abar = list(t.alpha), list(t.beta), list(t.alpha_bar)
    M_ab = Maug[np.ix_(alpha, beta)]
    M_abar_b = Maug[np.ix_(abar, beta)]
    q_a, q_abar = q[alpha], q[abar]

    def lsolve(b: np.ndarray) -> np.ndarray:
        if not alpha:
            return np.zeros(0, dtype=object)
        x = solve(M_ab, b)
        if x is None:  # principal_pivot has already refused a singular block
            raise np.linalg.LinAlgError("M^{alpha beta} is singular")
        return x

    def column(var: Any) -> np.ndarray:
        col = np.empty(n, dtype=object)
        if var[0] == "w":  # eqs (5)-(6)
            e = np.array([Fraction(int(k == alpha.index(var[1]))) for k in range(len(alpha))],
                         dtype=object)
            xb = lsolve(e)
            col[t.beta_prime] = xb
            col[t.alpha_bar_prime] = M_abar_b.dot(xb) if abar else xb[:0]
        else:  # eqs (7)-(8)
            g = Maug[:, var[1]]
            xb = -lsolve(g[alpha])
            col[t.beta_prime] = xb
            col[t.alpha_bar_prime] = g[abar] + (M_abar_b.dot(xb) if len(xb) else 0)
        return col

    qp = np.empty(n, dtype=object)
    qb = -lsolve(q_a)  # eq (2)
    qp[t.beta_prime] = qb
    qp[t.alpha_bar_prime] = q_abar + (M_abar_b.dot(qb) if len(qb) else 0)  # eq (3)
    out = dataclasses.replace(t, M_ab=M_ab, M_abar_b=M_abar_b, q_a=q_a, q_abar=q_abar,
                              q_prime=qp)
    if t.driving is not None:
        out.driving_column = column(t.driving)
        if t.driving[0] == "z":
            g = Maug[:, t.driving[1]]
            out.g_alpha, out.g_alpha_bar = g[alpha], g[abar]
    if t.full is not None:
        out.full = (np.column_stack([column(v) for v in t.independent]) if n
                    else np.zeros((0, 1), dtype=object))
    return out


def complementary(M: np.ndarray, code: int) -> np.ndarray:
    """The complementary matrix ``A_r`` in fractions: column ``I_j`` for ``w_j`` basic (bit j
    of ``code`` clear), ``-M_j`` for ``z_j`` basic (Murty's "Linear Complementarity, Linear and
    Nonlinear Programming", chapter 1)."""
    n = M.shape[0]
    A = np.empty((n, n), dtype=object)
    for j in range(n):
        A[:, j] = -M[:, j] if (code >> j) & 1 else [Fraction(int(i == j)) for i in range(n)]
    return A


def exact_cone(M: np.ndarray, q: np.ndarray, code: int) -> tuple[Any, np.ndarray | None]:
    """``(det A_r, y)`` with ``A_r y = q`` exactly (``y`` None for a singular cone)."""
    A = complementary(M, code)
    y, det = gauss_jordan(A, np.asarray(q, dtype=object).reshape(-1, 1))
    return det, (None if y is None else y[:, 0])


def exact_enumeration(res: Any, data: ExactData) -> Any:
    """An enumeration (:class:`lcpcli.analysis.enumeration.Enumeration`) with its numbers in
    fractions: ``det A_r`` and ``y`` of every nonsingular cone listed, and each solution's
    ``z``, ``w`` from its first nonsingular cone.  Singular cones keep their floating-point
    values (a point of the cone found by linear programming); the verdict is unchanged."""
    M, q = data.M, data.q
    n = M.shape[0]
    cones = []
    for c in res.cones:
        det, y = exact_cone(M, q, c.code)
        cones.append(dataclasses.replace(c, det=det, y=c.y if y is None else y))
    sols = []
    for sol in res.solutions:
        for code in sol.cones:
            _, y = exact_cone(M, q, code)
            if y is None:
                continue
            z = np.array([y[j] if (code >> j) & 1 else Fraction(0) for j in range(n)],
                         dtype=object)
            sol = dataclasses.replace(sol, z=z, w=M.dot(z) + q)
            break
        sols.append(sol)
    return dataclasses.replace(res, cones=cones, solutions=sols)


__all__ = ["AUTO_MAX_N", "EXACT_METHODS", "ExactData", "complementary", "exact_cone",
           "exact_data", "exact_enumeration", "exact_trace", "exact_transform", "gauss_jordan",
           "inverse", "rational", "rational_array", "same_pivots", "solve", "wants_exact"]
