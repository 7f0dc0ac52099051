"""Murty's least-index principal pivoting method (Bard-type) for the LCP.

Problem: LCP(q, M), ``w = M z + q``.  Start from the complementary basis ``w`` (z = 0); at
every step take the *least* index ``i`` whose basic variable (``w_i`` or ``z_i``) is negative
and exchange ``w_i`` and ``z_i`` (a single principal pivot), until every basic variable is
nonnegative.

Warm start from an index set: ``basis=`` (the set ``F`` of basic z's: a previous Result, its
``basis`` codes or letters, booleans; :func:`lcpcli.solvers.options.basis_option`), or ``z0``
(``F = {i : z0_i > 0}``, which loses a degenerate pair whose ``z_i`` is basic at 0).  The
problem is first replaced by its principal pivot transform on ``M_FF`` (one factorisation,
:func:`lcpcli.solvers.methods.dantzig.principal_pivot_transform`; not counted as pivots), whose
all-w basis is ``F``; the kernel's least-index pivots on it are the method's from ``F``, and
the answer is mapped back.  A basis that still solves the problem ends in 0 pivots (its basic
solution is feasible: the transform is not even formed).  When ``M_FF`` is singular the
dependent pairs leave ``F`` (:func:`lcpcli.solvers.methods.lemke_warm.repair`, as warm Lemke
does); when the run from the set fails at once, the method starts from z = 0.  Below
``n =`` :data:`TRANSFORM_MIN_N`, and in a traced run (whose trace shows the problem given), the
kernel pivots ``F`` in on its own tableau instead (O(|F| n^2), no Python around it).  The
least-index rule is finite from any complementary basis on a P-matrix (a principal pivot
transform of a P-matrix is a P-matrix; Cottle-Pang-Stone, section 4.1), so the guarantee is
the same warm or cold.

Matrix classes: **P-matrices** (all principal minors positive: e.g. symmetric or non-symmetric
positive definite, H-matrices with positive diagonal), for which the method is finite (Murty 1974)
and ends at the unique solution, though possibly after exponentially many pivots (up to 2^n - 1,
as on Murty's own triangular family).  On other matrices the pivot element may be zero or
negative (a principal pivot transform of a P-matrix has a positive diagonal), or the method may
cycle; both end as ``unsolved`` (non-positive pivot, pivot limit) and never as a false
``solved``: the answer is certified by the shared certificate.

Cost: O(n^2) per pivot on a dense tableau (compiled kernel); a sparse M is densified (the method is
meant for small and medium dense problems).  The final basis is re-solved by LU with one step of
refinement (as Lemke's polish) so the answer is accurate to the conditioning of the basic block.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.classify import exact_p_matrix, not_p_witness
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, SINGULAR, Outcome
from lcpcli.core.text import plural
from lcpcli.core.tolerances import PIVOT_TOL
from lcpcli.solvers.kernels.lemke import polish_kernel
from lcpcli.solvers.kernels.murty import BAD_PIVOT, OK, murty_kernel
from lcpcli.solvers.methods.dantzig import basic_solution, feasible, principal_pivot_transform
from lcpcli.solvers.methods.lemke import default_max_iter
from lcpcli.solvers.methods.lemke_warm import repair
from lcpcli.solvers.options import basis_option, bool_option, index_set, positive_int, vector_option
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import preload_for_basis, start_point

#: A basic value counts as negative below ``-NEG_TOL * ||q||_inf``.
NEG_TOL = 1e-13

#: From this n on a start from an index set factors its block (the principal pivot
#: transform) rather than pivoting the set in on the kernel's tableau: measured on random PD
#: problems with half the pairs basic, pivoting in took 0.05 ms at n = 100 and 0.44 ms at
#: n = 200 against 0.07-0.17 ms and 0.09 ms for the transform (which costs ~0.03 ms of Python
#: at any n).
TRANSFORM_MIN_N = 128


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, basis: np.ndarray | None = None,
        trace: bool = False) -> Outcome:
    """Solve ``problem`` (an LCP) by Murty's least-index method; see the module docstring.

    ``basis`` (booleans, True: ``z_i`` basic) starts from that index set; it takes precedence
    over ``z0``.  ``trace=True`` runs the numpy replica :mod:`lcpcli.solvers.trace.murty`
    instead of the kernel (same pivots) and records each principal pivot in ``Outcome.trace``.
    """
    if trace:
        from lcpcli.solvers.trace import Recorder
        from lcpcli.solvers.trace.murty import murty_traced

        recorder = Recorder(murty_traced)
        out = _run(problem, tol=tol, max_iter=max_iter, z0=z0, basis=basis, kernel=recorder)
        out.trace = recorder.trace or []  # n = 0: nothing recorded
        return out
    return _run(problem, tol=tol, max_iter=max_iter, z0=z0, basis=basis)


def _run(problem: Any, *, tol: float, max_iter: int | None, z0: np.ndarray | None,
         basis: np.ndarray | None = None, kernel: Any = None) -> Outcome:
    kernel = kernel or murty_kernel

    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    limit = max_iter or default_max_iter(n)
    start = _start_set(problem, z0, basis)
    if n and np.min(q) >= 0:
        if kernel is not murty_kernel:  # a trace: its step 0, the basis w that solves it
            kernel(M, q, limit, PIVOT_TOL, NEG_TOL, np.arange(n, dtype=np.int64))
        return Outcome(np.zeros(n), 0, CONVERGED, "q >= 0: z = 0 solves the problem")
    basic = np.arange(n, dtype=np.int64)
    warm, solved = "", False
    if start is not None and start[0].any():
        status, z, pivots, bad, basic, warm, solved = _from_set(kernel, M, q, limit, *start,
                                                        traced=kernel is not murty_kernel)
    else:
        status, z, pivots, bad = kernel(M, q, limit, PIVOT_TOL, NEG_TOL, basic)
    if status == OK and not solved:
        z = polish_kernel(M, q, z, basic)  # a singular basic block keeps the kernel's z
    if status == OK:
        return Outcome(z, int(pivots), CONVERGED,
                       f"Murty: all basic variables nonnegative after "
                       f"{plural(pivots, 'pivot')}{warm}")
    if status == BAD_PIVOT:
        var = "w" if basic[bad] < n else "z"
        return Outcome(z, int(pivots), SINGULAR,
                       f"Murty: pivot for {var}{bad + 1} not positive beyond the tolerance "
                       f"after {plural(pivots, 'pivot')}{warm}; {_class_words(M, basic, bad)}")
    return Outcome(z, int(pivots), ITERATION_LIMIT,
                   f"Murty: pivot limit {limit} reached{warm} (M may not be a P-matrix; "
                   f"raise --max-iter if it is)")


def _start_set(problem: Any, z0: np.ndarray | None,
               basis: np.ndarray | None) -> tuple[np.ndarray, str] | None:
    """The warm start's index set (booleans, True: ``z_i`` basic) and its name, or None."""
    if basis is not None:
        return index_set(basis, problem.n), "the given basis"
    if z0 is not None:
        return start_point(problem, z0) > 0, "the warm-start basis"
    return None


def _from_set(kernel: Any, M: np.ndarray, q: np.ndarray, limit: int, F: np.ndarray,
              what: str, traced: bool
              ) -> tuple[int, np.ndarray, int, int, np.ndarray, str, bool]:
    """The kernel run from the index set ``F`` (see the module docstring); when that fails at
    once (a singular block, a first pivot that is not positive) the run starts from z = 0.
    Returns the kernel's tuple with ``z`` and the final ``basic`` codes of the problem given,
    the words for the message, and whether ``z`` is the start's basic solution, solved and
    refined already (no pivot, no kernel)."""
    n = q.shape[0]
    run = _pivoted_in if traced or n < TRANSFORM_MIN_N else _transformed
    status, z, pivots, bad, basic, warm, why = run(kernel, M, q, limit, F, what)
    if status == BAD_PIVOT and pivots == 0:  # restart from z = 0 (as a cold run)
        basic = np.arange(n, dtype=np.int64)
        warm = f" ({what}, {int(F.sum())} z basic: {why}; restarted from z = 0)"
        status, z, pivots, bad = kernel(M, q, limit, PIVOT_TOL, NEG_TOL, basic)
    return status, z, pivots, bad, basic, warm, why == _SOLVED


#: The message's words when the start's basic solution is feasible (solved, not pivoted).
_SOLVED = "; its basic solution is feasible: one factorisation"


def _words(F: np.ndarray, kept: np.ndarray, what: str) -> str:
    """" from the given basis (k z basic[, j dependent pairs dropped ...])"."""
    dropped = int(F.sum() - kept.sum())
    return (f" from {what} ({int(F.sum())} z basic" +
            (f", {plural(dropped, 'dependent pair')} dropped from its singular block)"
             if dropped else ")"))


def _transformed(kernel: Any, M: np.ndarray, q: np.ndarray, limit: int, F: np.ndarray,
                 what: str) -> tuple[int, np.ndarray, int, int, np.ndarray, str, str]:
    """The run from ``F`` on the principal pivot transform of ``M_FF`` (one factorisation,
    :func:`lcpcli.solvers.methods.dantzig.basic_solution`; nothing more when the basic
    solution is feasible), mapped back: the kernel starts from the transform's all-w basis,
    which is ``F`` here, and its least-index pivots are the ones the method takes from ``F``."""
    n = q.shape[0]
    idx = np.arange(n, dtype=np.int64)
    start = basic_solution(M, q, F)
    if start is None:
        return BAD_PIVOT, np.zeros(n), 0, -1, idx, "", "its block is singular"
    kept, solve, z = start
    warm = _words(F, kept, what)
    if feasible(M, q, kept, z):  # no basic variable is negative: 0 pivots
        return OK, z, 0, -1, np.where(kept, idx + n, idx), warm + _SOLVED, _SOLVED
    Mp, qp = principal_pivot_transform(M, q, kept, solve)
    tb = idx.copy()
    status, zp, pivots, bad = kernel(Mp, qp, limit, PIVOT_TOL, NEG_TOL, tb)
    basic = np.where(kept, np.where(tb < n, tb + n, tb - n), tb)  # w'_F is z_F
    z = zp.copy()
    z[kept] = Mp[kept] @ zp + qp[kept]
    return (status, np.maximum(z, 0.0), pivots, bad, basic, warm,
            "the first pivot from it was not positive")


def _pivoted_in(kernel: Any, M: np.ndarray, q: np.ndarray, limit: int, F: np.ndarray,
                what: str) -> tuple[int, np.ndarray, int, int, np.ndarray, str, str]:
    """The run from ``F`` with the pairs of ``F`` pivoted in by the kernel itself (a traced
    run: the replica's tableaux then show the problem given); a block that cannot be pivoted in
    is repaired once (its dependent pairs leave, as in warm Lemke)."""
    n = q.shape[0]
    idx = np.arange(n, dtype=np.int64)
    basic = np.where(F, idx + n, idx)
    status, z, pivots, bad = kernel(M, q, limit, PIVOT_TOL, NEG_TOL, basic)
    start, warm = F, _words(F, F, what)
    if _not_pivoted_in(status, pivots, bad, basic, start):
        kept = repair(M, F)
        if kept.any() and not np.array_equal(kept, F):
            basic, start = np.where(kept, idx + n, idx), kept
            warm = _words(F, kept, what)
            status, z, pivots, bad = kernel(M, q, limit, PIVOT_TOL, NEG_TOL, basic)
    why = ("its block could not be pivoted in"
           if _not_pivoted_in(status, pivots, bad, basic, start)
           else "the first pivot from it was not positive")
    return status, z, pivots, bad, basic, warm, why


def _not_pivoted_in(status: int, pivots: int, bad: int, basic: np.ndarray,
                    start: np.ndarray) -> bool:
    """Did the kernel stop while pivoting the starting set ``start`` in?  It then leaves
    ``w`` basic in the failing row, a pair of the set (a failure of the first pivot leaves
    the set whole)."""
    return (status == BAD_PIVOT and pivots == 0 and bool(start[bad])
            and bool(basic[bad] < start.shape[0]))


def _class_words(M: np.ndarray, basic: np.ndarray, bad: int) -> str:
    """What a bad pivot shows about M: "not a P-matrix" only with a principal minor that is
    exactly ``<= 0`` (the pivot is ``det M[a+j] / det M[a]`` or ``det M[a-j] / det M[a]`` for
    the z-basic set ``a``; a positive diagonal scaling keeps the signs of the minors)."""
    n = M.shape[0]
    alpha = [i for i in range(n) if basic[i] >= n]
    witness = not_p_witness(M, [sorted(set(alpha) | {bad}), [i for i in alpha if i != bad],
                                alpha])
    if witness is not None:
        names = ", ".join(str(i + 1) for i in witness)
        return (f"M is not a P-matrix (its principal minor on {{{names}}} is exactly <= 0), "
                f"outside the method's class")
    if exact_p_matrix(M) is True:
        return ("M is a P-matrix (every principal minor is positive in exact arithmetic), but "
                "too close to losing the property for this method's pivot tolerance (try "
                "lemke or dantzig)")
    return ("no principal minor is exactly <= 0, so M may be a P-matrix that is too close to "
            "losing the property for this method's pivot tolerance (try lemke or dantzig)")


METHODS = [
    Method(
        name="murty",
        preload=preload_for_basis,
        run=run,
        summary="Murty's least-index principal pivoting (Bard-type), dense tableau",
        guarantees=(Guarantee(when("p_matrix"), "finite (up to 2^n pivots): the unique "
                                                "solution"),),
        notes="others: may stop on a non-positive pivot",
        cost=Cost.PIVOTING,
        preference=40,
        # contact LCPs of resting box stacks (redundant contacts, rank 42 of 72, zero diagonal
        # friction rows) that Lemke's paths end on rays or drift on: Murty certified 3 of the 4
        # islands of 8,000 that no other method did (benchmarks/README.md)
        fallback="least-index principal pivoting outside the P-matrices (may stop on a "
                 "non-positive pivot)",
        fallback_preference=95,  # after the other fallbacks of its cost class (dantzig's 90)
        auto_max_n=200,  # up to 100 n pivots of O(n^2) each where it fails: under a second
        kinds=("lcp",),
        options={
            "max_iter": Option(positive_int, None, "pivot limit (default max(1000, 100 n))"),
            "z0": Option(vector_option, None, "warm start: start from the basis {i: z0_i > 0}"),
            "basis": Option(basis_option, None, "warm start: start from this index set (a "
                                                "previous result, its basis letters 'FLF' "
                                                "or booleans; True/F: z_i basic)"),
            "trace": Option(bool_option, False, "record every principal pivot (numpy replica "
                                                 "of the kernel, same pivots)"),
        },
        scaling="auto",
    ),
]
