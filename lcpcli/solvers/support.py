"""Numerical helpers shared by the solver methods (not a method module: no ``METHODS``).

Conventions: ``w = M z + q``, the box ``[lo, up]`` from :meth:`Problem.bounds`.  Iterative methods
stop on :func:`certified_error`, the certificate's own ``error``, so that a method's "converged"
and the verdict agree.
"""

from __future__ import annotations

import warnings
from time import perf_counter
from typing import Any

import numpy as np

from lcpcli.core.certificate import AT_LOWER, AT_UPPER, BETWEEN, certify, check
from lcpcli.core.errors import OptionError
from lcpcli.core.tolerances import POLISHED, TINY_Z


def preload_linalg(problem: Any, options: Any = None) -> None:
    """``Method.preload`` of a method that factorises: scipy.linalg for a dense M,
    scipy.sparse.linalg for a sparse one (imported before the solve is timed)."""
    if problem.sparse:
        import scipy.sparse.linalg  # noqa: F401
    else:
        import scipy.linalg  # noqa: F401


def timed_imports(problem: Any, *loaders: Any) -> float:
    """Run ``loaders`` (each ``loader(problem)``: the modules a run's next steps import, such
    as :func:`preload_linalg`) and return the seconds they took: the one way a run loads
    modules it could not know it needed before it started, timed apart
    (``Outcome.import_seconds``, left out of ``Result.seconds``)."""
    start = perf_counter()
    for loader in loaders:
        loader(problem)
    return perf_counter() - start


def preload_for_basis(problem: Any, options: Any) -> None:
    """``Method.preload`` of a method whose start from a ``basis`` factorises the basic block
    (:func:`lcpcli.solvers.methods.bpp.factor_block`); nothing for a cold start."""
    if options.get("basis") is not None:
        import scipy.linalg  # noqa: F401


def start_point(problem: Any, z0: np.ndarray | None, default: float = 0.0) -> np.ndarray:
    """The warm start ``z0`` checked against ``problem`` (OptionError on a length mismatch)."""
    n = problem.n
    if z0 is None:
        return np.full(n, default)
    z = np.asarray(z0, dtype=np.float64).ravel()
    if z.shape[0] != n:
        raise OptionError(f"warm start z0 has length {z.shape[0]}, the problem has n = {n}")
    if not np.all(np.isfinite(z)):
        raise OptionError("warm start z0 contains NaN or Inf")
    return z.copy()


def certified_error(problem: Any, z: np.ndarray) -> float:
    """The certificate's ``error`` of ``z`` (the one definition, :mod:`lcpcli.core.certificate`).

    Iterative methods stop on it, so that "converged" and the verdict never disagree; Inf for a
    non-finite ``z``.
    """
    if not np.all(np.isfinite(z)):
        return float("inf")
    return certify(problem, z).error


class StallWatch:
    """Stagnation of an iterative method (termination ``stalled``): after each step,
    :meth:`update` with the step's merit says whether the best merit of the last ``window``
    steps is not below ``(1 - decrease)`` times the best merit before them.  Keeps only the
    last ``window + 1`` running bests."""

    __slots__ = ("window", "decrease", "best")

    def __init__(self, window: int, decrease: float, first: float | None = None) -> None:
        self.window, self.decrease = window, decrease
        self.best: list[float] = [] if first is None else [first]

    def update(self, merit: float) -> bool:
        """Record one step's merit; True when the method has stalled."""
        best = self.best
        best.append(min(best[-1], merit) if best else merit)
        if len(best) > self.window and best[-1] > (1.0 - self.decrease) * best[-1 - self.window]:
            return True
        del best[:-self.window - 1]
        return False


#: ``Outcome.info`` key of a Lemke ray whose artificial variable ``z0`` ended at rounding level
#: (``<= TINY_Z max |q|``, :func:`lcpcli.solvers.methods.lemke.ray_outcome`): its point is
#: polished as a converged answer's is and the certificate decides (pipeline, step 3).
RAY_AT_ROUNDING = "ray_at_rounding_level"


def refine(problem: Any, z: np.ndarray, rounds: int = 4, basis: list[int] | None = None,
           good_enough: float = POLISHED) -> tuple[np.ndarray, float] | None:
    """Polish ``z`` by re-solving the equations its active set implies; None if nothing better.

    The certificate names each pair's state (at a bound, or between with ``w_i = 0``).  The first
    candidate only snaps the variables at bounds exactly onto them (rounding noise such as a
    tangent impulse of 1e-32 in a friction-cone row whose other terms are zero); the second
    sets the entries at rounding level (``TINY_Z ||z||_inf``, where 0 is inside their box) to
    0, as the batched Lemke kernel does; then the variables at bounds are fixed and the
    others solve ``M_BB z_B = -(q_B + M_BN z_N)``
    (dense LU with one refinement step, sparse LU, least squares when singular).  Signs are then
    repaired (a basic ``z_i`` outside its box goes to the bound; a fixed one whose ``w_i`` has the
    wrong sign becomes basic) for a few rounds, and the candidate with the smallest certified
    error is returned with that error.  This is what turns a pivoting or iterative answer whose
    active set is right into one that is componentwise accurate (tiny rows included).

    ``basis`` (a pivoting method's final basic z's, nonsingular by construction) is tried before
    the certificate's states: on degenerate, rank-deficient problems (coplanar contacts) the
    states can name a singular set while the method's basis is not.  The search stops at the
    first candidate certified at ``good_enough`` (rounding level by default).  Floating-point
    exceptions inside are not numpy warnings: a candidate past the float64 range is dropped.
    """
    if not np.all(np.isfinite(z)):
        return None
    with np.errstate(all="ignore"):
        return _refine(problem, z, rounds, basis, good_enough)


def _refine(problem: Any, z: np.ndarray, rounds: int, basis: list[int] | None,
            good_enough: float) -> tuple[np.ndarray, float] | None:
    """:func:`refine`'s search."""
    lo, up = problem.bounds()
    state = np.empty(problem.n, dtype=np.int8)
    best_err = check(problem, z, state=state)[0].error
    best = None
    # first the cheapest candidate: the variables the certificate puts at a bound, exactly there
    snapped = np.where(state == AT_LOWER, lo, np.where(state == AT_UPPER, up, z))
    if np.all(np.isfinite(snapped)) and not np.array_equal(snapped, z):
        err = certify(problem, snapped).error
        if err < best_err:
            best, best_err = snapped, err
    if best is not None and best_err <= good_enough:
        return best, best_err
    # then z with its rounding-level entries at 0 (degenerate basic z's, which a tableau
    # leaves exactly 0: a row made only of such terms reads w_i / s_i ~ 1), as the batched
    # Lemke kernel and the warm starts try it (TINY_Z)
    tiny = (z != 0.0) & (np.abs(z) <= TINY_Z * float(np.max(np.abs(z), initial=0.0))) \
        & (lo <= 0.0) & (up >= 0.0)
    if tiny.any():
        zeroed = np.where(tiny, 0.0, best if best is not None else z)
        err = certify(problem, zeroed).error
        if err < best_err:
            best, best_err = zeroed, err
    if best is not None and best_err <= good_enough:
        return best, best_err
    if basis is not None:
        hinted = np.where(np.isfinite(lo), AT_LOWER, BETWEEN).astype(np.int8)
        hinted[np.asarray(basis, dtype=np.intp)] = BETWEEN
        zc = _solve_active_set(problem, z, hinted, lo, up)
        if zc is not None:
            err = certify(problem, zc).error
            if err < best_err:
                best, best_err = zc, err
    if best is not None and best_err <= good_enough:
        return best, best_err
    seen: set[bytes] = set()
    for _ in range(rounds):
        key = state.tobytes()
        if key in seen:
            break
        seen.add(key)
        zc = _solve_active_set(problem, z, state, lo, up)
        if zc is None:
            break
        cert, w = check(problem, zc)
        if cert.error < best_err:
            best, best_err = zc, cert.error
            if best_err <= good_enough:
                break
        new = state.copy()
        basic = new == BETWEEN
        new[basic & (zc < lo)] = AT_LOWER
        new[basic & (zc > up)] = AT_UPPER
        new[(state == AT_LOWER) & (w < 0)] = BETWEEN
        new[(state == AT_UPPER) & (w > 0)] = BETWEEN
        if np.array_equal(new, state):
            break
        state, z = new, zc
    return None if best is None else (best, best_err)


def _solve_active_set(problem: Any, z: np.ndarray, state: np.ndarray, lo: np.ndarray,
                      up: np.ndarray) -> np.ndarray | None:
    """z with the fixed variables at their bounds and the basic ones solving their rows."""
    zc = np.where(state == AT_LOWER, lo, np.where(state == AT_UPPER, up, z))
    if not np.all(np.isfinite(zc)):
        return None
    B = np.flatnonzero(state == BETWEEN)
    if B.size == 0:
        return zc
    N = np.flatnonzero(state != BETWEEN)
    M = problem.M
    rhs = -problem.q[B]
    if problem.sparse:
        Mr = M.tocsr()[B]
        MBB = Mr[:, B].tocsr()
        if N.size:
            rhs = rhs - np.asarray(Mr[:, N] @ zc[N]).ravel()
    else:
        MBB = M[np.ix_(B, B)]
        if N.size:
            rhs = rhs - M[np.ix_(B, N)] @ zc[N]
    zb = _solve_peeling_singletons(MBB, rhs, problem.sparse)
    if not np.all(np.isfinite(zb)):
        return None
    zc[B] = zb
    return zc


def _solve_peeling_singletons(A: Any, b: np.ndarray, sparse: bool) -> np.ndarray:
    """``A x = b`` with the singleton rows solved exactly first.

    A row whose only unknown left is ``x_j`` gives ``x_j = b_i / A_ij`` with one rounding (an
    exact zero when ``b_i = 0``); it is substituted and the search repeats.  This keeps the
    structural zeros that LU with partial pivoting would smear with rounding (a row
    ``w_i = -z_1`` with ``q_i = 0`` must give ``z_1 = 0`` exactly, or that row is 100% violated).
    The rest is solved by LU with one refinement step (sparse LU for a sparse A).
    """
    m = b.shape[0]
    x = np.zeros(m)
    if m == 0:
        return x
    A = A.tocsr() if sparse else np.asarray(A)
    pattern = (A != 0) if not sparse else A.astype(bool).tocsr()
    rows_left = np.ones(m, dtype=bool)
    cols_left = np.ones(m, dtype=bool)
    b = b.copy()
    while True:
        if sparse:
            counts = np.asarray(pattern[:, cols_left].sum(axis=1)).ravel()
        else:
            counts = pattern[:, cols_left].sum(axis=1)
        single = np.flatnonzero(rows_left & (counts == 1))
        if single.size == 0:
            break
        taken = False
        for i in single:
            row = (A.getrow(i).toarray().ravel() if sparse else A[i]) * cols_left
            nz = np.flatnonzero(row)
            if nz.size != 1:  # an earlier singleton of this round took its unknown
                continue
            j = int(nz[0])
            x[j] = b[i] / row[j]
            col = (A[:, [j]].toarray().ravel() if sparse else A[:, j])
            b = b - col * x[j]
            rows_left[i] = False
            cols_left[j] = False
            taken = True
        if not taken:
            break
    R, C = np.flatnonzero(rows_left), np.flatnonzero(cols_left)
    if C.size:
        sub = A[R][:, C] if sparse else A[np.ix_(R, C)]
        if R.size == C.size:
            x[C] = _sparse_solve(sub, b[R]) if sparse else _dense_solve(sub, b[R])
        else:
            dense = sub.toarray() if sparse else sub
            x[C] = np.linalg.lstsq(dense, b[R], rcond=None)[0]
    return x


def sparse_lu(A: Any) -> Any | None:
    """SuperLU's factorization of the square sparse ``A`` (``scipy.sparse.linalg.splu``), or
    None when ``A`` is singular: exactly (SuperLU's RuntimeError) or structurally (a row or a
    column without a nonzero entry, refused before SuperLU sees it: on such matrices its
    column ordering can call BLAS with invalid arguments, which OpenBLAS reports on stdout,
    where ``--json`` prints its one object)."""
    import scipy.sparse.linalg as spla  # scipy is imported on first use (start-up budget)

    A = A.tocsc()
    n = A.shape[0]
    stored = A.data != 0.0  # O(nnz) scatters, no sort: this runs once per Newton step
    hit_rows, hit_cols = np.zeros(n, bool), np.zeros(n, bool)
    hit_rows[A.indices[stored]] = True
    hit_cols[np.repeat(np.arange(n), np.diff(A.indptr))[stored]] = True
    if not (hit_rows.all() and hit_cols.all()):
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return spla.splu(A)
    except RuntimeError:  # exactly singular
        return None


def _sparse_solve(A: Any, b: np.ndarray) -> np.ndarray:
    """``A x = b`` by sparse LU with one refinement step; least squares when singular."""
    import scipy.sparse.linalg as spla  # scipy is imported on first use (start-up budget)

    lu = sparse_lu(A)
    if lu is None:
        return spla.lsqr(A, b, atol=1e-15, btol=1e-15, iter_lim=10 * b.shape[0])[0]
    x = lu.solve(b)
    return x + lu.solve(b - A @ x)


def _dense_solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A x = b`` by LU with one step of iterative refinement; least squares if singular."""
    import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lu = sla.lu_factor(A, check_finite=False)
        if np.any(np.diag(lu[0]) == 0.0):
            raise np.linalg.LinAlgError("singular")
        x = sla.lu_solve(lu, b, check_finite=False)
        with np.errstate(over="ignore", invalid="ignore"):  # a solution past float64: inf
            x = x + sla.lu_solve(lu, b - A @ x, check_finite=False)
        if not np.all(np.isfinite(x)):
            raise np.linalg.LinAlgError("singular to working precision")
        return x
    except (np.linalg.LinAlgError, ValueError):
        return np.linalg.lstsq(A, b, rcond=None)[0]


def better(problem: Any, candidates: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """The candidate with the smallest certified error, and that error."""
    best, best_err = candidates[0], float("inf")
    for z in candidates:
        e = certified_error(problem, z)
        if e < best_err:
            best, best_err = z, e
    return best, best_err
