"""Projected Gauss-Seidel / SOR sweeps one by one: a numpy replica of the compiled kernels.

One sweep sets, for ``i = 1..n`` in order, ``z_i <- proj_[l_i, u_i](z_i - omega r_i / M_ii)``
with ``r_i = (M z + q)_i`` at the current (partly updated) ``z``.  The stopping test is the
kernels': an in-sweep estimate of a normwise scaled error ``||mid(z - l, z - u, w)|| / (mu
||z|| + ||q||)``, confirmed by one exact product ``M z`` (every 1, 2, 4, ... 32 sweeps) before
stopping; the method then tightens that target until the componentwise certificate passes.
Row sums are accumulated left to right as in the kernels, so the iterates, and the sweep count,
are the same (one
exception: a NaN iterate is ``DIVERGED`` here at once, as the kernels' docstring says, while
the numba kernels' comparisons let a NaN through to the stopping test).

The trace keeps the first :data:`FIRST_SWEEPS` sweeps and the last one: ``z`` (n <= 8), the
largest change of a component, the kernel's in-sweep estimate (``estimate``: the gate of the
exact check; for PGS it is 0 by construction, since each row's update zeroes that row's own
residual, so the displays leave it out) and the exact normwise error (for the display only;
it does not steer the iteration).
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Status codes: the compiled kernels' values (the tests check they agree).
CONVERGED = 0
LIMIT = 1
DIVERGED = 2

#: Sweeps recorded from the start (then only the last one).
FIRST_SWEEPS = 10
#: Up to this n every recorded sweep holds the whole z.
VALUES_MAX_N = 8


def kernel_estimate(z: np.ndarray, w: np.ndarray, lo: np.ndarray, up: np.ndarray, mu: float,
                    qnorm: float) -> float:
    """The PGS kernel's own stopping estimate (``_scaled_error`` in kernels/pgs.pyx), replicated
    so that the trace stops on the sweep the kernel stops on.  It is a cheap normwise proxy;
    the method keeps sweeping until the certificate itself passes (methods/pgs.py), and the
    verdict is always the certificate's."""
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.maximum(mu * (z - up), np.minimum(mu * (z - lo), w))
    num = float(np.max(np.abs(r))) if r.size else 0.0
    if num == 0.0:
        return 0.0
    den = mu * (float(np.max(np.abs(z))) if z.size else 0.0) + qnorm
    if not np.isfinite(num):
        return float("inf")
    return num / den if den > 0 else float("inf")

def _row_sum(start: float, terms: np.ndarray) -> float:
    """``start + terms[0] + ...`` accumulated left to right (the kernels' loop)."""
    if terms.size == 0:
        return float(start)
    return float(np.cumsum(np.concatenate(([start], terms)))[-1])


def pgs_traced(M: Any, q: np.ndarray, diag: np.ndarray, lo: np.ndarray, up: np.ndarray,
               z: np.ndarray, omega: float, max_iter: int, tol: float, mu: float,
               qnorm: float) -> tuple[int, int, float, list[dict[str, Any]]]:
    """Run PGS/PSOR like ``pgs_dense`` (dense ``M``) or ``pgs_csr`` (a scipy CSR matrix).

    ``z`` is updated in place.  Returns ``(status, sweeps, error, trace)``; ``trace[0]`` is
    the starting point (sweep 0).
    """
    n = q.shape[0]
    sparse = hasattr(M, "indptr")
    if sparse:
        indptr, indices, data = M.indptr, M.indices, np.asarray(M.data, dtype=np.float64)

    def row(i: int) -> float:
        if sparse:
            s, e = indptr[i], indptr[i + 1]
            return _row_sum(q[i], data[s:e] * z[indices[s:e]])
        return _row_sum(q[i], M[i, :] * z)

    def exact_w() -> np.ndarray:
        return np.array([row(i) for i in range(n)])

    def display_error() -> float:
        with np.errstate(all="ignore"):
            w = (M @ z) + q
        return kernel_estimate(z, np.asarray(w, dtype=np.float64).ravel(), lo, up, mu, qnorm)

    trace: list[dict[str, Any]] = [{
        "kind": "sweep", "sweep": 0, "z": z.tolist() if n <= VALUES_MAX_N else None,
        "change": None, "estimate": None, "error": display_error(), "checked": False,
        "omega": float(omega)}]

    def record(it: int, change: float, est: float, checked: bool) -> None:
        if trace[-1]["sweep"] == it:
            return
        trace.append({"kind": "sweep", "sweep": it,
                      "z": z.tolist() if n <= VALUES_MAX_N else None, "change": change,
                      "estimate": est, "error": display_error(), "checked": checked,
                      "omega": float(omega)})

    gap = 1
    next_check = 1
    for it in range(1, max_iter + 1):
        est = 0.0
        zmax = 0.0
        change = 0.0
        for i in range(n):
            r = row(i)
            zi = z[i]
            znew = zi - omega * r / diag[i]
            if znew < lo[i]:
                znew = lo[i]
            if znew > up[i]:
                znew = up[i]
            z[i] = znew
            wi = r + diag[i] * (znew - zi)
            rc = min(mu * (znew - lo[i]), wi)
            r2 = mu * (znew - up[i])
            if r2 > rc:
                rc = r2
            rc = abs(rc)
            if rc > est:
                est = rc
            if abs(znew) > zmax:
                zmax = abs(znew)
            if abs(znew - zi) > change:
                change = abs(znew - zi)
        if not (np.isfinite(est) and np.isfinite(zmax) and np.all(np.isfinite(z))):
            # (the numba kernels test est and max|z| only, which a NaN slips past)
            record(it, change, est, False)
            return DIVERGED, it, float("inf"), trace
        checked = False
        if it >= next_check and est <= 0.5 * tol * (mu * zmax + qnorm):
            err = kernel_estimate(z, exact_w(), lo, up, mu, qnorm)
            checked = True
            if err <= tol:
                record(it, change, est, True)
                return CONVERGED, it, err, trace
            gap = min(2 * gap, 32)
            next_check = it + gap
        if it <= FIRST_SWEEPS or it == max_iter:
            record(it, change, est, checked)
    err = kernel_estimate(z, exact_w(), lo, up, mu, qnorm)
    return LIMIT, max_iter, err, trace


class SweepRecorder:
    """:func:`pgs_traced` standing in for the kernel over a whole run of several calls.

    The method calls its kernel again and again (blocks of sweeps, a tightened target); each
    call's trace numbers its sweeps from 0.  This keeps one trace for the run: the start
    (sweep 0 of the first call), the first :data:`FIRST_SWEEPS` sweeps and the last one, each
    numbered by the sweeps made since the start (the number the method reports).
    """

    def __init__(self) -> None:
        self.trace: list[dict[str, Any]] = []
        self.sweeps = 0  # sweeps made by the earlier calls

    def __call__(self, *args: Any) -> tuple[int, int, float]:
        # floating-point exceptions as the compiled kernel has them: quiet
        with np.errstate(all="ignore"):
            status, done, err, trace = pgs_traced(*args)
        entries = trace if not self.trace else trace[1:]  # a later call's start: a repeat
        if self.trace and self.trace[-1]["sweep"] > FIRST_SWEEPS:
            self.trace.pop()  # the previous call's last sweep is not the run's last
        for st in entries:
            st["sweep"] += self.sweeps
        last = entries[-1:] if entries and entries[-1]["sweep"] > FIRST_SWEEPS else []
        self.trace += [st for st in entries if st["sweep"] <= FIRST_SWEEPS] + last
        self.sweeps += int(done)
        return status, done, err


__all__ = ["CONVERGED", "DIVERGED", "FIRST_SWEEPS", "LIMIT", "SweepRecorder", "pgs_traced"]
