"""Lemke's method on an MLCP directly, also when ``A`` is singular or ill conditioned.

Problem (Siconos form, ``w = M z + q``): ``A u + C v + a = 0``, ``0 <= v _|_ D u + B v + b >= 0``.

Phase 1 pivots the free variables ``u`` into the basis (they never leave it): a block principal
pivot on ``S = eq + J``, where ``J`` is the smallest set of complementarity indices found
(greedily, by SVD) that makes ``M[S, S]`` invertible with condition below ``cond_max``
(``J`` is empty when ``A`` itself is fine: the Schur complement).  For ``j`` in ``J`` the pair
``(v_j, w_j)`` changes roles (``v_j`` basic).  Phase 2 is the project's lexicographic Lemke
kernel (``lemke``) on the ``m``-pair LCP that is left, a principal pivot transform of the
MLCP; ``u`` and ``v`` are then recovered, the final active set is re-solved on the original
problem and the answer is certified on the original MLCP.

Matrix classes: MLCPs whose free block can be completed to an invertible principal block
(e.g. Siconos' diodeBridge, A of rank 2 of 3) and whose transformed LCP is in Lemke's class:
P-matrices and copositive-plus (PSD) ones (principal pivoting preserves both).  A secondary
ray is ``no_solution`` only with a Farkas vector of the MLCP itself that passes the check of
:mod:`lcpcli.analysis.proof` (found by its linear program), else ``unsolved``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.mlcp import choose_pivot_set, reduce
from lcpcli.analysis.proof import prove_infeasible
from lcpcli.core.errors import ProblemError
from lcpcli.core.result import NUMERICAL, Outcome
from lcpcli.solvers.methods.mlcp_schur import _positive, solve_reduced
from lcpcli.solvers.options import positive_int
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when


def run(problem: Any, *, tol: float, cond_max: float = 1e12,
        max_iter: int | None = None) -> Outcome:
    """Solve an MLCP by block pivoting the free variables in, then Lemke; see the docstring."""
    M = np.asarray(problem.dense_M(), dtype=np.float64)
    J, cond = choose_pivot_set(M, problem.n_eq, cond_max)
    if not np.isfinite(cond):
        return Outcome(np.zeros(problem.n), 0, NUMERICAL,
                       "no invertible principal block contains the free variables: the "
                       "equality rows are rank deficient")
    try:
        red = reduce(M, problem.q, problem.n_eq, J)
    except ProblemError as exc:
        return Outcome(np.zeros(problem.n), 0, NUMERICAL, f"block pivot failed: {exc}")
    z, out = solve_reduced(problem, red, "lemke", tol, max_iter)
    how = (f"free variables pivoted in with {len(J)} complementarity pair(s) swapped "
           f"(pivot block cond ~ {red.cond:.2e})" if len(J) else
           f"free variables pivoted in (Schur complement, cond(A) ~ {red.cond:.2e})")
    msg = f"{how}; Lemke: {out.message}"
    proof = prove_infeasible(problem, search=True) if out.proven_infeasible else None
    if proof is not None:
        msg += f" (on the MLCP itself: {proof.describe()})"
    elif out.proven_infeasible:
        msg += (" (not carried over to the MLCP: no Farkas vector of the MLCP passes the "
                "check, so nothing is proven)")
    return Outcome(z, int(out.iterations) + int(red.S.size), out.termination, msg,
                   proven_infeasible=proof is not None,
                   info={"swapped": [int(j) + problem.n_eq for j in J],
                         "pivot_cond": red.cond,
                         **({"farkas_y": proof.y.tolist()} if proof else {})})


METHODS = [
    Method(
        name="mlcp-lemke",
        run=run,
        summary="MLCP: free variables block-pivoted into the basis (never leaving), then "
                "lexicographic Lemke on the remaining pairs; handles singular A",
        guarantees=(Guarantee(when("p_matrix"), "the pivoted LCP is P: finite"),),
        notes="generally: an invertible principal block containing the free variables, "
              "pivoted LCP P or copositive-plus (PSD)",
        cost=Cost.PIVOTING,
        preference=20,
        fallback="pivots the free variables in, also when A is singular",
        kinds=("mlcp",),
        options={
            "cond_max": Option(_positive, 1e12, "largest accepted condition of the pivot block"),
            "max_iter": Option(positive_int, None, "Lemke pivot limit"),
        },
        scaling="auto",
    ),
]
