"""The ``"cuda"`` batch backend: the single-source kernels compiled for a CUDA device.

``lcpcli/solvers/kernels/src/lcp_stack.h`` (the C text the ``"c"`` backend and the test suite
run on the CPU) is compiled by NVRTC through CuPy's :class:`cupy.RawModule` on first use
(once per process, with ``--fmad=false`` so that the device rounds as the CPU does), and its
``__global__`` kernels run one device thread, or a group of lanes of a warp, per problem.
CuPy is the optional ``gpu`` extra (``pip install "lcpcli[gpu]"``); without it, or without a
device, asking for this backend is an :class:`~lcpcli.core.errors.OptionError` (exit 2 on the
command line).

Host arrays (:data:`lcpcli.solvers.batched.StackKernel`): copied to the device, solved, the
outputs copied back (into pinned memory when ``M`` is in pinned memory: pinned in, pinned
out, :func:`output_alloc`).  Device arrays (CuPy, or anything with ``__dlpack__`` on a CUDA device:
torch, JAX) go through :func:`solve_many_device` without a copy of the stack to the host;
only the problems the device hands back travel to the CPU.  Either way what the device does
not certify is run by the ``"cpu"`` kernel and then by the full pipeline, so the verdicts are
those of ``backend="cpu"``.
"""

from __future__ import annotations

import functools
import importlib.resources
import time
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.solvers.backends import SOURCE
from lcpcli.solvers.backends.c import lemke_args, retry_on_cpu, sor_args
from lcpcli.solvers.batched import KERNEL_RETRY, KERNEL_SOLVED, Backend, StackOut

#: The one-line reason this backend cannot run here.
NEEDS = "the cuda backend needs CuPy and a CUDA device (pip install \"lcpcli[gpu]\")"
#: Threads per block of the one-thread-per-problem kernels.
BLOCK = 128
#: Bytes of device workspace the kernels may take at once (the grid is sized to fit; at most
#: a quarter of the free device memory).
WORK_BYTES = 4 << 30
#: Lemke's device kernel: "warp" (a group of lanes of one warp per problem, its workspace in
#: shared memory) or "thread" (one thread per problem).  Both run the code the CPU tests check
#: (the group paths with one lane, and with 8-32 emulated lanes in
#: tests/solvers/test_lane_groups.py).  On an H100 (benchmarks/README.md) both gave the CPU's
#: status, z and pivots on every problem compared, and "warp" ran 3.1x (n = 12) and 13x
#: (n = 50) faster.
LEMKE_VARIANT = "warp"
#: Warps per block of the warp kernel (at most), and the shared memory a block may use for
#: workspaces.
WARPS_PER_BLOCK = 8
SHARED_BYTES = 96 << 10
#: A multiprocessor's shared memory and the part the driver keeps per block (sm_90: H100,
#: H200), from which :func:`warp_launch` picks the warps per block that put the most warps on
#: a multiprocessor.  Speed only: a block never asks for more than SHARED_BYTES.
SM_SHARED_BYTES = 228 << 10
BLOCK_RESERVED_BYTES = 1 << 10
#: NVRTC options: no contraction into FMA (the CPU build has none: the same rounding).
NVRTC_OPTIONS = ("--std=c++11", "--fmad=false")
#: The warp kernel's speed choices by size: rows (largest n, lanes per problem, stage,
#: register budget), the first row whose n fits.  Lanes: 8, 16 or 32 (a warp holds 32 / lanes
#: problems); stage: the certificate reads M, q, z and w from the shared workspace (M copied
#: into the spent tableau's space: no more shared memory) instead of device memory; register
#: budget: the LCP_WARP_MIN_BLOCKS of its
#: ``__launch_bounds__`` (blocks of 256 threads that must fit on one multiprocessor: 1 = up
#: to 255 registers, 4 = 64).  Speed only: every choice computes the same numbers
#: (tests/solvers/test_lane_groups.py, test_gpu_backend.py).  The best of every combination
#: at n = 12, 24, 32, 50 in benchmarks/gpu_sweep.py's runs on an H200 (benchmarks/README.md,
#: results/gpu_sweep_h200_r4.json, 2026-11-27, blocks shaped by :func:`warps_per_block`; the
#: n = 50 budget from results/gpu_sweep_h200_r5_run*.json, 2026-11-28: budget 2 ahead of 1 by
#: 3-4 % in both runs); sizes above 50, never swept, keep the budget of the earlier sweeps.
WARP_TABLE: tuple[tuple[int, int, bool, int], ...] = (
    (12, 8, False, 2), (24, 16, False, 2), (32, 32, False, 2), (50, 32, True, 2),
    (1 << 62, 32, True, 1))
#: Extra NVRTC options that replace the table's register budget (``-D`` tuning macros of
#: lcp_stack.h), for benchmarks/bench_gpu.py; speed only, never a result.
EXTRA_OPTIONS: tuple[str, ...] = ()
#: Host stacks go to the device in chunks of about this many bytes of M, on two streams, so
#: that the copy of one chunk overlaps the kernel of the one before.
CHUNK_BYTES = 128 << 20
#: A host stack whose M is in pinned memory gets its results in pinned memory too (from
#: CuPy's pinned memory pool; see :func:`output_alloc`); False: in numpy's memory.  Speed only.
#: On an H200 (benchmarks/README.md) 27.5 ms against 66 ms for 10^6 problems of n = 12; two
#: pinned slots of one chunk copied into numpy's memory by the host (tried) were slower than
#: copying straight into it.
PINNED_OUT = True
#: DLPack device types of CUDA memory (kDLCUDA, kDLCUDAHost, kDLCUDAManaged).
DLPACK_CUDA = (2, 3, 13)


def _import_cupy() -> Any | None:
    try:
        import cupy
    except Exception:  # noqa: BLE001 - not installed, or a broken CUDA runtime: no backend
        return None
    return cupy


def device_present() -> bool:
    """Whether CuPy imports and sees at least one CUDA device (never raises)."""
    cp = _import_cupy()
    if cp is None:
        return False
    try:
        return cp.cuda.runtime.getDeviceCount() > 0
    except Exception:  # noqa: BLE001 - no driver / no device
        return False


def require_cupy() -> Any:
    """The cupy module; OptionError (:data:`NEEDS`) without CuPy or a device."""
    if not device_present():
        raise OptionError(NEEDS)
    return _import_cupy()


def source() -> str:
    """The single-source kernels' C text, as shipped in the package."""
    return (importlib.resources.files("lcpcli.solvers.kernels") / SOURCE).read_text()


@functools.cache
def _module(device: int, extra: tuple[str, ...] = ()) -> Any:
    """The compiled module for ``device`` (NVRTC, once per process, device and options)."""
    cp = require_cupy()
    return cp.RawModule(code=source(), options=NVRTC_OPTIONS + extra)


def warp_row(n: int) -> tuple[int, int, bool, int]:
    """The :data:`WARP_TABLE` row of size ``n``."""
    return next(row for row in WARP_TABLE if n <= row[0])


def build_options(name: str, n: int) -> tuple[str, ...]:
    """The extra NVRTC options of kernel ``name`` for problems of size ``n``."""
    if EXTRA_OPTIONS or name != "lcp_lemke_warp_stack":
        return EXTRA_OPTIONS
    blocks = warp_row(n)[3]
    return (f"-DLCP_WARP_MIN_BLOCKS={blocks}",) if blocks != 1 else ()


def kernel(name: str, n: int = 0) -> Any:
    """The device function ``name`` (``lcp_lemke_stack``, ``lcp_lemke_warp_stack`` or
    ``lcp_sor_stack``), as built for problems of size ``n``."""
    cp = require_cupy()
    return _module(cp.cuda.Device().id, build_options(name, n)).get_function(name)


def on_device(a: Any) -> bool:
    """Whether ``a`` lives in CUDA memory (CuPy, or a DLPack producer on a CUDA device)."""
    if hasattr(a, "__cuda_array_interface__"):
        return True
    dev = getattr(a, "__dlpack_device__", None)
    if dev is None:
        return False
    try:
        return int(dev()[0]) in DLPACK_CUDA
    except Exception:  # noqa: BLE001 - not a DLPack device query we understand
        return False


def as_device(a: Any, cp: Any) -> Any:
    """``a`` as a C-contiguous float64 CuPy array: no copy for a CuPy or DLPack device array
    that already is one; host arrays are copied to the device."""
    if not isinstance(a, cp.ndarray):
        a = cp.from_dlpack(a) if on_device(a) and hasattr(a, "__dlpack__") else cp.asarray(a)
    return cp.ascontiguousarray(a, dtype=cp.float64)


def _copy_in(a: Any, cp: Any) -> Any:
    """Host array ``a`` on the device, copied on the current stream (asynchronous from pinned
    memory: no staging copy); anything else as :func:`as_device`."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous:
        d = cp.empty(a.shape, cp.float64)
        d.set(a, stream=cp.cuda.get_current_stream())
        return d
    return as_device(a, cp)


def _grid(K: int, slot_bytes: int, per_block: int, cp: Any) -> int:
    """Blocks of ``per_block`` workspace slots to launch: enough for every problem, within
    :data:`WORK_BYTES` and a quarter of the free device memory."""
    budget = min(WORK_BYTES, cp.cuda.runtime.memGetInfo()[0] // 4)
    most = max(1, budget // max(1, slot_bytes * per_block))
    return int(max(1, min(-(-K // per_block), most)))


def _outputs(K: int, n: int, cp: Any) -> dict[str, Any]:
    """The device outputs of a stack: not computed yet (``code`` RETRY, ``error`` Inf), except
    for n = 0, where every problem is solved by the empty z (code SOLVED, error 0)."""
    empty = n == 0
    return {"z": cp.zeros((K, n)), "w": cp.zeros((K, n)),
            "code": cp.full(K, KERNEL_SOLVED if empty else KERNEL_RETRY, cp.int8),
            "iterations": cp.zeros(K, cp.int64), "error": cp.full(K, 0.0 if empty else np.inf),
            "residual": cp.full(K, 0.0 if empty else np.nan)}


def run_lemke(Md: Any, qd: Any, *, tol: float, options: Mapping[str, Any], scaling: str,
              variant: str | None = None) -> dict[str, Any]:
    """Lemke and the certificate on the device stack ``Md`` (K, n, n), ``qd`` (K, n): device
    arrays ``z``, ``w``, ``code``, ``iterations``, ``error``, ``residual``.  ``variant``:
    "thread" or "warp" (default :data:`LEMKE_VARIANT`)."""
    from lcpcli.solvers.kernels.stack_c import workspace

    cp = require_cupy()
    variant = variant or LEMKE_VARIANT
    if variant not in ("thread", "warp"):
        raise OptionError(f"unknown cuda Lemke variant '{variant}' (thread, warp)")
    K, n = qd.shape
    o = _outputs(K, n, cp)
    if K == 0 or n == 0:  # nothing to solve: every (empty) problem is solved by z = ()
        return o
    a = lemke_args(n, options, scaling)
    dw, iw = workspace("lemke", n)
    d = cp.ones(n) if a["d"] is None else cp.asarray(a["d"], dtype=cp.float64)
    bal = a["balance"] or (-1, 0, 0)
    head = (np.int64(K), np.int64(n), Md, qd, np.int32(a["d"] is not None), d,
            np.int64(a["max_iter"]), np.float64(a["piv_tol"]), np.float64(a["tie_tol"]),
            np.float64(tol), np.float64(a["polished"]), np.int32(bal[0]), np.int32(bal[1]),
            np.int32(bal[2]))
    tail = (o["z"], o["w"], o["code"], o["iterations"], o["error"], o["residual"])
    if variant == "thread":
        blocks = _grid(K, 8 * (dw + iw), BLOCK, cp)
        work = cp.empty(blocks * BLOCK * dw, cp.float64)
        iwork = cp.empty(blocks * BLOCK * iw, cp.int64)
        kernel("lcp_lemke_stack", n)((blocks,), (BLOCK,), head + (work, iwork) + tail)
        return o
    g = warp_launch(n)
    blocks = _grid(K, 8 * g.slots, g.groups, cp)
    work = cp.empty(blocks * g.groups * g.slots, cp.float64)
    fn = kernel("lcp_lemke_warp_stack", n)
    if g.shared > 48 << 10:
        fn.max_dynamic_shared_size_bytes = g.shared
    fn((blocks,), (32 * g.warps,),
       head + (np.int32(g.lanes), np.int32(g.shared > 0), np.int32(g.stage), work) + tail,
       shared_mem=g.shared)
    return o


class WarpLaunch(NamedTuple):
    """How the warp kernel runs problems of one size: ``lanes`` per problem, ``warps`` per
    block, ``groups`` (problems) per block, ``stage`` (M, q, z, w in shared memory),
    ``shared`` bytes of shared memory per block (0: the workspace in device memory),
    ``slots``: 8-byte workspace slots per group in device memory."""

    lanes: int
    warps: int
    groups: int
    stage: bool
    shared: int
    slots: int


def warp_launch(n: int, lanes: int | None = None, stage: bool | None = None) -> WarpLaunch:
    """The warp kernel's launch shape for size ``n`` (:data:`WARP_TABLE`,
    :data:`WARPS_PER_BLOCK`, :data:`SHARED_BYTES`; ``lanes``/``stage`` override the table).
    The fast part of each group's workspace goes to shared memory when one warp's groups fit
    in :data:`SHARED_BYTES`, else everything stays in device memory (and nothing is
    staged)."""
    from lcpcli.solvers.kernels.stack_c import group_slots

    row = warp_row(n)
    lanes = row[1] if lanes is None else lanes
    stage = row[2] if stage is None else stage
    if lanes not in (8, 16, 32):
        raise OptionError(f"lanes per problem must be 8, 16 or 32, not {lanes}")
    per_warp = 32 // lanes
    fast, cold = group_slots(n)
    if 8 * fast * per_warp <= SHARED_BYTES:
        warps = warps_per_block(8 * fast * per_warp, warp_budget(n))
        return WarpLaunch(lanes, warps, warps * per_warp, bool(stage),
                          warps * per_warp * 8 * fast, fast + cold)
    return WarpLaunch(lanes, 4, 4 * per_warp, False, 0, fast + cold)


def warp_budget(n: int) -> int:
    """The register budget (``LCP_WARP_MIN_BLOCKS``) the warp kernel for size ``n`` is built
    with: :func:`build_options`' define, else the kernel's default, 1."""
    for opt in build_options("lcp_lemke_warp_stack", n):
        if opt.startswith("-DLCP_WARP_MIN_BLOCKS="):
            return int(opt.split("=", 1)[1])
    return 1


def warps_per_block(warp_bytes: int, min_blocks: int) -> int:
    """Warps per block (1 to :data:`WARPS_PER_BLOCK`, a block within :data:`SHARED_BYTES`)
    that put the most warps on one multiprocessor, each warp's groups taking ``warp_bytes``
    of shared memory: blocks per multiprocessor limited by :data:`SM_SHARED_BYTES` (less
    :data:`BLOCK_RESERVED_BYTES` a block) and by the registers of a build whose
    ``__launch_bounds__`` fits ``min_blocks`` blocks of 8 warps; ties: the larger block."""
    cap = max(1, min(WARPS_PER_BLOCK, SHARED_BYTES // warp_bytes))

    def resident(w: int) -> tuple[int, int]:
        blocks = min(SM_SHARED_BYTES // (w * warp_bytes + BLOCK_RESERVED_BYTES),
                     8 * max(1, min_blocks) // w)
        return w * blocks, w
    return max(range(1, cap + 1), key=resident)


def run_sor(Md: Any, qd: Any, lo: Any, up: Any, *, tol: float,
            options: Mapping[str, Any]) -> dict[str, Any]:
    """Projected SOR and the certificate on the device stack (``lo``/``up``: None or (K, n)
    device bounds); outputs as :func:`run_lemke`."""
    from lcpcli.solvers.kernels.stack_c import workspace

    cp = require_cupy()
    K, n = qd.shape
    o = _outputs(K, n, cp)
    if K == 0 or n == 0:  # nothing to solve: every (empty) problem is solved by z = ()
        return o
    a = sor_args(options)
    if lo is not None:
        cp.clip(cp.zeros((K, n)), lo, up, out=o["z"])
    dw, iw = workspace("sor", n)
    blocks = _grid(K, 8 * (dw + iw), BLOCK, cp)
    work = cp.empty(blocks * BLOCK * dw, cp.float64)
    iwork = cp.empty(blocks * BLOCK * iw, cp.int64)
    dummy = cp.zeros(1)
    kernel("lcp_sor_stack", n)(
        (blocks,), (BLOCK,),
        (np.int64(K), np.int64(n), Md, qd, np.int32(lo is not None),
         dummy if lo is None else lo, dummy if up is None else up, np.float64(a["omega"]),
         np.int64(a["max_iter"]), np.float64(tol), work, iwork, o["z"], o["w"], o["code"],
         o["iterations"], o["error"], o["residual"]))
    return o


def _bounds(lower: Any, upper: Any, K: int, n: int, cp: Any) -> tuple[Any, Any]:
    if lower is None:
        return None, None
    lo = cp.broadcast_to(as_device(lower, cp), (K, n))
    up = cp.broadcast_to(as_device(upper, cp), (K, n))
    return cp.ascontiguousarray(lo), cp.ascontiguousarray(up)


def _chunks(K: int, n: int) -> list[tuple[int, int]]:
    """[start, stop) ranges of a host stack's problems: about :data:`CHUNK_BYTES` of M each."""
    step = max(1, CHUNK_BYTES // max(1, 8 * n * n))
    return [(a, min(K, a + step)) for a in range(0, K, step)]


def _host_kernel(name: str):  # noqa: ANN202 - a StackKernel
    def run(M: Any, q: Any, lower: Any, upper: Any, *, tol: float,
            options: Mapping[str, Any], out: StackOut, threads: int,
            scaling: str = "none") -> None:
        cp = require_cupy()
        K, n = np.shape(q)
        chunks = _chunks(K, n)
        streams = (cp.cuda.Stream(non_blocking=True), cp.cuda.Stream(non_blocking=True))
        direct = _pinned(out.code, cp)  # results in pinned memory: copied asynchronously
        pending: list[tuple[Any, dict[str, Any], int, int, tuple[Any, Any]]] = []

        def collect() -> None:  # the oldest chunk's outputs to the caller's arrays
            stream, o, a, b, _inputs = pending.pop(0)  # inputs held until the kernel ran
            if not direct:  # into numpy's memory: each copy blocks the host
                with stream:
                    for key, arr in o.items():
                        arr.get(stream=stream, out=getattr(out, key)[a:b])
            stream.synchronize()  # (direct: its copies were queued after its kernel)

        # chunk c's copy in and kernel are queued on one stream while chunk c - 1 runs on the
        # other; pinned inputs make the copies in asynchronous (pageable ones still work, with
        # less overlap), and pinned results let chunk c's copy out be queued after its kernel;
        # into numpy's memory chunk c - 1's results are fetched after chunk c is queued
        for c, (a, b) in enumerate(chunks):
            stream = streams[c % 2]
            with stream:
                Md, qd = _copy_in(M[a:b], cp), _copy_in(q[a:b], cp)
                if name == "lemke":
                    o = run_lemke(Md, qd, tol=tol, options=options, scaling=scaling)
                else:
                    lo = None if lower is None else np.broadcast_to(lower, (K, n))[a:b]
                    up = None if upper is None else np.broadcast_to(upper, (K, n))[a:b]
                    o = run_sor(Md, qd, *_bounds(lo, up, b - a, n, cp), tol=tol,
                                options=options)
                if direct:
                    for key, arr in o.items():
                        arr.get(stream=stream, out=getattr(out, key)[a:b], blocking=False)
            pending.append((stream, o, a, b, (Md, qd)))
            if len(pending) > 1:
                collect()
        while pending:
            collect()
        retry_on_cpu(name, M, q, lower, upper, tol=tol, options=options, out=out,
                     threads=threads, scaling=scaling)
    return run


def _pinned(a: Any, cp: Any) -> bool:
    """Whether host array ``a`` lives in page-locked (pinned) memory CUDA knows of."""
    if not isinstance(a, np.ndarray) or a.size == 0:
        return False
    try:
        return int(cp.cuda.runtime.pointerGetAttributes(a.ctypes.data).type) == 1  # host
    except Exception:  # noqa: BLE001 - an unknown pointer or an older runtime: not pinned
        return False


def _pinned_empty(cp: Any) -> Any:
    """An allocator ``(shape, dtype) -> numpy array`` in pinned memory from CuPy's pinned
    memory pool (freed arrays go back to the pool, so a loop of calls reuses the pages)."""
    def alloc(shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        dtype = np.dtype(dtype)
        mem = cp.cuda.alloc_pinned_memory(max(1, int(np.prod(shape)) * dtype.itemsize))
        return np.ndarray(shape, dtype, buffer=mem)
    return alloc


def output_alloc(M: Any) -> Any:
    """The allocator of a host stack's results (:attr:`Backend.output_alloc`): pinned memory
    when ``M`` is in pinned memory and :data:`PINNED_OUT` (pinned in, pinned out: the device
    then copies each chunk's results while it works on the next, with no host copy), else
    None (numpy's memory)."""
    if not PINNED_OUT:
        return None
    cp = require_cupy()
    return _pinned_empty(cp) if _pinned(M, cp) else None


class _HostRows:
    """Problem ``k`` of a device stack copied to the host on indexing (for ``auto``'s
    sample: a few problems, never the stack)."""

    def __init__(self, a: Any) -> None:
        self.a = a
        self.shape = a.shape

    def __getitem__(self, k: int) -> np.ndarray:
        return self.a[k].get()


def solve_many_device(M: Any, q: Any, method: str | None, *, tol: float | None,
                      lower: Any, upper: Any, n_eq: int, threads: int | None, on_error: str,
                      options: dict[str, Any]) -> Any:
    """:func:`lcpcli.solve_many` for a stack in device memory: the StackResult's ``z`` and
    ``w`` are CuPy arrays (K, n) on the same device (zero-copy back to torch/JAX through
    DLPack); ``status``, ``iterations``, ``error``, ``residual`` are host arrays (K,).  Only
    the problems the device hands back are copied to the host (and solved there by
    ``solve_many(..., backend="cpu")``, whose verdicts they get)."""
    from lcpcli import stacks
    from lcpcli.core.result import STATUS_CODES, StackResult, Status
    from lcpcli.solvers.request import check_kind, method_of, resolve_tol

    start = time.perf_counter()
    cp = require_cupy()
    Md, qd = as_device(M, cp), as_device(q, cp)
    if Md.ndim != 3 or qd.ndim != 2 or Md.shape != (qd.shape[0], qd.shape[1], qd.shape[1]):
        raise ProblemError(f"a stack needs M of shape (K, n, n) and q of shape (K, n); got M "
                           f"{Md.shape} and q {qd.shape}")
    if n_eq:
        raise OptionError("the cuda backend's device path solves LCPs and box LCPs; give an "
                          "MLCP (n_eq > 0) as host arrays")
    K, n = qd.shape
    lo, up = _bounds(lower, upper, K, n, cp)
    spec = method_of(method)
    kind = "box" if lo is not None else "lcp"
    check_kind(spec, kind)
    spec.parse_options(options)
    tol = resolve_tol(spec, tol)
    qh = qd.get()
    loh, uph = (None, None) if lo is None else (lo.get(), up.get())
    run_spec, kernel_options = stacks._batched_method(spec, kind, options, _HostRows(Md), qh,
                                                      loh, uph)
    if run_spec is None:
        raise OptionError(f"method '{spec.name}' (with these options) has no batched kernel: "
                          f"give the stack as host arrays")
    name = run_spec.batch.kernel
    if name == "lemke":
        o = run_lemke(Md, qd, tol=tol, options=kernel_options, scaling=run_spec.scaling)
    else:
        o = run_sor(Md, qd, lo, up, tol=tol, options=kernel_options)
    code = o["code"].get()
    status = np.where(code == KERNEL_SOLVED, STATUS_CODES[Status.SOLVED],
                      STATUS_CODES[Status.UNSOLVED]).astype(np.int8)
    iterations, error, residual = o["iterations"].get(), o["error"].get(), o["residual"].get()
    retry = np.flatnonzero(code != KERNEL_SOLVED)
    messages: dict[int, str] = {}
    methods_of: dict[int, str] = {}
    results: dict[int, Any] = {}
    retried = np.zeros(K, bool)
    if retry.size:
        rd = cp.asarray(retry)
        sub = stacks.solve_many(Md[rd].get(), qh[retry], spec.name, tol=tol,
                                lower=None if loh is None else loh[retry],
                                upper=None if uph is None else uph[retry], threads=threads,
                                backend="cpu", on_error=on_error, **options)
        o["z"][rd] = cp.asarray(sub.z)
        o["w"][rd] = cp.asarray(sub.w)
        status[retry], iterations[retry] = sub.status, sub.iterations
        error[retry], residual[retry] = sub.error, sub.residual
        retried[retry] = True
        for j, k in enumerate(retry.tolist()):
            for src, dst in ((sub.messages, messages), (sub.methods, methods_of),
                             (sub.results, results)):
                if j in src:
                    dst[k] = src[j]
    return StackResult(z=o["z"], w=o["w"], status=status, iterations=iterations, error=error,
                       residual=residual, method=run_spec.batch.runs_as or run_spec.name,
                       tol=tol, seconds=time.perf_counter() - start, retried=retried,
                       messages=messages, methods=methods_of, batched=True, results=results)


def backend() -> Backend:
    """The ``"cuda"`` backend; OptionError (:data:`NEEDS`) without CuPy or a device."""
    require_cupy()
    return Backend("cuda", {"lemke": _host_kernel("lemke"), "sor": _host_kernel("sor")},
                   output_alloc)
