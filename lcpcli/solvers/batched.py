"""Batched solves: the interface between stacks of problems and the batched kernels.

A **stack** is ``M`` of shape (K, n, n) and ``q`` of shape (K, n) (problem ``k``, 0-based, is
``w = M[k] z + q[k]``), optionally with bounds ``lower``/``upper`` of shape (K, n) (a box LCP).
A method that has a batched kernel declares it in its registry record
(:attr:`lcpcli.solvers.registry.Method.batch`, a :class:`BatchSpec`): the kernel's name, the
method options it understands and, as ``params``, how those options (with the method's defaults)
become the kernel's parameters (:func:`kernel_params`).  Nothing here names a method.

**Backends.**  A backend maps kernel names to callables with one signature
(:class:`StackKernel`)::

    kernel(M, q, lower, upper, *, tol, options, out, threads, scaling) -> None

(``scaling``: the method's equilibration policy, :attr:`Method.scaling`; anything but
``"none"`` asks the kernel to equilibrate each problem that is not balanced, as the one-problem
pipeline does) that fills the preallocated :class:`StackOut` (``z``, ``w``, ``code``,
``iterations``, ``error``, ``residual``); ``code[k]`` is :data:`KERNEL_SOLVED` only when problem
k's answer passed the certificate (:mod:`lcpcli.core.certificate`'s definition, at ``tol``), else
:data:`KERNEL_RETRY` and the caller runs the full one-problem pipeline on it.  The CPU backend
(``"cpu"``) is :mod:`lcpcli.solvers.kernels.batch` (OpenMP threads).  A GPU backend (CuPy or
CUDA) registers itself with :func:`register_backend` and is chosen with ``backend=`` in
:func:`lcpcli.solve_many`; callers do not change.  It may take device arrays and must fill
``out`` with host arrays (or arrays ``numpy.asarray`` accepts).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.core.errors import OptionError
from lcpcli.core.tolerances import PIVOT_TOL, POLISHED, TIE_TOL
from lcpcli.solvers.registry import BatchSpec, methods

#: Kernel ``code`` of a certified answer / of a problem handed back to the full pipeline.
KERNEL_SOLVED = 0
KERNEL_RETRY = 1


@dataclass
class StackOut:
    """Preallocated outputs of a stacked kernel (C-contiguous, host memory)."""

    z: np.ndarray           # (K, n) float64
    w: np.ndarray           # (K, n) float64, M z + q
    code: np.ndarray        # (K,) int8: KERNEL_SOLVED or KERNEL_RETRY
    iterations: np.ndarray  # (K,) int64: pivots or sweeps
    error: np.ndarray       # (K,) float64: the certified error (inf: not computed)
    residual: np.ndarray    # (K,) float64: the certificate's residual (NaN: not computed)
    #: (K, batch.CERT_FIELDS) float64: each certified answer's whole certificate (NaN rows:
    #: none; lcpcli.core.certificate.from_row reads a row), or None: not asked for
    cert: np.ndarray | None = None
    #: (K, n) int8: each certified answer's complementary basis from the pivoting (1: z_i
    #: basic, 0: w_i basic; -1 rows: none), or None: not asked for
    pivot_basis: np.ndarray | None = None

    @classmethod
    def empty(cls, K: int, n: int, certificates: bool = False,
              pivot_basis: bool = False) -> StackOut:
        return cls(np.zeros((K, n)), np.zeros((K, n)), np.full(K, KERNEL_RETRY, np.int8),
                   np.zeros(K, np.int64), np.full(K, np.inf), np.full(K, np.nan),
                   *_extras(K, n, certificates, pivot_basis))

    @classmethod
    def unfilled(cls, K: int, n: int, alloc: Callable[[tuple[int, ...], Any], np.ndarray],
                 certificates: bool = False, pivot_basis: bool = False) -> StackOut:
        """Outputs whose six kernel arrays come from ``alloc(shape, dtype)`` with whatever they
        hold: for a backend whose kernels write every element of them (``cert`` and
        ``pivot_basis`` as :meth:`empty`)."""
        return cls(alloc((K, n), np.float64), alloc((K, n), np.float64), alloc((K,), np.int8),
                   alloc((K,), np.int64), alloc((K,), np.float64), alloc((K,), np.float64),
                   *_extras(K, n, certificates, pivot_basis))


def _extras(K: int, n: int, certificates: bool,
            pivot_basis: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:class:`StackOut`'s ``cert`` and ``pivot_basis``, as asked: NaN rows, -1 rows."""
    cert = None
    if certificates:
        from lcpcli.solvers.kernels.batch import CERT_FIELDS

        cert = np.full((K, CERT_FIELDS), np.nan)
    return cert, np.full((K, n), -1, np.int8) if pivot_basis else None


#: A stacked kernel: ``kernel(M, q, lower, upper, *, tol, options, out, threads, scaling)``
#: (see the module docstring; a plain alias, not a Protocol class: this module is imported by
#: the registry records, on every one-liner's path).
StackKernel = Callable[..., None]


def default_threads() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


#: The work (estimated seconds of one core) a default stack gives each thread at least: a
#: thread costs little to start, but on a busy machine the call waits for the last one to be
#: scheduled again (a scheduler time slice, milliseconds: 20 contact islands of n = 72, 1 ms
#: of work, took a median 16 ms on 2 threads against 1 ms on one at load 4.5).
MIN_THREAD_SECONDS = 0.002


def useful_threads(threads: int, K: int, n: int) -> int:
    """At most ``threads``, and one per :data:`MIN_THREAD_SECONDS` of the stack's estimated
    work (about ``0.2 us + 0.15 ns n^3`` a problem for Lemke's kernels, measured at n = 12
    and 72), at least 1."""
    work = K * (2e-7 + 1.5e-10 * float(n) ** 3)
    return max(1, min(threads, int(work / MIN_THREAD_SECONDS)))


def kernel_params(kernel: str, n: int, options: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters of the batched ``kernel`` for problems of size n: the
    :attr:`BatchSpec.params` of the registered methods that declare ``kernel`` applied to
    ``options`` (policy as data: the record names its kernel and its defaults; backends name
    kernels only).  ``options`` as given when no record declares ``params``."""
    for method in methods().values():
        spec: BatchSpec | None = method.batch
        if spec is not None and spec.kernel == kernel and spec.params is not None:
            return spec.params(n, options)
    return dict(options)


# ------------------------------------------------------------------------------ CPU backend
def _cpu_lemke(M: Any, q: Any, lower: Any, upper: Any, *, tol: float,
               options: Mapping[str, Any], out: StackOut, threads: int,
               scaling: str = "none") -> None:
    from lcpcli.analysis.scaling import BALANCED, MAX_ROUNDS, Q_BALANCED
    from lcpcli.solvers.kernels import batch

    p = kernel_params("lemke", M.shape[1], options)
    balance = None if scaling == "none" else (BALANCED, Q_BALANCED, MAX_ROUNDS)
    batch.lemke_stack(M, q, p["covering"], p["max_iter"], PIVOT_TOL, TIE_TOL, tol, out.z, out.w,
                      out.code, out.iterations, out.error, out.residual, threads, balance, POLISHED,
                      out.cert, out.pivot_basis)


def _cpu_sor(M: Any, q: Any, lower: Any, upper: Any, *, tol: float,
             options: Mapping[str, Any], out: StackOut, threads: int,
             scaling: str = "none") -> None:
    from lcpcli.solvers.kernels import batch

    p = kernel_params("sor", q.shape[1], options)
    if lower is None:
        out.z[...] = 0.0
    else:
        np.clip(0.0, lower, upper, out=out.z)  # the start point, projected onto the box
    batch.sor_stack(M, q, lower, upper, p["omega"], p["max_iter"], tol, out.z, out.w, out.code,
                    out.iterations, out.error, out.residual, threads, out.cert)


@dataclass
class Backend:
    """A named set of stacked kernels (``kernels``: kernel name -> :class:`StackKernel`).
    ``output_alloc``: None (outputs in numpy's memory, :meth:`StackOut.empty`), or, for a
    backend whose kernels write every element of the six kernel arrays, a function of the
    stack's ``M`` that returns the allocator of those arrays (``(shape, dtype) -> array``;
    :meth:`StackOut.unfilled`) or None for numpy's."""

    name: str
    kernels: dict[str, StackKernel] = field(default_factory=dict)
    output_alloc: Callable[[Any], Callable[[tuple[int, ...], Any], np.ndarray] | None] | None \
        = None

    def kernel(self, name: str) -> StackKernel | None:
        return self.kernels.get(name)

    def outputs(self, M: Any, K: int, n: int, certificates: bool = False,
                pivot_basis: bool = False) -> StackOut:
        """The preallocated outputs of a stack of K problems of size n (``M``: its matrices)."""
        alloc = None if self.output_alloc is None else self.output_alloc(M)
        if alloc is None:
            return StackOut.empty(K, n, certificates, pivot_basis)
        return StackOut.unfilled(K, n, alloc, certificates, pivot_basis)


def _single_source(name: str) -> Callable[[], Backend]:
    """The factory of a backend of :mod:`lcpcli.solvers.backends` (imported on first use)."""
    def factory() -> Backend:

        return importlib.import_module(f"lcpcli.solvers.backends.{name}").backend()
    return factory


_BACKENDS: dict[str, Callable[[], Backend]] = {
    "cpu": lambda: Backend("cpu", {"lemke": _cpu_lemke, "sor": _cpu_sor}),
    # the single-source kernels (src/lcp_stack.h) compiled for the CPU / for a CUDA device
    "c": _single_source("c"),
    "cuda": _single_source("cuda"),
}
_LOADED: dict[str, Backend] = {}


def register_backend(name: str, factory: Callable[[], Backend]) -> None:
    """Add a backend (e.g. a GPU one): ``factory()`` is called on first use."""
    _BACKENDS[name] = factory
    _LOADED.pop(name, None)


#: ``backend="auto"`` picks ``"cuda"`` (when CuPy sees a device) for stacks whose M takes at
#: least this many bytes (16 MiB: 14,563 problems of n = 12, 839 of n = 50; the stacked
#: command line's chunks of 32 MiB qualify): below it the device's fixed costs (context,
#: copies, the first NVRTC compile of a process) outweigh the CPU's time.
AUTO_CUDA_MIN_BYTES = 16 << 20


#: The backend :func:`lcpcli.solve_many` uses when given none (``--backend`` sets it for a
#: command's process: the stacked batch path passes no backend of its own).
_DEFAULT_BACKEND = ["cpu"]


def set_default_backend(name: str) -> None:
    """Make ``name`` (a registered backend or ``"auto"``) this process's default; OptionError
    for an unknown name or a backend that cannot run here (e.g. ``cuda`` without a device)."""
    if name != "auto":
        get_backend(name)
    _DEFAULT_BACKEND[0] = name


def default_backend() -> str:
    """This process's default backend (``"cpu"`` unless :func:`set_default_backend` ran)."""
    return _DEFAULT_BACKEND[0]


def choose_backend(name: str, K: int, n: int) -> str:
    """``name``, with ``"auto"`` resolved for a stack of K problems of size n: ``"cuda"`` when
    CuPy imports, a CUDA device is present and M holds at least :data:`AUTO_CUDA_MIN_BYTES`,
    else ``"cpu"``."""
    if name != "auto":
        return name
    if 8 * K * n * n >= AUTO_CUDA_MIN_BYTES:
        from lcpcli.solvers.backends.cuda import device_present

        if device_present():
            return "cuda"
    return "cpu"


def get_backend(name: str) -> Backend:
    """The backend called ``name``; OptionError if there is none."""

    if name not in _LOADED:
        if name not in _BACKENDS:
            raise OptionError(f"unknown batch backend '{name}' (available: "
                              f"{', '.join(sorted(_BACKENDS))})")
        _LOADED[name] = _BACKENDS[name]()
    return _LOADED[name]
