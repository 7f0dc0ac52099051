"""Lemke's complementary pivoting method (dense tableau, lexicographic anti-cycling).

Problem: LCP(q, M), ``w = M z + q``; the augmented system is ``w = q + M z + d z0`` with the
covering vector ``d > 0`` (default all ones) and the artificial variable ``z0``.

Matrix classes: finds a solution for P-matrices, and for copositive-plus matrices (e.g. positive
semidefinite ones) whenever one exists.  A secondary ray suggests infeasibility (on a
copositive-plus matrix its direction is a Farkas vector in exact arithmetic); the verdict is
``no_solution`` only when a vector ``y >= 0`` with ``M^T y <= 0`` and ``q^T y < 0`` passes the
componentwise check of :mod:`lcpcli.analysis.proof`, else ``unsolved``.

Degenerate data: when the path with ``d`` all ones ends on a ray that is neither a proof nor at
rounding level and no covering vector was given, the method runs once more with a generic
covering vector (:func:`generic_covering`).  Any ``d > 0`` is a valid covering vector (Cottle,
Pang and Stone, The Linear Complementarity Problem, 4.4), and a generic one separates the exact
ties that symmetric data make in the first ratio tests (the four corners of a box resting on
another: equal q_i), where floating point can only resolve the lexicographic rule up to rounding
and the path can go astray: a friction-cone island of a stack of boxes (n = 72, M singular)
ended on a ray at z0 = 3.8e-13 with ``d`` all ones and was solved with the generic ``d``.

Cost: O(n^2) per pivot (rank-one tableau update in the compiled kernel
:mod:`lcpcli.solvers.kernels.lemke`).  The final basis is
re-solved with a dense LU factorisation (one step of refinement) so the answer is accurate to
the conditioning of the basic block, not to the accumulated tableau updates.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.analysis.classify import is_psd
from lcpcli.analysis.proof import preload_proof_search, prove_infeasible
from lcpcli.core.errors import OptionError
from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, RAY, Outcome
from lcpcli.core.text import plural
from lcpcli.core.tolerances import PIVOT_TOL, TIE_TOL, TINY_Z
from lcpcli.solvers.kernels.dense import bind_numpy_lapack
from lcpcli.solvers.kernels.lemke import (
    MAX_ITER,
    OK,
    TRIVIAL,
    default_max_iter,
    lemke_solve,
    polish_kernel,
)
from lcpcli.solvers.options import bool_option, positive_int, vector_option
from lcpcli.solvers.registry import BatchSpec, Cost, Guarantee, Method, Option, when
from lcpcli.solvers.support import RAY_AT_ROUNDING, preload_linalg, timed_imports

#: Empty pivot record (the kernel records nothing).
NO_RECORD = np.zeros((0, 3), dtype=np.int64)


def covering_vector(n: int, covering: np.ndarray | None) -> np.ndarray | None:
    """The covering vector ``d`` (length n, positive); None for the default, all ones (the
    kernels take None as all ones, one allocation less on the small-solve path)."""
    if covering is None:
        return None
    d = np.asarray(covering, dtype=np.float64).ravel()
    if d.size == 1:
        d = np.full(n, float(d[0]))
    if d.shape[0] != n:
        raise OptionError(f"covering vector has length {d.shape[0]}, expected {n}")
    if not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise OptionError("covering vector must be finite and positive")
    return d


#: The step of :func:`generic_covering`'s sequence: the golden ratio's fractional part.
GOLDEN_STEP = 0.6180339887498949


def generic_covering(n: int) -> np.ndarray:
    """A fixed covering vector without ties, ``d_i = 1 + frac((i + 1) phi)`` (values in [1, 2),
    no two equal; the same for every run, so the retry is reproducible)."""
    return 1.0 + np.modf(np.arange(1, n + 1) * GOLDEN_STEP)[0]


def astray(out: Outcome) -> bool:
    """Whether ``out`` is a Lemke ray that neither proves infeasibility nor sits at rounding
    level: the case the generic covering vector is tried for."""
    return out.termination == RAY and not out.proven_infeasible \
        and not out.info.get(RAY_AT_ROUNDING)


def batch_params(n: int, options: Mapping[str, Any]) -> dict[str, Any]:
    """The batched ``lemke`` kernel's parameters (:attr:`BatchSpec.params`): the covering
    vector (None: all ones) and the pivot limit (default :func:`default_max_iter`)."""
    return {"covering": covering_vector(n, options.get("covering")),
            "max_iter": int(options.get("max_iter") or default_max_iter(n))}


def run(problem: Any, *, tol: float, covering: np.ndarray | None = None,
        max_iter: int | None = None, trace: bool = False) -> Outcome:
    """Solve ``problem`` (an LCP) by Lemke's method; see the module docstring.

    ``trace=True`` runs the numpy replica of the kernel (same pivots) and records each pivot
    in ``Outcome.trace`` (see :mod:`lcpcli.solvers.trace.lemke`).
    """
    n = problem.n
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = problem.q
    d = covering_vector(n, covering)
    limit = max_iter or default_max_iter(n)
    if trace:
        from lcpcli.solvers.trace import Recorder
        from lcpcli.solvers.trace.lemke import lemke_traced

        recorder = Recorder(lemke_traced)  # as the other replicas: the kernel's fp rules
        status, z, pivots, basic, ray_dz, _, z0 = recorder(
            M, q, np.ones(n) if d is None else d, limit, PIVOT_TOL, TIE_TOL)
        if status == OK:
            z = polish(M, q, z, basic)
        out = finish(problem, M, q, status, z, int(pivots), basic_z(basic, n), ray_dz,
                     float(z0), limit)
        out.trace = recorder.trace
    else:  # kernel and final polish in one compiled call
        status, z, pivots, basis, ray_dz, z0 = lemke_solve(M, q, d, limit, PIVOT_TOL, TIE_TOL)
        out = finish(problem, M, q, status, z, pivots, basis, ray_dz, z0, limit)
    if d is not None or not astray(out):
        return out
    again = retry_generic(problem, M, q, limit, out)  # traced or not: the same verdict
    if trace and again is not out:
        again.message += " (the trace shows the first path, d all ones)"
        again.trace = out.trace
    return again


def retry_generic(problem: Any, M: np.ndarray, q: np.ndarray, limit: int,
                  out: Outcome) -> Outcome:
    """The module docstring's retry of an astray ray ``out`` (``d`` all ones) with
    :func:`generic_covering`: its outcome when it converges, proves infeasibility or ends at
    rounding level (with the pivots of both runs), else ``out``, noting the retry (its pivots
    those of the path it reports, as without the retry)."""
    status, z, pivots, basis, ray_dz, z0 = lemke_solve(M, q, generic_covering(problem.n),
                                                       limit, PIVOT_TOL, TIE_TOL)
    again = finish(problem, M, q, status, z, pivots, basis, ray_dz, z0, limit)
    out.import_seconds += again.import_seconds
    if again.termination == CONVERGED or (again.termination == RAY and not astray(again)):
        again.message = f"{out.message}; with a generic covering vector: {again.message}"
        again.info["covering"] = "generic"
        again.iterations += out.iterations
        again.import_seconds = out.import_seconds
        return again
    out.message += f"; a generic covering vector: {again.message.split(';')[0]}"
    return out


def finish(problem: Any, M: np.ndarray, q: np.ndarray, status: int, z: np.ndarray, pivots: int,
           basis: list[int], ray_dz: np.ndarray, z0: float, limit: int) -> Outcome:
    """Turn a Lemke kernel's status into an :class:`Outcome` (``z`` already polished when the
    status is OK; ray classification otherwise; ``basis``: the basic z's, 0-based)."""
    if status == TRIVIAL:
        return Outcome(np.zeros(problem.n), 0, CONVERGED, "q >= 0: z = 0 solves the problem")
    if status == OK:
        return Outcome(z, pivots, CONVERGED,
                       f"artificial variable left the basis after {plural(pivots, 'pivot')}",
                       info={"basis": basis})
    if status == MAX_ITER:
        return Outcome(np.maximum(z, 0.0), pivots, ITERATION_LIMIT,
                       f"pivot limit {limit} reached (raise it with --max-iter)")
    return ray_outcome(problem, M, q, z, pivots, ray_dz, z0)


def basic_z(basic: np.ndarray, n: int) -> list[int]:
    """The 0-based indices of the z's in Lemke's final basis (codes n..2n-1; see the kernel)."""
    return sorted(b - n for b in basic.tolist() if n <= b < 2 * n)


def polish(M: np.ndarray, q: np.ndarray, z: np.ndarray, basic: np.ndarray) -> np.ndarray:
    """Re-solve the final complementary basis ``M[b, b] z_b = -q_b`` by LU (one refinement).

    Keeps the tableau's answer when the re-solve is not better (e.g. a singular block).
    """
    return polish_kernel(M, q, z, basic)


def ray_outcome(problem: Any, M: np.ndarray, q: np.ndarray, z: np.ndarray, pivots: int,
                ray_dz: np.ndarray, z0: float) -> Outcome:
    """Classify a secondary-ray termination: proven infeasible (a Farkas vector that passes
    :func:`lcpcli.analysis.proof.check_farkas`), or merely unsolved.

    On a copositive-plus M (tested: positive semidefinite) the ray direction is a Farkas vector
    in exact arithmetic (Cottle-Pang-Stone, Theorem 4.4.13); in floating point the ray may come
    from rounding (a solvable problem near an infeasible one), so it is a proof only when the
    vector (or one found by the linear program of :func:`prove_infeasible`) passes the check.
    """
    # the definiteness test factorises (scipy.linalg) and the search may solve a linear
    # program: modules loaded here, on the ray's path only, are timed apart
    imported = timed_imports(problem, preload_linalg)
    psd = is_psd(M)
    if psd:
        imported += timed_imports(problem, preload_proof_search)
    proof = prove_infeasible(problem, (ray_dz,), search=psd)
    base = f"ray termination after {plural(pivots, 'pivot')} (z0 = {z0:.3g})"
    z = np.maximum(z, 0.0)
    if proof is not None:
        return Outcome(z, pivots, RAY, f"{base}; {proof.describe()}", proven_infeasible=True,
                       info={"farkas_y": proof.y.tolist()}, import_seconds=imported)
    hint: dict[str, Any] = {"ray": ray_dz.tolist()}  # a proof candidate (auto's search)
    if 0.0 <= z0 <= TINY_Z * float(np.max(np.abs(q), initial=0.0)):
        # the artificial variable at rounding level: z solves the problem with q + z0 d, a
        # change of q below its rounding; the dispatcher polishes it and the certificate
        # decides (contact LCPs of resting boxes end so: z0 = 1.4e-17, max |q| = 0.15)
        hint[RAY_AT_ROUNDING] = True
        return Outcome(z, pivots, RAY,
                       f"{base}, at rounding level: its point is the candidate answer",
                       info=hint, import_seconds=imported)
    if psd:
        return Outcome(z, pivots, RAY,
                       f"{base}; M is positive semidefinite (copositive-plus), where the ray "
                       f"would prove infeasibility in exact arithmetic, but no Farkas vector "
                       f"passes the exact check, so this ray comes from rounding and proves "
                       f"nothing (try another method)", info=hint,
                       import_seconds=imported)
    return Outcome(z, pivots, RAY,
                   f"{base}; M is not known to be copositive-plus, so this proves nothing "
                   f"(try another method)", info=hint, import_seconds=imported)


#: Lemke's classes (both Lemke methods, and the inner LCP of the MLCP methods).
GUARANTEES = (
    Guarantee(when("p_matrix"), "finite: the unique solution"),
    Guarantee(when("psd"), "copositive-plus: a solution, or a checked Farkas proof that "
                          "none exists"),
)

METHODS = [
    Method(
        name="lemke-tableau",
        run=run,
        summary="Lemke's complementary pivoting, dense tableau, lexicographic anti-cycling",
        guarantees=GUARANTEES,
        cost=Cost.PIVOTING,
        preference=20,  # after lemke-revised, which is faster (benchmarks/bench_lemke.py)
        # contact islands of resting box stacks (n = 72, singular M) on which the revised
        # method's updated inverse drifts to a basis whose answer no polish certifies
        # (error 2.09) while the tableau's rank-one updates reach the solution
        fallback="the whole tableau updated where the revised method's inverse drifts "
                 "(a ray then proves nothing)",
        fallback_preference=96,  # after murty's 95: the revised method reruns the tableau
        # itself on its unproven rays, so auto gets here after a drifted answer
        auto_max_n=200,  # up to 100 n pivots of O(n^2) each where it fails: under a second
        kinds=("lcp",),
        options={
            "covering": Option(vector_option, None, "covering vector d > 0 (default all ones)"),
            "max_iter": Option(positive_int, None, "pivot limit (default max(1000, 100 n))"),
            "trace": Option(bool_option, False, "record every pivot (numpy replica of the "
                                                 "kernel, same pivots; slow for large n)"),
        },
        scaling="auto",
        prepare=bind_numpy_lapack,  # LAPACK from numpy's OpenBLAS, bound before timing
        batch=BatchSpec("lemke", ("covering", "max_iter"), params=batch_params),
    ),
]
