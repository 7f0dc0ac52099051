"""Murty's least-index principal pivoting step by step: a numpy replica of the compiled kernel.

Dictionary ``x_B = q' + M' x_N`` of ``w = M z + q`` without an artificial variable: row ``i``
always holds ``w_i`` or ``z_i`` and column ``i`` its complement, so a principal pivot on
``(r, r)`` exchanges ``w_r`` and ``z_r``.  The rule: the least ``r`` with ``q'_r < 0``
(below ``-neg_tol ||q||_inf``) pivots, on the diagonal entry ``M'_rr`` (which must be
positive: a principal pivot transform of a P-matrix has a positive diagonal).  Same
operations and tolerances as the kernel, hence the same pivots.

In Dai & Drumwright's terms every basis is complementary: ``alpha = beta`` is the set of ``i`` with
``z_i`` basic, and ``q'`` is eqs (2)-(3) with ``M^{alpha alpha}``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.solvers.trace.tableau import code_name, num, pivot_update, scalar, state_record

# Status codes: the compiled kernel's values (the tests check they agree).
OK = 0
LIMIT = 1
BAD_PIVOT = 2

#: The ``end`` of the last trace entry per status: ``solved`` (no basic variable is negative
#: by the method's rule, so this complementary basis solves the LCP), ``limit`` (the pivot
#: limit stopped it), ``bad_pivot`` (a pivot not positive beyond the tolerance).
END = {OK: "solved", LIMIT: "limit", BAD_PIVOT: "bad_pivot"}

#: Up to this n the trace holds the whole tableau of each state.
TABLEAU_MAX_N = 8


def murty_traced(M: np.ndarray, q: np.ndarray, max_iter: int, piv_tol: float, neg_tol: float,
                 basic: np.ndarray) -> tuple[Any, ...]:
    """Run the least-index rule like the kernel; return ``(status, z, pivots, bad, trace)``.

    ``basic`` (codes: ``i`` = ``w_{i+1}``, ``n + i`` = ``z_{i+1}``) is the starting
    complementary basis and is updated in place, as in the kernel.  ``trace[0]`` is the
    starting state; ``trace[k]`` is principal pivot ``k``: the row, the exchanged pair, the
    pivot element ``M'_rr``, the index sets and ``q'`` after the pivot.
    """
    n = q.shape[0]
    kind = object if np.asarray(M).dtype == object else np.float64  # fractions: exact
    T = np.array(M, dtype=kind, copy=True)
    qb = np.array(q, dtype=kind, copy=True)
    nonbasic = np.empty(n, dtype=np.int64)

    def sync_nonbasic() -> None:
        for i in range(n):
            nonbasic[i] = i if basic[i] >= n else n + i

    def state() -> dict[str, Any]:
        sync_nonbasic()
        out = state_record(T, qb, basic, nonbasic, n, TABLEAU_MAX_N)
        alpha = [i + 1 for i in range(n) if basic[i] >= n]
        out["alpha"] = alpha
        out["alpha_bar"] = [i + 1 for i in range(n) if basic[i] < n]
        return out

    warm = 0
    for i in range(n):
        if basic[i] >= n:
            basic[i] = i
            if abs(T[i, i]) <= piv_tol:
                return BAD_PIVOT, np.zeros(n), 0, i, [
                    {"kind": "principal", "pivot": 0, "rule": "bad_start",
                     "reason": f"warm start: the diagonal entry of row {i + 1} is "
                               f"{num(T[i, i])}, no principal pivot possible", **state()}]
            pivot_update(T, qb, i, i)
            basic[i] = n + i
            warm += 1
    start = {"kind": "principal", "pivot": 0, "row": None, "entering": None, "leaving": None,
             "pivot_element": None, "rule": "start",
             "reason": ("starting basis: w (z = 0)" if warm == 0 else
                        f"starting basis from the warm start: {warm} principal pivots made"),
             **state()}
    trace: list[dict[str, Any]] = [start]
    qscale = float(np.max(np.abs(q))) if n else 0.0
    pivots = 0
    status = LIMIT
    bad = -1
    while pivots < max_iter:
        neg = np.flatnonzero(qb < -neg_tol * qscale)
        if neg.size == 0:
            status = OK
            break
        r = int(neg[0])
        p = T[r, r]
        scale = float(np.max(np.abs(T[r, :])))
        entering, leaving = code_name(nonbasic_of(basic, r, n), n), code_name(basic[r], n)
        if not p > piv_tol * max(scale, 1e-300):
            status = BAD_PIVOT
            bad = r
            # exact (fractions) and not positive: a principal minor ratio <= 0, so not P;
            # in floating point only the tolerance was shown
            why_not_p = (" (M is not a P-matrix)" if kind is object and not p > 0 else
                         " beyond the pivot tolerance (a P-matrix has positive pivots only)")
            trace.append({"kind": "principal", "pivot": pivots + 1, "row": r + 1,
                          "entering": entering, "leaving": leaving,
                          "pivot_element": {"row": r + 1, "column": entering, "value": scalar(p)},
                          "rule": "bad_pivot",
                          "reason": (f"least index with q' < 0 is row {r + 1} ({leaving} = "
                                     f"{num(qb[r])}); its diagonal entry M'_rr = {num(p)} is not "
                                     f"positive{why_not_p}: no pivot is made"), **state()})
            break
        value = qb[r]
        pivot_update(T, qb, r, r)
        basic[r] = n + r if basic[r] < n else r
        pivots += 1
        trace.append({"kind": "principal", "pivot": pivots, "row": r + 1,
                      "entering": entering, "leaving": leaving,
                      "pivot_element": {"row": r + 1, "column": entering, "value": scalar(p)},
                      "rule": "least_index",
                      "reason": (f"row {r + 1} is the least index with q' < 0 ({leaving} = "
                                 f"{num(value)}): {leaving} and {entering} exchange (principal "
                                 f"pivot on the diagonal entry M'_rr = {num(p)})"), **state()})
    # how the method ended, on its last entry: the renderers state it, they do not re-decide it
    trace[-1]["end"] = END[status]
    z = np.zeros(n)
    for i in range(n):
        if basic[i] >= n:
            z[i] = max(qb[i], 0.0)
    return status, z, pivots, bad, trace


def nonbasic_of(basic: np.ndarray, r: int, n: int) -> int:
    """The code of the complement of row ``r``'s basic variable (the column it pivots on)."""
    return r if basic[r] >= n else n + r
