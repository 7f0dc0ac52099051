"""Block principal pivoting (Kostreva 1978; Júdice & Pires 1994) for the LCP and the MLCP.

Problem: LCP(q, M), ``w = M z + q`` (MLCP: the first ``n_eq`` variables free, always basic).
A *basis* is the set ``F`` of basic z's (the other pairs have ``w_i`` basic and ``z_i = 0``); its
basic solution solves ``M_FF z_F = -q_F`` and sets ``w_G = q_G + M_GF z_F`` (G the complement).
Every iteration factors ``M_FF`` once and finds the *infeasible* pairs (``z_i < 0`` in F,
``w_i < 0`` in G); with none, the basic solution solves the problem.  Otherwise (Júdice &
Pires, "A block principal pivoting algorithm for large-scale strictly monotone linear
complementarity problems", Computers & Operations Research 21, 1994):

* while the number of infeasible pairs keeps falling, or for at most ``block_tries`` iterations
  after it last fell, *every* infeasible pair is exchanged at once (a block pivot);
* after that, only the least-index infeasible pair is exchanged (Murty's least-index rule,
  1974), until the count falls below its best again.

Pure block pivoting can cycle even on P-matrices; the single-pivot fallback makes the method
finite on **P-matrices** (Murty's rule is), ending at the unique solution.  Block pivots usually
end it in a handful of factorisations, independent of n, which is why a nearby basis (a warm
start: :mod:`lcpcli.solvers.warm`) ends it in one or two.  On other matrices ``M_FF`` may be
singular (reported as ``singular_basis``) or the pivot limit may be reached; the answer is
judged by the shared certificate, never by this module.

Cost: one dense LU of ``M_FF`` (O(|F|^3)) and one product with M (O(n^2)) per iteration; a sparse
M is densified.  ``z0`` starts from the basis ``{i: z0_i > 0}`` (or give ``basis=``, booleans).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, SINGULAR, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.options import positive_int, vector_option
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import start_point

#: Block pivots allowed without a new lowest count of infeasible pairs (Júdice & Pires' p).
BLOCK_TRIES = 3
#: A basic value is infeasible below ``-NEG_TOL`` times its row's scale ``|q_i| + (|M||z|)_i``
#: (for ``w_i``) or ``||z||_inf`` (for ``z_i``).
NEG_TOL = 1e-12
#: A pivot block whose LU has ``min |u_ii| <= SINGULAR_TOL * max |u_ii|`` counts as singular.
SINGULAR_TOL = 1e-14


def default_max_iter(n: int) -> int:
    """Factorisation limit when none is given (finite for P-matrices)."""
    return max(100, 10 * n)


def basic_solution(M: np.ndarray, q: np.ndarray, F: np.ndarray) -> np.ndarray | None:
    """The basic z of basis ``F`` (booleans): ``M_FF z_F = -q_F`` by LU with one refinement
    step, other z's zero; None when ``M_FF`` is singular (to :data:`SINGULAR_TOL`)."""
    from scipy.linalg import LinAlgWarning, lu_factor, lu_solve

    z = np.zeros(q.shape[0])
    idx = np.flatnonzero(F)
    if idx.size == 0:
        return z
    # factor the transpose: a C-ordered copy of M_FF is a Fortran-ordered M_FF^T, factored in
    # place (no copy); solves then use trans=1
    with warnings.catch_warnings():  # a singular block is reported below, not warned about
        warnings.simplefilter("ignore", LinAlgWarning)
        lu, piv = lu_factor(M[np.ix_(idx, idx)].T, overwrite_a=True, check_finite=False)
    d = np.abs(np.diag(lu))
    if not np.all(np.isfinite(d)) or d.min() <= SINGULAR_TOL * d.max():
        return None
    z[idx] = lu_solve((lu, piv), -q[idx], trans=1, check_finite=False)
    r = M[idx] @ z + q[idx]  # one step of refinement: M_FF z_F + q_F should be 0
    z[idx] -= lu_solve((lu, piv), r, trans=1, check_finite=False)
    if not np.all(np.isfinite(z)):
        return None
    return z


def pivot(M: np.ndarray, q: np.ndarray, F: np.ndarray, free: np.ndarray, max_iter: int,
          block_tries: int = BLOCK_TRIES) -> tuple[str, np.ndarray, int, int, np.ndarray]:
    """Run block principal pivoting from the basis ``F`` (booleans; ``free`` pairs are always
    basic).  Returns ``(status, z, factorisations, single_pivots, F)`` with status ``"ok"``
    (every basic variable nonnegative), ``"singular"`` (a singular ``M_FF``) or ``"limit"``."""
    n = q.shape[0]
    F = F | free
    absM = np.abs(M)
    best, tries, singles = n + 1, block_tries, 0
    z = np.zeros(n)
    for it in range(1, max_iter + 1):
        zn = basic_solution(M, q, F)
        if zn is None:
            return "singular", z, it, singles, F
        z = zn
        w = M @ z + q
        scale = np.abs(q) + absM @ np.abs(z)
        bad = np.where(F, z < -NEG_TOL * max(1.0, float(np.max(np.abs(z), initial=0.0))),
                       w < -NEG_TOL * scale) & ~free
        count = int(np.count_nonzero(bad))
        if count == 0:
            return "ok", z, it, singles, F
        if count < best:
            best, tries = count, block_tries
            F = F ^ bad
        elif tries > 0:
            tries -= 1
            F = F ^ bad
        else:  # Murty's least-index rule: finite on P-matrices
            i = int(np.argmax(bad))
            F = F.copy()
            F[i] = not F[i]
            singles += 1
    return "limit", z, max_iter, singles, F


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, basis: Any = None,
        block_tries: int = BLOCK_TRIES) -> Outcome:
    """Solve ``problem`` (LCP or MLCP) by block principal pivoting; see the module docstring."""
    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    limit = max_iter or default_max_iter(n)
    free = np.zeros(n, dtype=bool)
    free[:problem.n_eq] = True
    F = np.zeros(n, dtype=bool)
    start = ""
    if basis is not None:
        F = np.asarray(basis, dtype=bool).ravel()
        if F.shape[0] != n:
            from lcpcli.core.errors import OptionError

            raise OptionError(f"basis has length {F.shape[0]}, the problem has n = {n}")
        start = f" from the given basis ({int(F.sum())} z basic)"
    elif z0 is not None:
        F = start_point(problem, z0) > 0
        start = f" from the warm-start basis ({int(F.sum())} z basic)"
    status, z, its, singles, F = pivot(M, q, F, free, limit, block_tries)
    info = {"basis": np.flatnonzero(F).tolist(), "single_pivots": singles}
    did = (f"{plural(its, 'factorisation')} ({plural(singles, 'single pivot')} by Murty's "
           f"least-index fallback){start}")
    if status == "ok":
        return Outcome(z, its, CONVERGED, f"BPP: all basic variables nonnegative after {did}",
                       info=info)
    if status == "singular":
        return Outcome(z, its, SINGULAR, f"BPP: singular pivot block M_FF after {did}; M is "
                                         f"not a P-matrix, outside the method's class",
                       info=info)
    return Outcome(z, its, ITERATION_LIMIT, f"BPP: limit of {limit} factorisations reached "
                                            f"{start} (M may not be a P-matrix)", info=info)


def _basis_option(value: Any) -> np.ndarray:
    """A basis: a sequence of booleans (True: z_i basic)."""
    arr = np.asarray(value)
    if arr.ndim != 1 or arr.dtype.kind not in "bi" or not np.isin(arr, (0, 1)).all():
        raise ValueError("a basis is a list of booleans (True: z_i basic)")
    return arr.astype(bool)


METHODS = [
    Method(
        name="bpp",
        run=run,
        summary="block principal pivoting (Kostreva; Júdice-Pires), Murty's least-index "
                "fallback against cycling; warm-startable from a basis",
        guarantees=(Guarantee(when("p_matrix"), "finite: the unique solution"),),
        notes="others: may stop on a singular pivot block",
        cost=Cost.FACTORING,
        preference=50,
        kinds=("lcp", "mlcp"),
        options={
            "max_iter": Option(positive_int, None, "factorisation limit (default "
                                                   "max(100, 10 n))"),
            "z0": Option(vector_option, None, "warm start: start from the basis "
                                              "{i: z0_i > 0}"),
            "basis": Option(_basis_option, None, "start from this basis (booleans, True: z_i "
                                                 "basic)"),
            "block_tries": Option(positive_int, BLOCK_TRIES, "block pivots without progress "
                                                             "before the single-pivot rule"),
        },
        scaling="auto",
    ),
]
