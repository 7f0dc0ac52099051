"""The warp kernel's speed choices on a CUDA device, each checked against the first and the CPU.

    PYTHONPATH=. python benchmarks/gpu_sweep.py --out "$OUT/gpu_sweep.json" \
        [--cubins DIR] [--sizes 12,24,32,50]

For random positive definite stacks (benchmarks/bench_stack.py's ``make_stack``, the sizes of
benchmarks/bench_gpu.py), Lemke with the certificate on data already on the device (CUDA
events, best of ``--repeat``), every combination of the choices that change speed only:

* the register budget (``LCP_WARP_MIN_BLOCKS`` of ``__launch_bounds__``: 1-4),
* lanes per problem (8, 16, 32),
* staging M, q, z, w in shared memory,

the three columns of ``backends/cuda.py``'s ``WARP_TABLE``; with ``--warps``, also the most
warps per block (``WARPS_PER_BLOCK``, within which ``warps_per_block`` shapes the block for
residency; not a table column: the table is made from the shipped value's rows,
``best_any_warps`` says whether another did better).

Every combination must give the first one's z, w, code, pivots, error and residual bit for
bit (``same``), and the first one the CPU's status, z and pivots on a sample (``cpu``).
``digest`` (SHA-256 of the first one's outputs, per size) lets another build be checked
against this one bit for bit: ``--against EARLIER.json`` records ``same_as_against`` per
size (``gpu_device_run.sh`` checks each of its ``VARIANTS`` against the shipped build so).
``--cubins DIR``: modules built ahead with nvcc (``mb1.cubin`` ... ``mb4.cubin``: the
current ``lcp_stack.h`` with ``-DLCP_WARP_MIN_BLOCKS=k``), so that the sweep does not wait on
NVRTC; without it each budget is compiled by NVRTC as the package does.
An earlier ``lcp_stack.h`` of the same kernel signature is compared by sweeping its own
build (``gpu_device_run.sh``'s ``BASELINE``).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _gpu import use_cubins  # noqa: E402
from _results import write_cases  # noqa: E402
from bench_stack import make_stack  # noqa: E402

import lcpcli  # noqa: E402
from lcpcli.solvers.backends import cuda  # noqa: E402
from lcpcli.solvers.batched import KERNEL_SOLVED  # noqa: E402
from lcpcli.solvers.registry import get_method  # noqa: E402

STACKS = {12: 1_000_000, 24: 300_000, 32: 200_000, 50: 100_000}
KEYS = ("z", "w", "code", "iterations", "error", "residual")


def timed(cp, fn, repeat: int) -> float:  # noqa: ANN001
    best = float("inf")
    for _ in range(repeat):
        e0, e1 = cp.cuda.Event(), cp.cuda.Event()
        e0.record()
        fn()
        e1.record()
        e1.synchronize()
        best = min(best, cp.cuda.get_elapsed_time(e0, e1) / 1e3)
    return best


def digest(outputs: dict) -> str:
    """SHA-256 of a run's outputs (:data:`KEYS`, in that order, as host arrays)."""
    h = hashlib.sha256()
    for k in KEYS:
        h.update(np.ascontiguousarray(outputs[k]).tobytes())
    return h.hexdigest()


def against(path: Path | None) -> dict[tuple[int, int], str]:
    """The first combination's :func:`digest` per (n, K) of an earlier sweep's JSON."""
    if path is None:
        return {}
    if not path.exists():  # the reference sweep failed: nothing to compare (said so)
        print(json.dumps({"against": str(path), "missing": True}), flush=True)
        return {}
    cases = json.loads(path.read_text())["cases"]
    return {(c["n"], c["K"]): c["digest"] for c in cases if "digest" in c}


def sweep(n: int, K: int, args: argparse.Namespace) -> dict:
    import cupy as cp

    spec = get_method("lemke")
    tol = spec.default_tol
    M, q = make_stack(K, n, seed=2026)
    Md, qd = cp.asarray(M), cp.asarray(q)
    out: dict = {"n": n, "K": K, "configs": []}
    first = None
    lanes_list = [8, 16, 32] if n <= 24 else [16, 32]
    shipped_warps = cuda.WARPS_PER_BLOCK
    for mb, lanes, stage, warps in itertools.product(args.blocks, lanes_list, (True, False),
                                                     args.warps):
        cuda.EXTRA_OPTIONS = (f"-DLCP_WARP_MIN_BLOCKS={mb}",)
        cuda.WARP_TABLE = ((1 << 62, lanes, stage, mb),)
        cuda.WARPS_PER_BLOCK = warps
        shape = cuda.warp_launch(n)
        res = {}

        def run(res=res) -> None:  # noqa: ANN001
            res["o"] = cuda.run_lemke(Md, qd, tol=tol, options={},
                                      scaling=spec.scaling, variant="warp")
        secs = timed(cp, run, args.repeat)
        o = res["o"]
        certified = int((o["code"] == KERNEL_SOLVED).sum())
        row = {"min_blocks": mb, "lanes": lanes, "stage": shape.stage,
               "warps_asked": warps,
               "warps_per_block": shape.warps, "shared_per_block": shape.shared,
               "kernel_s": secs, "certified_per_s": certified / secs,
               "certified": certified}
        if first is None:
            first = {k: o[k].get() for k in KEYS}
            out["digest"] = digest(first)
            if (n, K) in args.against:
                out["same_as_against"] = out["digest"] == args.against[(n, K)]
            idx = np.random.default_rng(1).choice(K, min(args.sample, K), replace=False)
            host = lcpcli.solve_many(M[idx], q[idx], "lemke")
            ok = first["code"][idx] == KERNEL_SOLVED
            out["cpu"] = {
                "sample": int(idx.size), "device_certified": int(ok.sum()),
                "cpu_solved_where_device_certified": bool(host.solved[ok].all()),
                "same_z": bool(np.array_equal(first["z"][idx][ok], host.z[ok])),
                "same_pivots": bool(np.array_equal(first["iterations"][idx][ok],
                                                   host.iterations[ok]))}
            row["same"] = True
        else:
            row["same"] = all(np.array_equal(o[k].get(), first[k], equal_nan=True)
                              for k in KEYS)
        del o, res["o"]
        out["configs"].append(row)
        print(json.dumps({"n": n, **row}), flush=True)
    cuda.WARPS_PER_BLOCK = shipped_warps
    good = [c for c in out["configs"] if c["same"]]
    shipped = [c for c in good if c["warps_asked"] == shipped_warps]  # what the table can say
    if shipped:
        out["best"] = max(shipped, key=lambda c: c["certified_per_s"])
    if good:
        out["best_any_warps"] = max(good, key=lambda c: c["certified_per_s"])
    Md = qd = None  # noqa: F841 - the stack's device memory back before the next size
    cp.get_default_memory_pool().free_all_blocks()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--sizes", default="12,24,32,50")
    ap.add_argument("--blocks", default="1,2,3,4")
    ap.add_argument("--warps", default=None,
                    help="warps per block to try (backends/cuda.py's WARPS_PER_BLOCK; default "
                         "the shipped one); the table comes from the shipped one's rows")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sample", type=int, default=20_000)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every K by this")
    ap.add_argument("--cubins", type=Path, default=None)
    ap.add_argument("--against", type=Path, default=None,
                    help="an earlier sweep's JSON: its first combination's outputs (digest) "
                         "must be this one's, bit for bit, at every size both swept")
    ap.add_argument("--table-out", type=Path, default=None,
                    help="the WARP_TABLE the best rows make (JSON), for bench_gpu.py --table")
    args = ap.parse_args()
    args.blocks = [int(b) for b in args.blocks.split(",")]
    args.against = against(args.against)
    args.warps = [cuda.WARPS_PER_BLOCK] if args.warps is None else \
        [int(w) for w in args.warps.split(",")]
    import cupy as cp

    modules = {} if args.cubins is None else use_cubins(args.cubins)
    props = cp.cuda.runtime.getDeviceProperties(cp.cuda.Device().id)
    info = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "device": props["name"].decode(), "cupy": cp.__version__,
            "prebuilt": sorted(" ".join(k) for k in modules)}
    print(json.dumps(info), flush=True)
    cases = []
    for n in (int(x) for x in args.sizes.split(",")):
        t = time.perf_counter()
        cases.append(sweep(n, max(1, int(STACKS.get(n, 100_000) * args.scale)), args))
        cases[-1]["seconds"] = time.perf_counter() - t
        print(json.dumps({"n": n, "same_as_against": cases[-1].get("same_as_against"),
                          "best": cases[-1].get("best")}), flush=True)
    rows = [[c["n"], c["best"]["lanes"], c["best"]["stage"], c["best"]["min_blocks"]]
            for c in cases if c.get("best")]
    if rows:
        rows[-1][0] = 1 << 62  # the largest size measured speaks for every larger one
        print(json.dumps({"table": rows}), flush=True)
        if args.table_out is not None:
            args.table_out.write_text(json.dumps(rows) + "\n")
    write_cases(args.out, "gpu_sweep.json", info, cases)


if __name__ == "__main__":
    main()
