"""MLCP by Schur complement: eliminate the free variables, solve the LCP left, recover them.

Problem (Siconos form, ``w = M z + q``): ``A u + C v + a = 0``, ``0 <= v _|_ D u + B v + b >= 0``
with ``M = [[A, C], [D, B]]``.  With ``A`` invertible, ``u = -A^-1 (a + C v)`` and ``v`` solves
the LCP ``(B - D A^-1 C) v + (b - D A^-1 a)``; that LCP goes to an inner method (option
``inner``, default ``lemke``), ``u`` is recovered, the active set is re-solved on the original
MLCP and the whole answer is certified on the original MLCP.

Matrix classes: ``A`` invertible with condition estimate below ``cond_max`` (default 1e12),
and a Schur complement ``B - D A^-1 C`` in the inner method's class (for ``lemke``: P-matrix, or
copositive-plus such as PSD; the Schur complement of a P / PSD matrix is P / PSD).  When ``A``
is singular or ill conditioned the method stops with ``unsolved`` and says so: use
``mlcp-lemke``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.mlcp import polish, recover, schur
from lcpcli.analysis.proof import prove_infeasible
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.problem import Problem
from lcpcli.core.result import CONVERGED, NUMERICAL, Outcome
from lcpcli.solvers.options import positive_int
from lcpcli.solvers.pipeline import run_method
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when
from lcpcli.solvers.request import method_of, resolve


def _positive(value: Any) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 1):
        raise ValueError("must be a finite number > 1")
    return v


def solve_reduced(problem: Any, red: Any, inner: str, tol: float,
                  max_iter: int | None) -> tuple[np.ndarray, Outcome]:
    """Run the inner LCP method on a reduction's LCP; return (full z, inner outcome)."""
    spec = method_of(inner)
    if "lcp" not in spec.kinds:
        raise OptionError(f"inner method '{spec.name}' does not solve LCPs")
    sub = Problem.create(red.lcp_M, red.lcp_q, name=f"{problem.name}-reduced")
    opts: dict[str, Any] = {}
    if max_iter is not None and "max_iter" in spec.options:
        opts["max_iter"] = max_iter
    req = resolve(sub, spec.name, tol, opts)
    out = run_method(req.spec, sub, req.tol, req.options)  # as lcpcli.solve runs it
    x = np.asarray(out.z, dtype=np.float64)
    M = np.asarray(problem.dense_M(), dtype=np.float64)
    if not np.all(np.isfinite(x)):
        return np.full(problem.n, np.nan), out
    z = recover(M, problem.q, red, np.maximum(x, 0.0))
    return polish(problem, z), out


def run(problem: Any, *, tol: float, inner: str = "lemke", cond_max: float = 1e12,
        max_iter: int | None = None) -> Outcome:
    """Solve an MLCP by Schur reduction; see the module docstring."""
    try:
        red = schur(problem, cond_max)
    except ProblemError as exc:
        return Outcome(np.zeros(problem.n), 0, NUMERICAL,
                       f"Schur reduction refused: {exc}; try --method mlcp-lemke",
                       info={"cond_A": None})
    z, out = solve_reduced(problem, red, inner, tol, max_iter)
    msg = (f"Schur complement (cond(A) ~ {red.cond:.2e}), inner {inner}: {out.message}")
    term = out.termination
    proof = prove_infeasible(problem, search=True) if out.proven_infeasible else None
    proven = proof is not None
    if proof is not None:
        msg += f" (on the MLCP itself: {proof.describe()})"
    elif out.proven_infeasible:
        msg += (" (not carried over to the MLCP: no Farkas vector of the MLCP passes the "
                "check, so nothing is proven)")
    return Outcome(z, int(out.iterations), term if term else CONVERGED, msg,
                   proven_infeasible=proven,
                   info={"cond_A": red.cond, **({"farkas_y": proof.y.tolist()} if proof else {})})


METHODS = [
    Method(
        name="mlcp-schur",
        run=run,
        summary="MLCP: eliminate the free variables by the Schur complement of A (LU), "
                "solve the LCP left with an inner method, recover u",
        guarantees=(Guarantee(when("p_matrix"), "A is nonsingular and the Schur complement "
                                                "is P: finite with lemke"),),
        notes="generally: A invertible and well conditioned, Schur complement in the inner "
              "method's class (lemke: P or copositive-plus/PSD)",
        cost=Cost.PIVOTING,
        preference=10,
        fallback="eliminates the free variables when A is well conditioned",
        kinds=("mlcp",),
        options={
            "inner": Option(str, "lemke", "inner LCP method for the Schur complement"),
            "cond_max": Option(_positive, 1e12, "largest accepted condition estimate of A"),
            "max_iter": Option(positive_int, None, "iteration limit of the inner method"),
        },
        scaling="auto",
    ),
]
