"""The ``"c"`` batch backend: the single-source kernels (``src/lcp_stack.h``) on the CPU.

Kernels follow :data:`lcpcli.solvers.batched.StackKernel`.  Problems the single-source kernel
hands back (not balanced enough for it, not certified at rounding level, a ray...) go to the
``"cpu"`` kernel, then (as every ``KERNEL_RETRY``) to the caller's full pipeline.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.core.tolerances import PIVOT_TOL, POLISHED, TIE_TOL
from lcpcli.solvers.batched import KERNEL_SOLVED, Backend, StackOut, get_backend, kernel_params


def lemke_args(n: int, options: Mapping[str, Any], scaling: str) -> dict[str, Any]:
    """The Lemke kernel's parameters, from the same definitions the ``"cpu"`` kernel uses:
    covering vector ``d`` (None: the default, ones, which equilibration leaves alone),
    ``max_iter``, ``piv_tol``, ``tie_tol``, ``polished`` and ``balance``
    (None or (balanced, q_balanced, max_rounds))."""
    from lcpcli.analysis.scaling import BALANCED, MAX_ROUNDS, Q_BALANCED

    p = kernel_params("lemke", n, options)
    return {"d": p["covering"], "max_iter": p["max_iter"],
            "piv_tol": PIVOT_TOL, "tie_tol": TIE_TOL, "polished": POLISHED,
            "balance": None if scaling == "none" else (BALANCED, Q_BALANCED, MAX_ROUNDS)}


def sor_args(options: Mapping[str, Any]) -> dict[str, Any]:
    """The SOR kernel's ``omega`` and ``max_iter`` (as the ``"cpu"`` kernel reads them; they do
    not depend on n)."""
    return kernel_params("sor", 0, options)


def start_point(lower: Any, upper: Any, z: np.ndarray) -> None:
    """SOR's start: 0 projected onto the bounds (as the ``"cpu"`` kernel)."""
    if lower is None:
        z[...] = 0.0
    else:
        np.clip(0.0, lower, upper, out=z)


def retry_on_cpu(kernel: str, M: Any, q: Any, lower: Any, upper: Any, *, tol: float,
                 options: Mapping[str, Any], out: StackOut, threads: int,
                 scaling: str) -> None:
    """Run the ``"cpu"`` backend's ``kernel`` on the problems ``out`` hands back and merge its
    answers (host arrays): then the caller's pipeline sees exactly the problems the ``"cpu"``
    backend would hand it."""
    idx = np.flatnonzero(out.code != KERNEL_SOLVED)
    if idx.size == 0:
        return
    n = out.z.shape[1]
    sub = StackOut.empty(idx.size, n)
    Ms = np.ascontiguousarray(np.asarray(M)[idx])
    qs = np.ascontiguousarray(np.asarray(q)[idx])
    lo = None if lower is None else np.ascontiguousarray(np.asarray(lower)[idx])
    up = None if upper is None else np.ascontiguousarray(np.asarray(upper)[idx])
    get_backend("cpu").kernel(kernel)(Ms, qs, lo, up, tol=tol, options=options, out=sub,
                                      threads=threads, scaling=scaling)
    for name in ("z", "w", "code", "iterations", "error", "residual"):
        getattr(out, name)[idx] = getattr(sub, name)


def _lemke(M: Any, q: Any, lower: Any, upper: Any, *, tol: float, options: Mapping[str, Any],
           out: StackOut, threads: int, scaling: str = "none") -> None:
    from lcpcli.solvers.kernels import stack_c

    a = lemke_args(q.shape[1], options, scaling)
    stack_c.lemke_stack(M, q, a["d"], a["max_iter"], a["piv_tol"], a["tie_tol"], tol,
                        a["polished"], a["balance"], out.z, out.w, out.code, out.iterations,
                        out.error, out.residual, threads)
    retry_on_cpu("lemke", M, q, lower, upper, tol=tol, options=options, out=out,
                 threads=threads, scaling=scaling)


def _sor(M: Any, q: Any, lower: Any, upper: Any, *, tol: float, options: Mapping[str, Any],
         out: StackOut, threads: int, scaling: str = "none") -> None:
    from lcpcli.solvers.kernels import stack_c

    a = sor_args(options)
    start_point(lower, upper, out.z)
    stack_c.sor_stack(M, q, lower, upper, a["omega"], a["max_iter"], tol, out.z, out.w,
                      out.code, out.iterations, out.error, out.residual, threads)
    retry_on_cpu("sor", M, q, lower, upper, tol=tol, options=options, out=out,
                 threads=threads, scaling=scaling)


def backend() -> Backend:
    """The ``"c"`` backend (registered in :mod:`lcpcli.solvers.batched`)."""
    return Backend("c", {"lemke": _lemke, "sor": _sor})
