"""Cottle-Dantzig principal pivoting step by step: a numpy replica of the compiled kernel.

Problem ``w = M z + q`` with ``l <= z <= u`` (LCP: ``l = 0``, ``u = inf``).  Indices are
processed one at a time (free ones first); the driving index ``i`` moves ``z_i`` towards
``w_i = 0`` while the clamped block ``C`` (``w_C = 0``, ``z_C`` basic) follows, until the first
event: ``w_i`` reaches 0 (clamp ``i``), ``z_i`` reaches a bound, a clamped ``z_j`` reaches a
bound (unclamp ``j``), or a bounded ``w_j`` reaches 0 (clamp ``j``).  The inverse of
``M[C, C]`` is updated by bordering / downdating and recomputed every ``64 + |C|`` updates,
exactly as in the kernel: the sums run in the kernel's order (sequential accumulation) and
the inverse comes from the same LAPACK routines (``getrf`` + ``getri``), so the events, and
hence the pivots, are the kernel's.

Index states: 0 not yet processed, 1 clamped (in ``C``), 2 at the lower bound, 3 at the upper
bound, 4 fixed (``l = u``).
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np

from lcpcli.solvers.trace.tableau import num, scalar

# Status codes and index states: the compiled kernel's values (the tests check they agree).
OK = 0
UNBOUNDED = 1
MAX_ITER = 2
SINGULAR = 3
FREE, CLAMPED, AT_LOWER, AT_UPPER, FIXED = 0, 1, 2, 3, 4

#: Up to this n the trace holds z and w of every state.
VALUES_MAX_N = 8

_EVENTS = {0: "w_i reaches 0: clamp i", 1: "z_i reaches a bound", 2: "a clamped z_j reaches a "
           "bound: unclamp j", 3: "a bounded w_j reaches 0: clamp j"}


def _seq(start: Any, terms: np.ndarray) -> Any:
    """``start + terms[0] + terms[1] + ...`` accumulated left to right (the kernel's loops)."""
    if terms.size == 0:
        return scalar(start)
    return scalar(np.cumsum(np.concatenate(([start], terms)))[-1])


def _seq_rows(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Row sums ``sum_b A[a, b] x[b]`` accumulated from 0.0 left to right, for every row ``a``."""
    if A.shape[1] == 0:
        return np.zeros(A.shape[0], dtype=A.dtype)
    prods = A * x[None, :]
    zero = np.zeros(A.shape[0], dtype=prods.dtype)  # object: int 0, fractions stay exact
    return np.cumsum(np.column_stack([zero, prods]), axis=1)[:, -1]


def _inv(K: np.ndarray) -> np.ndarray:
    """``inv(K)`` by LAPACK ``getrf`` + ``getri``, the routines numba's ``np.linalg.inv`` calls
    (fractions: exact Gauss-Jordan)."""
    if K.dtype == object:
        from lcpcli.solvers.trace.exact import inverse

        return inverse(K)
    from scipy.linalg import lapack  # scipy only on the (rare) refactorisation path

    lu, piv, info = lapack.dgetrf(K)
    if info > 0:
        raise np.linalg.LinAlgError("singular matrix")
    lwork, _ = lapack.dgetri_lwork(K.shape[0])  # numba asks for the optimal workspace too
    inv, info = lapack.dgetri(lu, piv, lwork=max(1, int(lwork)))
    return inv


class _Block:
    """The explicit inverse of ``M[C, C]`` and its updates (the kernel's ``_add``/``_remove``)."""

    def __init__(self, n: int, kind: Any = np.float64) -> None:
        self.Binv = np.zeros((n, n), dtype=kind)
        self.C = np.empty(n, dtype=np.int64)
        self.pos = np.full(n, -1, dtype=np.int64)
        self.k = 0

    def add(self, M: np.ndarray, j: int) -> bool:
        k, B, C = self.k, self.Binv, self.C
        Cs = C[:k]
        col = M[Cs, j]
        x = _seq_rows(B[:k, :k], col)
        y = np.zeros(k, dtype=B.dtype)
        for b in range(k):  # y = M[j, C] Binv, accumulated row by row of Binv
            mb = M[j, Cs[b]]
            if mb != 0:
                y = y + mb * B[b, :k]
        t = M[j, Cs] * x
        s = _seq(M[j, j], -t)
        big = _seq(abs(M[j, j]), np.abs(t))
        if abs(s) <= 1e-13 * big or big == 0:
            return False
        inv = 1 / s  # 1.0 / s for floats, exact for fractions
        B[:k, :k] += np.multiply.outer(x, y) * inv
        B[:k, k] = -x * inv
        B[k, :k] = -y * inv
        B[k, k] = inv
        C[k] = j
        return True

    def remove(self, p: int) -> None:
        k, B, C = self.k, self.Binv, self.C
        last = k - 1
        if p != last:
            B[:k, [p, last]] = B[:k, [last, p]]
            B[[p, last], :k] = B[[last, p], :k]
            moved = C[last]
            C[p] = moved
            self.pos[moved] = p
        h = B[last, last]
        f = B[:last, last] / h
        nz = f != 0
        B[:last, :last][nz] -= f[nz, None] * B[last, :last][None, :]

    def refactor(self, M: np.ndarray) -> None:
        k = self.k
        if k:
            Cs = self.C[:k]
            self.Binv[:k, :k] = _inv(np.ascontiguousarray(M[np.ix_(Cs, Cs)]))


def dantzig_traced(M: np.ndarray, q: np.ndarray, lo: np.ndarray, up: np.ndarray,
                   order: np.ndarray, max_piv: int) -> tuple[Any, ...]:
    """Run the method like the kernel (default refactorisation, no refinement).

    Returns ``(status, z, pivots, state, trace)``.  ``trace[0]`` is the start; then one entry
    per pivot (a step of the driving index to the first event) and one per index that is
    settled without a step (already at its bound with the right sign of ``w``, or ``w_i = 0``),
    each with the index sets, the entering/leaving pair and the values after it.
    """
    n = q.shape[0]
    kind = object if np.asarray(M).dtype == object else np.float64  # fractions: exact
    M = np.asarray(M, dtype=kind)
    q = np.asarray(q, dtype=kind)
    mscale = float(np.max(np.abs(M))) if n else 0.0
    if mscale == 0.0:
        mscale = 1.0
    zero: Any = Fraction(0) if kind is object else 0.0
    z = np.array([min(max(zero, lo[j]), up[j]) for j in range(n)], dtype=kind)
    w = np.zeros(n, dtype=kind)
    state = np.zeros(n, dtype=np.int64)
    state[lo == up] = FIXED
    blk = _Block(n, kind)
    pivots = 0
    updates = 0
    dz = np.zeros(n, dtype=kind)
    dw = np.zeros(n, dtype=kind)
    status = OK
    lcp = bool(np.all(lo == 0) and np.all(np.isinf(np.asarray(up, dtype=np.float64))))
    trace: list[dict[str, Any]] = []

    def record(entry: dict[str, Any]) -> None:
        sets = {"clamped": sorted(int(j) + 1 for j in blk.C[:blk.k]),
                "at_lower": [int(j) + 1 for j in np.flatnonzero(state == AT_LOWER)],
                "at_upper": [int(j) + 1 for j in np.flatnonzero(state == AT_UPPER)],
                "unprocessed": [int(j) + 1 for j in range(n)
                                if state[j] == FREE and j not in done]}
        wv = np.where(state == CLAMPED, zero, w)
        entry.update({"kind": "dantzig", "sets": sets,
                      "z": [scalar(x) for x in z] if n <= VALUES_MAX_N else None,
                      "w": [scalar(wv[j]) if j in done or state[j] != FREE else None
                            for j in range(n)] if n <= VALUES_MAX_N else None})
        trace.append(entry)

    done: set[int] = set()
    record({"pivot": 0, "index": None, "event": "start", "entering": None, "leaving": None,
            "step": None, "reason": ("LCP: every z_i starts at 0, no index processed" if lcp
                                     else "every z_i starts at clip(0, l_i, u_i)")})
    for t in range(n):
        i = int(order[t])
        if state[i] == FIXED:
            done.add(i)
            continue
        w[i] = _seq(q[i], M[i, :] * z)
        done.add(i)
        while True:
            wi = w[i]
            tolw = 1e-13 * (mscale * max(1.0, abs(z[i])) + abs(q[i])) + 1e-300
            if z[i] <= lo[i] and wi >= -tolw:
                state[i] = AT_LOWER
                z[i] = lo[i]
                record({"pivot": pivots, "index": i + 1, "event": "settled", "entering": None,
                        "leaving": None, "step": None,
                        "reason": (f"index {i + 1}: w{i + 1} = {num(wi)} >= 0 with z{i + 1} at "
                                   f"its lower bound: w{i + 1} stays basic, no pivot")})
                break
            if z[i] >= up[i] and wi <= tolw:
                state[i] = AT_UPPER
                z[i] = up[i]
                record({"pivot": pivots, "index": i + 1, "event": "settled", "entering": None,
                        "leaving": None, "step": None,
                        "reason": (f"index {i + 1}: w{i + 1} = {num(wi)} <= 0 with z{i + 1} at "
                                   f"its upper bound: no pivot")})
                break
            if abs(wi) <= tolw:
                if not blk.add(M, i):
                    status = SINGULAR
                    break
                blk.pos[i] = blk.k
                blk.k += 1
                updates += 1
                state[i] = CLAMPED
                w[i] = zero
                record({"pivot": pivots, "index": i + 1, "event": "clamped", "entering":
                        f"z{i + 1}", "leaving": f"w{i + 1}", "step": None,
                        "reason": f"index {i + 1}: w{i + 1} is already 0: clamp it, no step"})
                break
            direc = 1 if wi < 0 else -1  # an int: fractions stay exact
            k = blk.k
            Cs = blk.C[:k].copy()
            s = _seq_rows(blk.Binv[:k, :k], M[Cs, i])
            dz[:k] = -s * direc
            dmax = max(1.0, float(np.max(np.abs(dz[:k])))) if k else 1.0
            epsz = 1e-12 * dmax
            epsw = 1e-12 * mscale * dmax
            tmin = np.inf
            event = -1
            ev_j = -1
            for j in range(n):
                if j != i and state[j] != AT_LOWER and state[j] != AT_UPPER:
                    continue
                dw[j] = _seq(M[j, i] * direc, M[j, Cs] * dz[:k])
            if dw[i] * direc > epsw:
                tmin = max(-wi / dw[i], zero)
                event = 0
            if direc > 0 and up[i] < np.inf:
                tt = up[i] - z[i]
                if tt <= tmin:
                    tmin = max(tt, zero)
                    event = 1
            elif direc < 0 and lo[i] > -np.inf:
                tt = z[i] - lo[i]
                if tt <= tmin:
                    tmin = max(tt, zero)
                    event = 1
            for a in range(k):
                j = Cs[a]
                dd = dz[a]
                if dd < -epsz and lo[j] > -np.inf:
                    tt = max(z[j] - lo[j], zero) / (-dd)
                    if tt < tmin:
                        tmin, event, ev_j = tt, 2, a
                elif dd > epsz and up[j] < np.inf:
                    tt = max(up[j] - z[j], zero) / dd
                    if tt < tmin:
                        tmin, event, ev_j = tt, 2, a
            for j in range(n):
                if state[j] == AT_LOWER and dw[j] < -epsw:
                    tt = max(w[j], zero) / (-dw[j])
                    if tt < tmin:
                        tmin, event, ev_j = tt, 3, j
                elif state[j] == AT_UPPER and dw[j] > epsw:
                    tt = max(-w[j], zero) / dw[j]
                    if tt < tmin:
                        tmin, event, ev_j = tt, 3, j
            if event < 0:
                status = UNBOUNDED
                record({"pivot": pivots, "index": i + 1, "event": "unbounded", "entering": None,
                        "leaving": None, "step": None,
                        "reason": (f"driving z{i + 1} {'up' if direc > 0 else 'down'}: no "
                                   f"event blocks the step (unbounded direction)")})
                break
            z[Cs] += tmin * dz[:k]
            z[i] += tmin * direc
            for j in range(n):
                if j == i or state[j] == AT_LOWER or state[j] == AT_UPPER:
                    w[j] += tmin * dw[j]
            pivots += 1
            move = f"z{i + 1} {'rises' if direc > 0 else 'falls'} by {num(tmin)}"
            if event == 0:
                if not blk.add(M, i):
                    status = SINGULAR
                    break
                blk.pos[i] = blk.k
                blk.k += 1
                updates += 1
                state[i] = CLAMPED
                w[i] = zero
                record({"pivot": pivots, "index": i + 1, "event": "clamp_driving",
                        "entering": f"z{i + 1}", "leaving": f"w{i + 1}", "step": scalar(tmin),
                        "reason": f"{move}: w{i + 1} reaches 0, index {i + 1} is clamped"})
                break
            if event == 1:
                bound = "upper" if direc > 0.0 else "lower"
                if direc > 0.0:
                    z[i] = up[i]
                    state[i] = AT_UPPER
                else:
                    z[i] = lo[i]
                    state[i] = AT_LOWER
                record({"pivot": pivots, "index": i + 1, "event": "driving_at_bound",
                        "entering": None, "leaving": None, "step": scalar(tmin),
                        "reason": f"{move}: z{i + 1} reaches its {bound} bound first"})
                break
            if event == 2:
                j = int(blk.C[ev_j])
                if dz[ev_j] < 0.0:
                    z[j] = lo[j]
                    state[j] = AT_LOWER
                else:
                    z[j] = up[j]
                    state[j] = AT_UPPER
                w[j] = zero
                blk.remove(ev_j)
                blk.pos[j] = -1
                blk.k -= 1
                updates += 1
                record({"pivot": pivots, "index": i + 1, "event": "unclamp",
                        "entering": f"w{j + 1}", "leaving": f"z{j + 1}", "step": scalar(tmin),
                        "reason": (f"{move}: z{j + 1} reaches its bound first, index {j + 1} "
                                   f"leaves the clamped set")})
            elif event == 3:
                j = ev_j
                if not blk.add(M, j):
                    status = SINGULAR
                    break
                blk.pos[j] = blk.k
                blk.k += 1
                updates += 1
                state[j] = CLAMPED
                w[j] = zero
                record({"pivot": pivots, "index": i + 1, "event": "clamp",
                        "entering": f"z{j + 1}", "leaving": f"w{j + 1}", "step": scalar(tmin),
                        "reason": f"{move}: w{j + 1} reaches 0 first, index {j + 1} is clamped"})
            period = 64 + blk.k
            if updates >= period:
                blk.refactor(M)
                updates = 0
            if pivots >= max_piv:
                status = MAX_ITER
                break
        if status != OK:
            break
    return status, z, pivots, state, trace


__all__ = ["AT_LOWER", "AT_UPPER", "CLAMPED", "FIXED", "FREE", "MAX_ITER", "OK", "SINGULAR",
           "UNBOUNDED", "dantzig_traced"]
