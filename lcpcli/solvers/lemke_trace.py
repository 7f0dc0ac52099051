"""Lemke's method step by step: a numpy replica of :mod:`lcpcli.solvers.kernels.lemke`.

Same tableau, same pivot rule (initial pivot, lexicographic minimum ratio with the same
tolerances, ``z0`` preferred on ties), same floating-point operations in the same order, so
the pivot sequence is the compiled kernel's; in addition every pivot is recorded for
``lcpcli solve --method lemke --trace``.  O(n^2) numpy work per pivot: meant for teaching and
debugging, not for speed.

Variable codes as in the kernel: ``0..n-1`` = ``w1..wn``, ``n..2n-1`` = ``z1..zn``, ``2n`` = ``z0``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.solvers.kernels.lemke import MAX_ITER, OK, RAY, TRIVIAL

#: Up to this n the trace holds the whole tableau after each pivot; above it q' and the column.
TABLEAU_MAX_N = 8


def code_name(code: int, n: int) -> str:
    """1-based name of a kernel variable code (``z0`` is the artificial variable)."""
    if code < n:
        return f"w{code + 1}"
    if code < 2 * n:
        return f"z{code - n + 1}"
    return "z0"


def _pivot(T: np.ndarray, qb: np.ndarray, r: int, c: int) -> None:
    """The kernel's ``_pivot`` in numpy (same operations, same rounding)."""
    p = T[r, c]
    inv = 1.0 / p
    rowr = -T[r, :] * inv
    rowr[c] = inv
    qr = -qb[r] * inv
    f = T[:, c].copy()
    rows = np.flatnonzero(f != 0.0)
    rows = rows[rows != r]
    fr = f[rows]
    qb[rows] += fr * qr
    T[rows, :] += fr[:, None] * rowr[None, :]
    T[rows, c] = fr * inv
    T[r, :] = rowr
    qb[r] = qr


def _lex_key(T: np.ndarray, where: np.ndarray, i: int, k: int) -> float:
    loc = where[k]
    if loc >= 0:
        return 1.0 if loc == i else 0.0
    return -T[i, -loc - 1]


def lemke_traced(M: np.ndarray, q: np.ndarray, d: np.ndarray, max_iter: int, piv_tol: float,
                 tie_tol: float) -> tuple[Any, ...]:
    """Run Lemke's method like ``lemke_kernel``; return its tuple plus the trace list."""
    n = q.shape[0]
    nz = 2 * n
    T = np.empty((n, n + 1))
    T[:, :n] = M
    T[:, n] = d
    qb = q.astype(np.float64).copy()
    basic = np.arange(n, dtype=np.int64)
    nonbasic = np.arange(n, 2 * n + 1, dtype=np.int64)
    where = np.empty(2 * n + 1, dtype=np.int64)
    where[:n] = np.arange(n)
    where[n:] = -(np.arange(n + 1) + 1)
    ray_dz = np.zeros(n)
    z = np.zeros(n)
    trace: list[dict[str, Any]] = []

    def name(code: int) -> str:
        return code_name(int(code), n)

    def record(pivot: int, entering: int, leaving: int, r: int, cands: list[dict[str, Any]],
               rule: str, reason: str) -> None:
        nxt = None if leaving == nz else (leaving + n if leaving < n else leaving - n)
        step: dict[str, Any] = {
            "pivot": pivot, "entering": name(entering), "leaving": name(leaving),
            "row": r + 1, "basis": [name(b) for b in basic], "q_prime": qb.tolist(),
            "rule": rule, "reason": reason, "candidates": cands,
            "nonbasic": [name(v) for v in nonbasic],
            "next_entering": None if nxt is None else name(nxt),
            "driving_column": None if nxt is None else T[:, -where[nxt] - 1].tolist(),
        }
        step["tableau"] = T.tolist() if n <= TABLEAU_MAX_N else None
        trace.append(step)

    ratios = q / d
    best = min(0.0, float(np.min(ratios))) if n else 0.0
    if best >= 0.0:
        return TRIVIAL, z, 0, basic, ray_dz, 0.0, 0.0, trace
    r = int(np.flatnonzero(ratios <= best + tie_tol * abs(best))[-1])
    entering, c, leaving = nz, n, int(basic[r])
    cands = [{"row": i + 1, "basic": name(basic[i]), "q": float(q[i]), "column": float(d[i]),
              "ratio": float(-ratios[i]), "tied": bool(ratios[i] <= best + tie_tol * abs(best))}
             for i in range(n) if q[i] < 0]
    ntie = sum(1 for x in cands if x["tied"])
    reason = (f"initial pivot: z0 enters at level max(-q_i/d_i) = {-best:.6g}; row {r + 1} "
              f"has the most negative q_i/d_i" +
              (f" ({ntie} rows tie, the last one wins: lexicographic rule for q + eps-vector)"
               if ntie > 1 else ""))
    _pivot(T, qb, r, c)
    basic[r], nonbasic[c] = entering, leaving
    where[entering], where[leaving] = r, -(c + 1)
    pivots = 1
    record(1, entering, leaving, r, cands, "initial", reason)
    status = MAX_ITER
    while pivots < max_iter:
        entering = leaving + n if leaving < n else leaving - n
        c = int(-where[entering] - 1)
        col = T[:, c]
        colmax = float(np.max(np.abs(col)))
        ptol = piv_tol * colmax
        qmax = max(0.0, float(np.max(qb)))
        ztol = 1e-13 * qmax
        elig = np.flatnonzero(col < -ptol)
        if elig.size == 0:
            status = RAY
            break
        v = np.where(qb[elig] > ztol, qb[elig], 0.0)
        t = v / (-col[elig])
        tmin = float(np.min(t))
        tied = t <= tmin + tie_tol * tmin
        cand = [int(i) for i in elig[tied]]
        cands = [{"row": int(i) + 1, "basic": name(basic[i]), "q": float(qb[i]),
                  "column": float(col[i]), "ratio": float(tt), "tied": bool(tf) and len(cand) > 1}
                 for i, tt, tf in zip(elig, t, tied, strict=True)]
        z0_rows = [i for i in cand if basic[i] == nz]
        if z0_rows:
            r = z0_rows[-1]
            rule = "z0_preferred" if len(cand) > 1 else "min_ratio"
            reason = (f"{len(cand)} rows tie at the minimum ratio {tmin:.6g}; z0 is among them "
                      f"and leaves (that ends the method)" if len(cand) > 1 else
                      f"unique minimum ratio {tmin:.6g}: z0 leaves, the method ends")
        elif len(cand) == 1:
            r = cand[0]
            rule = "min_ratio"
            reason = f"unique minimum ratio {tmin:.6g}"
        else:
            amax = max(float(-T[i, c]) for i in cand)
            unit = 1.0 / amax
            ntied = len(cand)
            decided = -1
            for k in range(n):
                keys = [_lex_key(T, where, i, k) / (-T[i, c]) for i in cand]
                kmin = min(keys)
                kmax = max(abs(x) for x in keys)
                cand = [i for i, x in zip(cand, keys, strict=True)
                        if x <= kmin + 1e-10 * max(kmax, unit)]
                if len(cand) == 1:
                    decided = k
                    break
            r = cand[0]
            rule = "lexicographic"
            reason = (f"{ntied} rows tie at the minimum ratio {tmin:.6g}; lexicographic "
                      f"tie-break on the rows of the basis inverse divided by the pivot "
                      + (f"decided at column {decided + 1} (variable {name(decided)})"
                         if decided >= 0 else "left a tie: the first row wins"))
        leaving = int(basic[r])
        _pivot(T, qb, r, c)
        basic[r], nonbasic[c] = entering, leaving
        where[entering], where[leaving] = r, -(c + 1)
        pivots += 1
        record(pivots, entering, leaving, r, cands, rule, reason)
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
