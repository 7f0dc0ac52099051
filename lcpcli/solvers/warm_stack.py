"""Warm-started stacks: each problem of a stack starts from its basis in a previous stack.

``lcpcli.solve_many(M, q, warm=previous)`` (``previous``: a :class:`StackResult` of a stack of
the same shape, a (K, n) array of bases, booleans with True: ``z_i`` basic, or of points
``z0``, whose bases are ``{i: z0_i > 0}``).  When the stack runs Lemke's batched kernel on the
``"cpu"`` backend (LCPs below n = 200: :func:`uses_warm_kernel`), every problem runs, in the
same compiled call (:func:`lcpcli.solvers.kernels.batch.lemke_warm_stack`), block principal
pivoting from its basis (one factorisation of ``M_FF`` when the basis is still right, at most
:data:`WARM_ITER` iterations: Júdice & Pires' block pivots, Murty's least-index fallback; only
the first on a matrix with a diagonal entry that is not positive, which is no P-matrix), then
Lemke with the covering ray from that basis (the compiled form of
:mod:`lcpcli.solvers.methods.lemke_warm`: cold Lemke on the principal pivot transform on the
basis, at most ``lemke_warm.WARM_MAX_PIVOTS`` pivots).  A singular basis block is repaired
(the dependent pairs leave the basis).  The answer is kept only when it passes the
certificate; any other problem is solved by cold Lemke in the same call, and what that leaves
uncertified goes through the one-problem pipeline as in a cold stack.  The warm start never
claims ``no_solution``, so a problem's verdict is never worse than a cold stack's (it can be
better: the warm path sets rounding-level basic z's to 0 when the certificate prefers it,
which the cold kernel does not).  Each certified answer's basis (the certificate's pair
states) is returned for the next step (:attr:`StackResult.basis`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.core.certificate import BETWEEN
from lcpcli.core.errors import OptionError
from lcpcli.core.result import StackResult

#: BPP iterations a problem may take from its warm basis before cold Lemke takes over.
WARM_ITER = 2


def uses_warm_kernel(spec: Any, lower: Any, K: int, n: int, backend: str) -> bool:
    """Does the stack start each problem from its basis in the batched kernel?  For Lemke's
    kernel on the ``"cpu"`` backend, LCPs below n = :data:`lcpcli.solvers.warm.WARM_MIN_N`
    (from there on a warm :func:`lcpcli.solve` per problem, which keeps its block's factors
    and uses LAPACK, beats the kernel's unblocked LU)."""
    from lcpcli.solvers.warm import WARM_MIN_N

    return (spec.batch is not None and spec.batch.kernel == "lemke" and lower is None
            and backend == "cpu" and n < WARM_MIN_N and K > 0)


def stack_bases(warm: Any, K: int, n: int) -> np.ndarray:
    """The (K, n) int8 warm bases of ``warm`` (1: ``z_i`` basic; a row of -1: none, e.g. a
    problem that was not solved or whose warm row has NaN).  OptionError on a wrong shape."""
    if isinstance(warm, StackResult):
        if warm.pivot_basis is not None and np.shape(warm.pivot_basis) == (K, n):
            # the pivoting's bases (degenerate pairs included); rows it did not record: the
            # certificate's
            bases = np.array(warm.pivot_basis, dtype=np.int8)
            if warm.basis is not None and n:
                none = bases[:, 0] < 0
                bases[none] = np.equal(warm.basis[none], BETWEEN)
        elif warm.basis is not None:  # a solved problem's z is finite (it passed the certificate)
            bases = np.equal(warm.basis, BETWEEN).view(np.int8)
        else:
            rows = np.asarray(warm.z)
            bases = (rows > 0).view(np.int8)
            if bases.shape == (K, n):
                bases[~np.isfinite(rows).all(axis=1)] = -1
        if bases.shape != (K, n):
            raise OptionError(f"warm start of a stack must have shape ({K}, {n}), got "
                              f"{bases.shape}")
        bases[~warm.solved] = -1
        return np.ascontiguousarray(bases)
    rows = np.asarray(warm)
    if rows.shape != (K, n):
        raise OptionError(f"warm start of a stack must have shape ({K}, {n}), got {rows.shape}")
    if rows.dtype.kind == "b":
        return np.ascontiguousarray(rows.astype(np.int8))
    bases = (rows > 0).astype(np.int8)
    bases[~np.isfinite(rows).all(axis=1)] = -1
    return np.ascontiguousarray(bases)


def lemke_warm(M: np.ndarray, q: np.ndarray, bases: np.ndarray, *, tol: float,
               options: dict[str, Any], out: Any, threads: int,
               scaling: str = "none") -> tuple[np.ndarray, np.ndarray]:
    """Run the warm kernel on the stack (``out``: a preallocated
    :class:`lcpcli.solvers.batched.StackOut`); returns ``(state, warm)``: the (K, n) int8
    basis of every certified answer and the (K,) int8 mark of the problems the warm start
    itself solved."""
    from lcpcli.analysis.scaling import BALANCED, MAX_ROUNDS, Q_BALANCED
    from lcpcli.core.tolerances import PIVOT_TOL, POLISHED, TIE_TOL
    from lcpcli.solvers.kernels import batch
    from lcpcli.solvers.methods.lemke import covering_vector, default_max_iter
    from lcpcli.solvers.methods.lemke_warm import WARM_MAX_PIVOTS

    K, n = q.shape
    d = covering_vector(n, options.get("covering"))
    limit = options.get("max_iter") or default_max_iter(n)
    balance = None if scaling == "none" else (BALANCED, Q_BALANCED, MAX_ROUNDS)
    state = np.zeros((K, n), np.int8)
    warm = np.zeros(K, np.int8)
    batch.lemke_warm_stack(M, q, d, bases, limit, WARM_ITER, WARM_MAX_PIVOTS, PIVOT_TOL,
                           TIE_TOL, tol, out.z,
                           out.w, out.code, out.iterations, out.error, out.residual, state,
                           warm, threads, balance, POLISHED, out.cert, out.pivot_basis)
    return state, warm
