"""Lemke's method step by step: a numpy replica of the compiled tableau kernel.

Same tableau, same pivot rule (initial pivot, lexicographic minimum ratio with the same
tolerances, ``z0`` preferred on ties), same floating-point operations in the same order, so
the pivot sequence is the compiled method's; in addition every pivot is recorded for
``lcpcli solve --method lemke --trace``.  O(n^2) numpy work per pivot: meant for teaching and
debugging, not for speed.  Nothing here imports the compiled kernels.

Dictionary ``x_B = q' + M' x_N`` of ``w = q + M z + d z0`` (``d`` the covering vector).
Variable codes as in the kernel: ``0..n-1`` = ``w1..wn``, ``n..2n-1`` = ``z1..zn``,
``2n`` = ``z0``.  The trace (see :func:`lemke_traced`) starts with the initial tableau (basis
``w``) and has one entry per pivot.
"""

from __future__ import annotations

from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np

from lcpcli.analysis.pivoting import ARTIFICIAL
from lcpcli.solvers.trace.tableau import (
    as_numbers,
    code_name,
    num,
    pivot_update,
    scalar,
    state_record,
)

# Status codes: the compiled kernel's values (tests/solvers/test_trace.py checks they agree).
OK = 0
RAY = 1
MAX_ITER = 2
TRIVIAL = 3

#: Up to this n the trace holds the whole tableau of each state; above it q' and the column.
TABLEAU_MAX_N = 8
#: q' entries below this fraction of max(q') count as 0 in the ratio test (the kernel's).
ZERO_Q = 1e-13
#: Relative tolerance of the lexicographic comparison, with a floor at the identity scale.
LEX_TOL = 1e-10


def ratio_formula(entering: str, piv_tol: float, tie_tol: float) -> str:
    """The minimum-ratio test in the dictionary's signs (the column ``c`` of ``entering``)."""
    return (f"{entering} rises to t = min q'_i / (-c_i) over the rows with "
            f"c_i < -{piv_tol:g} max|c| (c = column of {entering}; q'_i below "
            f"{ZERO_Q:g} max q' counts as 0; ratios within {tie_tol:g} (relative) of the "
            f"minimum tie)")


def ratio_formula_murty(entering: str, piv_tol: float, tie_tol: float) -> str:
    """The same test in the signs of Murty's tableau (``a = -c`` is the entering column there)."""
    return (f"{entering} rises to t = min q_i / a_i over the rows with a_i > {piv_tol:g} max|a| "
            f"(a = column of {entering}; q_i below {ZERO_Q:g} max q counts as 0; ratios "
            f"within {tie_tol:g} (relative) of the minimum tie)")


def initial_formula_murty(tie_tol: float) -> str:
    """The first pivot in Murty's tableau, where the column of ``z0`` is ``-d``."""
    return (f"{ARTIFICIAL} enters at level t = max(-q_i / d_i) over the rows with q_i < 0; the "
            f"row with the most negative q_i / d_i pivots, on the entry -d_i of the "
            f"{ARTIFICIAL} column (ties within {tie_tol:g}: the last row)")


def initial_formula(tie_tol: float) -> str:
    """The rule of the first pivot, which brings in ``z0``."""
    return (f"{ARTIFICIAL} rises to t = max(-q_i / d_i) over the rows with q_i < 0, the level "
            f"at which every w_i = q_i + d_i {ARTIFICIAL} >= 0; that row leaves (ties within "
            f"{tie_tol:g}: the last row, the lexicographic rule for q + (eps, ..., eps^n))")


def ratio_test(col: np.ndarray, qb: np.ndarray, basis: list[str], entering: str,
               piv_tol: float, tie_tol: float) -> dict[str, Any]:
    """Lemke's minimum-ratio test on the entering column ``col`` (``x_B = qb + col t``).

    Exactly the kernel's rule and tolerances.  Returns ``formula``, ``rows`` (every row: its
    ratio, or why it cannot block), ``min_ratio`` (``None``: no row blocks, a ray),
    ``tied_rows`` (0-based rows at the minimum, in row order) and ``z0_row`` (the row of
    ``z0`` among them, -1 if none).
    """
    col = as_numbers(col)
    qb = as_numbers(qb)
    colmax = float(np.max(np.abs(col))) if col.size else 0.0
    ptol = piv_tol * colmax
    qmax = max(0.0, float(np.max(qb))) if qb.size else 0.0
    ztol = ZERO_Q * qmax
    elig = np.flatnonzero(col < -ptol)
    # q' below ztol counts as a zero of the data's type (0 * q' was NaN for a q' of inf, when
    # ztol = 1e-13 max q' is inf too: no row tied, a false ray; the kernel takes 0.0)
    zero = Fraction(0) if qb.dtype == object else 0.0
    v = np.where(qb[elig] > ztol, qb[elig], zero)
    with np.errstate(over="ignore"):  # a ratio past the double range is inf: it blocks last
        t = v / (-col[elig])
    tmin = np.min(t) if elig.size else None
    if not elig.size:
        tied_mask = np.zeros(0, dtype=bool)
    elif tmin == np.inf:  # every ratio is past the range: they tie
        tied_mask = t == np.inf
    else:  # t <= tmin (1 + tie_tol), which overflowed for a tmin near the largest double
        tied_mask = t - tmin <= tie_tol * tmin
    tied = [int(i) for i in elig[tied_mask]]
    ratio = dict(zip(elig.tolist(), t.tolist(), strict=True))
    rows = []
    for i in range(col.shape[0]):
        c = scalar(col[i])
        rec: dict[str, Any] = {"row": i + 1, "basic": basis[i], "q": scalar(qb[i]),
                               "column": c, "ratio": None, "eligible": i in ratio,
                               "tied": False, "why": ""}
        if i in ratio:
            rec["ratio"] = scalar(ratio[i])
            rec["tied"] = i in tied and len(tied) > 1
            if qb[i] <= ztol and qb[i] != 0:
                rec["why"] = f"q' = {float(qb[i]):.3g} counts as 0"
        elif c == 0:
            rec["why"] = f"entry 0: {basis[i]} does not change as {entering} rises"
        elif abs(c) <= ptol:
            rec["why"] = (f"entry below {piv_tol:g} times the column's largest in "
                          f"magnitude: counts as 0")
        else:
            rec["why"] = f"{basis[i]} grows as {entering} rises: never blocks"
        rows.append(rec)
    z0_rows = [i for i in tied if basis[i] == ARTIFICIAL]
    return {"formula": ratio_formula(entering, piv_tol, tie_tol),
            "formula_murty": ratio_formula_murty(entering, piv_tol, tie_tol), "rows": rows,
            "min_ratio": None if tmin is None else scalar(tmin), "tied_rows": tied,
            "z0_row": z0_rows[-1] if z0_rows else -1}



def lexicographic(tied: list[int], col: np.ndarray, binv_row: Callable[[int], np.ndarray],
                  basis: list[str]) -> tuple[int, dict[str, Any]]:
    """The kernel's lexicographic tie-break; returns the winning row and what was compared.

    The key of row ``i`` is row ``i`` of the basis inverse ``B^-1`` (``d q'_i / d q_k``,
    columns in the order ``w1..wn``) divided by the pivot entry ``-col[i]``; columns are
    compared one at a time and the rows above the minimum (within ``LEX_TOL``, floor at the
    identity scale ``1 / max pivot``) drop out until one row is left.
    """
    cand = list(tied)
    unit = 1.0 / max(float(-col[i]) for i in cand)
    full = {i: as_numbers(binv_row(i)) for i in cand}
    n = len(next(iter(full.values())))
    compared = []
    decided = -1
    for k in range(n):
        with np.errstate(over="ignore"):  # a pivot entry of 5e-324: keys past the range, inf
            keys = [scalar(full[i][k] / -col[i]) for i in cand]
        kmin = min(keys)
        kmax = max(abs(x) for x in keys)
        # the minimum itself is always kept (an infinite kmin made the bound NaN)
        kept = [i for i, x in zip(cand, keys, strict=True)
                if x == kmin or x <= kmin + LEX_TOL * max(kmax, unit)]
        if not kept:  # NaN keys (B^-1 past the double range) compare to nothing: still tied
            break
        compared.append({"column": k + 1, "variable": f"w{k + 1}",
                         "rows": [i + 1 for i in cand], "keys": keys,
                         "kept": [i + 1 for i in kept]})
        cand = kept
        if len(cand) == 1:
            decided = k
            break
    with np.errstate(over="ignore"):
        keyed = {i: (full[i] / -col[i]).tolist() for i in tied}
    record = {
        "rows": [{"row": i + 1, "basic": basis[i], "pivot_entry": scalar(-col[i]),
                  "binv_row": full[i].tolist(), "key": keyed[i]}
                 for i in tied],
        "compared": compared,
        "decided_by": f"w{decided + 1}" if decided >= 0 else None,
    }
    return cand[0], record


def lemke_traced(M: np.ndarray, q: np.ndarray, d: np.ndarray, max_iter: int, piv_tol: float,
                 tie_tol: float) -> tuple[Any, ...]:
    """Run Lemke's method like the compiled kernel; return its tuple plus the trace list.

    ``(status, z, pivots, basic, ray_dz, ray_dz0, z0, trace)``.  ``trace[0]`` is the initial
    tableau (``pivot`` 0, basis ``w``); ``trace[k]`` is pivot ``k``: entering / leaving
    variables and why, the ratio test of every row, the lexicographic comparison of a tie,
    ``pivot_element`` (row, entering column, value in the tableau of ``trace[k-1]``), and the
    state after the pivot.  A ray ends with an entry whose ``rule`` is ``ray`` (no pivot made).
    """
    n = q.shape[0]
    nz = 2 * n
    kind = object if np.asarray(M).dtype == object else np.float64  # fractions: exact
    T = np.empty((n, n + 1), dtype=kind)
    T[:, :n] = M
    T[:, n] = d
    qb = np.array(q, dtype=kind)
    basic = np.arange(n, dtype=np.int64)
    nonbasic = np.arange(n, 2 * n + 1, dtype=np.int64)
    where = np.empty(2 * n + 1, dtype=np.int64)
    where[:n] = np.arange(n)
    where[n:] = -(np.arange(n + 1) + 1)
    ray_dz = np.zeros(n)
    z = np.zeros(n)

    def name(code: int) -> str:
        return code_name(int(code), n)

    def state(next_entering: int | None) -> dict[str, Any]:
        out = state_record(T, qb, basic, nonbasic, n, TABLEAU_MAX_N)
        out["next_entering"] = None if next_entering is None else name(next_entering)
        out["driving_column"] = (None if next_entering is None
                                 else T[:, -where[next_entering] - 1].tolist())
        return out

    def binv_row(i: int) -> np.ndarray:
        """Row i of the basis inverse (the kernel's ``_lex_key`` for k = 0..n-1)."""
        loc = where[:n]
        cols = np.where(loc < 0, -loc - 1, 0)
        return np.where(loc >= 0, (loc == i).astype(np.int64).astype(kind), -T[i, cols])

    with np.errstate(over="ignore"):
        trivial = bool(n == 0 or np.min(q / d) >= 0)
    start = {"kind": "lemke", "pivot": 0, "entering": None, "leaving": None, "row": None,
             "entering_reason": None, "pivot_element": None, "ratio_test": None,
             "candidates": [], "lexicographic": None, "rule": "start",
             "reason": ("initial tableau w = q + M z + d z0: basis w, z = 0, z0 = 0" +
                        ("; q >= 0, so z = 0 solves the problem without a pivot" if trivial
                         else "; some q_i < 0, so z0 enters first"))}
    start.update(state(None if trivial else nz))
    trace: list[dict[str, Any]] = [start]

    def record(pivot: int, entering: int, leaving: int, r: int, p: float, test: dict[str, Any],
               why_enters: str, rule: str, reason: str, lex: dict[str, Any] | None) -> None:
        nxt = None if leaving == nz else (leaving + n if leaving < n else leaving - n)
        step: dict[str, Any] = {
            "kind": "lemke", "pivot": pivot, "entering": name(entering), "leaving": name(leaving),
            "row": r + 1, "entering_reason": why_enters,
            "pivot_element": {"row": r + 1, "column": name(entering), "value": scalar(p)},
            "ratio_test": test, "candidates": [x for x in test["rows"] if x["eligible"]],
            "lexicographic": lex, "rule": rule, "reason": reason,
        }
        step.update(state(nxt))
        trace.append(step)

    with np.errstate(over="ignore"):  # q_i / d_i past the double range is -inf: most negative
        ratios = q / d
    best = min(0, np.min(ratios)) if n else 0
    if best >= 0:
        return TRIVIAL, z, 0, basic, ray_dz, 0.0, 0.0, trace
    # ties within tie_tol |best|; a best of -inf ties the rows that are -inf (best + tie_tol
    # |best| is NaN there, so no row tied: IndexError, exit 3)
    tied0 = ratios == best if best == -np.inf else ratios <= best + tie_tol * abs(best)
    r = int(np.flatnonzero(tied0)[-1])
    entering, c, leaving = nz, n, int(basic[r])
    rows0 = [{"row": i + 1, "basic": name(basic[i]), "q": scalar(q[i]), "column": scalar(d[i]),
              "ratio": scalar(-ratios[i]) if q[i] < 0 else None, "eligible": bool(q[i] < 0),
              "tied": bool(tied0[i]) and int(np.sum(tied0)) > 1,
              "why": "" if q[i] < 0 else f"q_{i + 1} >= 0: w{i + 1} >= 0 already at z0 = 0"}
             for i in range(n)]
    test0 = {"formula": initial_formula(tie_tol), "formula_murty": initial_formula_murty(tie_tol),
             "rows": rows0, "min_ratio": scalar(-best),
             "tied_rows": [int(i) for i in np.flatnonzero(tied0)], "z0_row": -1}
    ntie = int(np.sum(tied0))
    reason = (f"initial pivot: z0 enters at level max(-q_i/d_i) = {num(-best)}; row {r + 1} "
              f"has the most negative q_i/d_i" +
              (f" ({ntie} rows tie, the last one wins: lexicographic rule for q + eps-vector)"
               if ntie > 1 else ""))
    why0 = (f"{ARTIFICIAL} enters first: the artificial variable lifts every w_i = q_i + "
            f"d_i {ARTIFICIAL} to >= 0")
    p = T[r, c]
    pivot_update(T, qb, r, c)
    basic[r], nonbasic[c] = entering, leaving
    where[entering], where[leaving] = r, -(c + 1)
    pivots = 1
    record(1, entering, leaving, r, p, test0, why0, "initial", reason, None)
    status = MAX_ITER
    while pivots < max_iter:
        left = leaving
        entering = leaving + n if leaving < n else leaving - n
        c = int(-where[entering] - 1)
        col = T[:, c]
        names = [name(b) for b in basic]
        test = ratio_test(col, qb, names, name(entering), piv_tol, tie_tol)
        why = (f"{name(entering)} enters because {name(left)} left (complementary rule: the "
               f"complement of the variable that just left enters)")
        cand = test["tied_rows"]
        lex = None
        if not cand:
            status = RAY
            trace.append({"kind": "lemke", "pivot": pivots + 1, "entering": name(entering),
                          "leaving": None, "row": None, "entering_reason": why,
                          "pivot_element": None, "ratio_test": test, "candidates": [],
                          "lexicographic": None, "rule": "ray",
                          "reason": (f"no row blocks: no basic variable falls as "
                                     f"{name(entering)} rises, so it can rise without bound "
                                     f"(a secondary ray); no pivot is made"),
                          **state(None)})
            break
        tmin = test["min_ratio"]
        if test["z0_row"] >= 0:
            r = test["z0_row"]
            rule = "z0_preferred" if len(cand) > 1 else "min_ratio"
            reason = (f"{len(cand)} rows tie at the minimum ratio {num(tmin)}; z0 is among "
                      f"them and leaves (that ends the method)" if len(cand) > 1 else
                      f"unique minimum ratio {num(tmin)}: z0 leaves, the method ends")
        elif len(cand) == 1:
            r = cand[0]
            rule = "min_ratio"
            reason = f"unique minimum ratio {num(tmin)}"
        else:
            r, lex = lexicographic(cand, col, binv_row, names)
            rule = "lexicographic"
            decided = lex["decided_by"]
            reason = (f"{len(cand)} rows tie at the minimum ratio {num(tmin)}; lexicographic "
                      f"tie-break on the rows of the basis inverse divided by the pivot entry, "
                      + (f"decided at column {decided[1:]} (variable {decided})"
                         if decided else "left a tie: the first row wins"))
        leaving = int(basic[r])
        p = T[r, c]
        pivot_update(T, qb, r, c)
        basic[r], nonbasic[c] = entering, leaving
        where[entering], where[leaving] = r, -(c + 1)
        pivots += 1
        record(pivots, entering, leaving, r, p, test, why, rule, reason, lex)
        if leaving == nz:
            status = OK
            break
    z0 = 0.0
    for i in range(n):
        b = int(basic[i])
        if n <= b < nz:
            z[b - n] = qb[i]
        elif b == nz:
            z0 = float(qb[i])
    dz0 = 0.0
    if status == RAY:
        if n <= entering < nz:
            ray_dz[entering - n] = 1.0
        for i in range(n):
            b = int(basic[i])
            if n <= b < nz:
                ray_dz[b - n] = T[i, c]
            elif b == nz:
                dz0 = float(T[i, c])
    return status, z, pivots, basic, ray_dz, dz0, z0, trace


def path_points(trace: list[dict[str, Any]], q: np.ndarray) -> list[dict[str, Any]]:
    """Lemke's path ``q + z0 d`` through the complementary cones, one point per state.

    Each item is ``{"step": k, "z0": z0, "point": q + z0 d}``.  State 0 is ``q`` itself
    (``z0 = 0`` before it enters); after pivot 1 the point lies on the boundary of the
    nonnegative orthant, and later states move it back towards ``q`` (``z0`` is the basic
    value of ``z0``, 0 once it has left).  Empty when no pivot is made.
    """
    if not trace or trace[0].get("next_entering") != ARTIFICIAL:
        return []
    q = np.asarray(q, dtype=np.float64)
    d = np.asarray(trace[0]["driving_column"], dtype=np.float64)
    out = [{"step": 0, "z0": 0.0, "point": q.tolist()}]
    for st in trace[1:]:
        if st.get("rule") == "ray":
            continue
        z0 = st["q_prime"][st["basis"].index(ARTIFICIAL)] if ARTIFICIAL in st["basis"] else 0.0
        out.append({"step": int(st["pivot"]), "z0": float(z0),
                    "point": (q + float(z0) * d).tolist()})
    return out


__all__ = ["MAX_ITER", "OK", "RAY", "TABLEAU_MAX_N", "TRIVIAL", "initial_formula",
           "initial_formula_murty", "lemke_traced", "lexicographic", "path_points", "ratio_formula",
           "ratio_formula_murty", "ratio_test"]
