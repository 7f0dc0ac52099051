"""The single-source batched kernels: on a CUDA device (``backend="cuda"``) and on the CPU.

On a machine with a device (one run, a few minutes; nothing is built but the NVRTC module):

    PYTHONPATH=. python benchmarks/bench_gpu.py --out "$OUT/bench_gpu.json"

measures, for random positive definite stacks (benchmarks/bench_stack.py's ``make_stack``:
``M = A A^T / n + I``) at n = 12 (K = 10^6) and n = 50 (K = 10^5), Lemke (lexicographic)
with the certificate:

* ``kernel``: the device kernel alone on data already on the device (CUDA events), for both
  variants (``thread``: one thread per problem; ``warp``: a group of lanes per problem, as
  ``backends/cuda.py``'s WARP_TABLE or ``--table`` says);
* ``pinned``: ``solve_many(M, q, backend="cuda")`` from host arrays in pinned memory (copy in,
  kernel, copy out, the CPU for what the device hands back);
* ``pageable``: the same from ordinary numpy arrays;
* ``cpu``: ``solve_many(M, q)`` (the ``"cpu"`` backend, every core) on the same stack;
* ``verdicts``: status, z and pivots of each variant against the CPU on a subsample (the
  end-to-end runs use the fastest variant that matched).

Rates are certified problems per second (problems whose certificate passed on the path
measured, divided by its time).  Without a device (``--cpu``) it compares the single-source
kernel compiled for the CPU (``backend="c"``) with the ``"cpu"`` backend's Lemke at n = 12
(K = 100,000) and n = 50 (K = 10,000), one thread, best of ``--repeat`` interleaved runs.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _gpu import use_cubins  # noqa: E402
from _results import write_cases  # noqa: E402
from bench_stack import make_stack  # noqa: E402

import lcpcli  # noqa: E402
from lcpcli.solvers.batched import KERNEL_SOLVED, StackOut, get_backend  # noqa: E402
from lcpcli.solvers.registry import get_method  # noqa: E402


def best_of(repeat: int, fn) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def cpu_case(n: int, K: int, repeat: int, threads: int) -> dict:
    """The "c" backend's kernel (single source, no CPU fallback) against the "cpu" one."""
    from lcpcli.solvers.backends.c import lemke_args
    from lcpcli.solvers.kernels import stack_c

    M, q = make_stack(K, n, seed=2026)
    out: dict = {"n": n, "K": K, "threads": threads}
    spec = get_method("lemke")
    cpu = get_backend("cpu").kernel("lemke")
    o = StackOut.empty(K, n)
    a = lemke_args(n, {}, spec.scaling)
    s = StackOut.empty(K, n)

    def base() -> None:
        cpu(M, q, None, None, tol=spec.default_tol, options={}, out=o, threads=threads,
            scaling=spec.scaling)

    def single() -> None:
        stack_c.lemke_stack(M, q, a["d"], a["max_iter"], a["piv_tol"], a["tie_tol"],
                            spec.default_tol, a["polished"], a["balance"], s.z, s.w, s.code,
                            s.iterations, s.error, s.residual, threads)
    # interleaved (the machine may be shared): the best of `repeat` runs of each
    t_cpu = t_c = float("inf")
    for _ in range(repeat):
        t_cpu = min(t_cpu, best_of(1, base))
        t_c = min(t_c, best_of(1, single))
    ok = s.code == KERNEL_SOLVED
    out.update(cpu_s=t_cpu, c_s=t_c, cpu_per_s=K / t_cpu,
               c_certified_per_s=int(ok.sum()) / t_c, c_over_cpu_time=t_c / t_cpu,
               c_certified=int(ok.sum()), cpu_certified=int((o.code == KERNEL_SOLVED).sum()),
               same_z_where_certified=bool(np.array_equal(s.z[ok], o.z[ok])),
               same_pivots_where_certified=bool(np.array_equal(s.iterations[ok],
                                                               o.iterations[ok])))
    return out


def gpu_case(n: int, K: int, sample: int, repeat: int,
             min_blocks: tuple[int, ...] = (1, 2, 3, 4), profile: bool = False,
             variants: tuple[str, ...] = ("thread", "warp"), e2e: str = "all") -> dict:
    """The device at size n; ``warp`` is the shipped choice (backends/cuda.py's
    WARP_MIN_BLOCKS), ``warp_mbK`` the warp kernel built with LCP_WARP_MIN_BLOCKS = K."""
    import cupy as cp
    import cupyx

    from lcpcli.solvers.backends import cuda

    M, q = make_stack(K, n, seed=2026)
    spec = get_method("lemke")
    out: dict = {"n": n, "K": K}
    t = time.perf_counter()
    cuda.kernel("lcp_lemke_stack")  # NVRTC, once per process
    out["nvrtc_s"] = time.perf_counter() - t
    idx = np.random.default_rng(1).choice(K, size=min(sample, K), replace=False)
    host = lcpcli.solve_many(M[idx], q[idx], "lemke")
    Md, qd = cp.asarray(M), cp.asarray(q)
    usable = []
    # the two kernels, and the warp kernel under tighter register budgets (__launch_bounds__
    # minimum blocks per multiprocessor: more warps resident, perhaps spills)
    configs = [(v, v, ()) for v in variants] + [
        (f"warp_mb{k}", "warp", (f"-DLCP_WARP_MIN_BLOCKS={k}",)) for k in min_blocks]
    for label, variant, extra in configs:
        # verdicts on a subsample: the device's against the CPU's, problem by problem
        cuda.LEMKE_VARIANT = variant
        cuda.EXTRA_OPTIONS = extra
        dev = lcpcli.solve_many(Md[cp.asarray(idx)], qd[cp.asarray(idx)], "lemke",
                                backend="cuda")
        same = {"same_status": bool(np.array_equal(dev.status, host.status)),
                "same_z": bool(np.array_equal(dev.z.get(), host.z)),
                "same_pivots": bool(np.array_equal(dev.iterations, host.iterations)),
                "device_retried": int(dev.retried.sum())}
        out[f"{label}_verdicts"] = same
        times = []
        for _ in range(repeat):
            e0, e1 = cp.cuda.Event(), cp.cuda.Event()
            e0.record()
            o = cuda.run_lemke(Md, qd, tol=spec.default_tol, options={}, scaling=spec.scaling,
                               variant=variant)
            e1.record()
            e1.synchronize()
            times.append(cp.cuda.get_elapsed_time(e0, e1) / 1e3)
        certified = int((o["code"] == KERNEL_SOLVED).sum())
        out[f"{label}_kernel_s"] = min(times)
        out[f"{label}_kernel_certified_per_s"] = certified / min(times)
        del o
        try:  # registers per thread and spilled (local) bytes of this build
            at = cuda.kernel("lcp_lemke_warp_stack" if variant == "warp"
                             else "lcp_lemke_stack", n).attributes
            out[f"{label}_regs_local_bytes"] = [int(at["num_regs"]),
                                                int(at["local_size_bytes"])]
        except Exception:  # noqa: BLE001, S110 - optional figures
            pass
        if same["same_status"] and same["same_z"] and same["same_pivots"]:
            usable.append((min(times), label, variant, extra))
    out["verdict_sample"] = int(idx.size)
    cuda.EXTRA_OPTIONS = ()
    # projected Gauss-Seidel (the "sor" kernel, omega = 1) on the same stack, kernel alone
    pgs = get_method("pgs")
    times = []
    for _ in range(repeat):
        e0, e1 = cp.cuda.Event(), cp.cuda.Event()
        e0.record()
        o = cuda.run_sor(Md, qd, None, None, tol=pgs.default_tol, options={"omega": 1.0})
        e1.record()
        e1.synchronize()
        times.append(cp.cuda.get_elapsed_time(e0, e1) / 1e3)
    out["pgs_kernel_s"] = min(times)
    out["pgs_kernel_certified_per_s"] = int((o["code"] == KERNEL_SOLVED).sum()) / min(times)
    out["pgs_mean_sweeps"] = float(o["iterations"].mean())
    del o
    try:  # registers and local memory of each kernel (what limits its occupancy)
        out["kernel_attributes"] = {
            name: {k: int(v) for k, v in cuda.kernel(name, n).attributes.items()
                   if k in ("num_regs", "local_size_bytes", "shared_size_bytes",
                            "max_threads_per_block")}
            for name in ("lcp_lemke_stack", "lcp_lemke_warp_stack", "lcp_sor_stack")}
    except Exception as exc:  # noqa: BLE001 - an older CuPy: the figures are optional
        out["kernel_attributes"] = repr(exc)
    del Md, qd
    if not usable:
        out["end_to_end"] = "skipped: no variant gave the CPU's verdicts"
        return out
    best = min(usable)
    out["end_to_end_variant"] = best[1]
    cuda.LEMKE_VARIANT, cuda.EXTRA_OPTIONS = best[2], best[3]
    out["chunk_bytes"] = cuda.CHUNK_BYTES
    # end to end from pinned host memory, then from pageable memory
    Mp = cupyx.empty_pinned(M.shape, np.float64)
    qp = cupyx.empty_pinned(q.shape, np.float64)
    Mp[...] = M
    qp[...] = q
    # the copy floor: the whole stack from pinned memory to the device in one copy
    dev_m = cp.empty(M.shape, cp.float64)

    def h2d() -> None:
        dev_m.set(Mp)
        cp.cuda.Device().synchronize()
    out["h2d_pinned_M_s"] = best_of(repeat, h2d)
    out["h2d_pinned_M_gb_per_s"] = M.nbytes / out["h2d_pinned_M_s"] / 1e9
    print(json.dumps({"n": n, "h2d_pinned_M_gb_per_s": out["h2d_pinned_M_gb_per_s"]}))
    dev_m = None
    if profile:  # where the host's time goes in one pinned call
        import cProfile
        import io
        import pstats

        lcpcli.solve_many(Mp, qp, "lemke", backend="cuda")  # CuPy's pools warm
        prof = cProfile.Profile()
        prof.enable()
        lcpcli.solve_many(Mp, qp, "lemke", backend="cuda")
        prof.disable()
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(18)
        out["pinned_profile"] = text.getvalue()[-4000:]
        print(out["pinned_profile"], flush=True)
    # the shipped path ("pinned", "pageable"), other chunk sizes, and results in numpy's
    # memory although M is pinned (the behaviour before pinned-out)
    runs = [("pinned", Mp, qp, cuda.CHUNK_BYTES), ("pageable", M, q, cuda.CHUNK_BYTES)]
    runs += [(f"pinned_chunk{c >> 20}M", Mp, qp, c) for c in (32 << 20, 64 << 20, 256 << 20)
             if c != cuda.CHUNK_BYTES]
    runs.append(("pinned_numpy_out", Mp, qp, cuda.CHUNK_BYTES))
    if e2e != "all":
        runs = [r for r in runs if r[0] in e2e.split(",")]
    shipped = cuda.CHUNK_BYTES
    for label, Ma, qa, chunk in runs:
        cuda.CHUNK_BYTES = chunk
        cuda.PINNED_OUT = label != "pinned_numpy_out"
        res = None

        def full(Ma=Ma, qa=qa) -> None:  # noqa: ANN001
            nonlocal res
            res = lcpcli.solve_many(Ma, qa, "lemke", backend="cuda")
        t = time.perf_counter()
        full()  # the first call of this run (pools cold unless an earlier run warmed them)
        out[f"{label}_first_s"] = time.perf_counter() - t
        secs = min(out[f"{label}_first_s"], best_of(repeat - 1, full))
        out[f"{label}_s"] = secs
        out[f"{label}_certified_per_s"] = int(res.solved.sum()) / secs
        out[f"{label}_retried"] = int(res.retried.sum())
        print(json.dumps({"n": n, "end_to_end": label, "s": secs,
                          "first_s": out[f"{label}_first_s"],
                          "certified_per_s": out[f"{label}_certified_per_s"]}), flush=True)
    cuda.CHUNK_BYTES = shipped
    cuda.PINNED_OUT = True
    t = time.perf_counter()
    ref = lcpcli.solve_many(M, q, "lemke")
    out["cpu_s"] = time.perf_counter() - t
    out["cpu_certified_per_s"] = int(ref.solved.sum()) / out["cpu_s"]
    out["cpu_threads"] = os.cpu_count()
    out["end_to_end_same_status"] = bool(np.array_equal(res.status, ref.status))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cpu", action="store_true",
                    help="no device: the single-source kernel on the CPU against 'cpu'")
    ap.add_argument("--out", type=Path, default=None,
                    help="JSON results (default: $OUT/bench_gpu.json, else stdout only)")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every K by this")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="CPU threads (--cpu)")
    ap.add_argument("--sample", type=int, default=20_000, help="problems compared with the CPU")
    ap.add_argument("--sizes", default="12,50", help="n of the device cases (comma-separated)")
    ap.add_argument("--min-blocks", default="1,2,3,4",
                    help="LCP_WARP_MIN_BLOCKS builds of the warp kernel to compare")
    ap.add_argument("--variants", default="thread,warp", help="Lemke device kernels timed")
    ap.add_argument("--e2e", default="all",
                    help="end-to-end runs (comma-separated labels, e.g. pinned,pageable)")
    ap.add_argument("--profile", action="store_true",
                    help="cProfile one pinned end-to-end call per size (the host's share)")
    ap.add_argument("--cubins", type=Path, default=None,
                    help="the warp kernel built ahead with nvcc (mb1.cubin ... mb4.cubin) in "
                         "place of NVRTC builds")
    ap.add_argument("--table", type=Path, default=None,
                    help="a WARP_TABLE for backends/cuda.py (JSON rows, from gpu_sweep.py "
                         "--table-out) instead of the shipped one")
    args = ap.parse_args()
    if args.table is not None:
        from lcpcli.solvers.backends import cuda

        cuda.WARP_TABLE = tuple((int(a), int(b), bool(c), int(d))
                                for a, b, c, d in json.loads(args.table.read_text()))
        print(json.dumps({"warp_table": cuda.WARP_TABLE}), flush=True)
    info = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "python": platform.python_version(), "numpy": np.__version__,
            "machine": platform.platform(), "cpus": os.cpu_count()}
    cases = []
    if args.cpu:
        for n, K in ((12, 100_000), (50, 10_000)):
            cases.append(cpu_case(n, max(1, int(K * args.scale)), args.repeat, args.threads))
            print(json.dumps(cases[-1]), flush=True)
    else:
        import cupy as cp

        props = cp.cuda.runtime.getDeviceProperties(cp.cuda.Device().id)
        from lcpcli.solvers.backends import cuda

        if args.cubins is not None:  # modules built ahead: the package's lookup returns them
            use_cubins(args.cubins)
        info.update(device=props["name"].decode(), cupy=cp.__version__,
                    warp_table=cuda.WARP_TABLE)
        stacks = {12: 1_000_000, 24: 300_000, 32: 200_000, 50: 100_000}
        blocks = tuple(int(b) for b in args.min_blocks.split(",") if b)
        for n in (int(x) for x in args.sizes.split(",")):
            K = stacks.get(n, 100_000)
            cases.append(gpu_case(n, max(1, int(K * args.scale)), args.sample, args.repeat,
                                  blocks, args.profile, tuple(args.variants.split(",")),
                                  args.e2e))
            print(json.dumps(cases[-1]), flush=True)
    write_cases(args.out, "bench_gpu.json", info, cases)


if __name__ == "__main__":
    main()
