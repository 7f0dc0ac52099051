"""A small stack through each device kernel, for compute-sanitizer (memcheck, racecheck).

    compute-sanitizer --tool memcheck python benchmarks/gpu_sanitize.py
    compute-sanitizer --tool racecheck python benchmarks/gpu_sanitize.py warp warp8

Variants: ``thread``, ``warp`` (the shipped WARP_TABLE) and ``warp8`` (8 lanes per problem:
four problems to a warp, M, q, z, w staged in shared memory wherever they fit).

Prints, per kernel variant and size, whether the verdicts equal the CPU's; the sanitizer's
own report says whether a kernel read or wrote out of bounds or raced on shared memory.
"""

from __future__ import annotations

import sys

import numpy as np

import lcpcli
from lcpcli.solvers.backends import cuda


def main() -> None:
    variants = sys.argv[1:] or ["thread", "warp", "warp8"]
    table = cuda.WARP_TABLE
    rng = np.random.default_rng(7)
    for n in (1, 12, 40, 130):  # 130: the warp's tableau in global memory
        K = 64
        A = rng.standard_normal((K, n, n))
        M = A @ A.transpose(0, 2, 1) / n + np.eye(n)
        M[: K // 2] += rng.standard_normal((K // 2, n, n))  # half not PD: rays, retries
        q = rng.standard_normal((K, n))
        ref = lcpcli.solve_many(M, q, "lemke")
        for variant in variants:
            cuda.LEMKE_VARIANT = "thread" if variant == "thread" else "warp"
            cuda.WARP_TABLE = ((1 << 62, 8, True, 4),) if variant == "warp8" else table
            got = lcpcli.solve_many(M, q, "lemke", backend="cuda")
            same = np.array_equal(got.status, ref.status) and np.array_equal(got.z, ref.z)
            print(f"lemke {variant} n={n}: same as cpu {same}, device retried "
                  f"{int(got.retried.sum())}/{K}", flush=True)
        if "thread" in variants:
            S = (M + M.transpose(0, 2, 1)) / 2
            ref = lcpcli.solve_many(S, q, "pgs")
            got = lcpcli.solve_many(S, q, "pgs", backend="cuda")
            print(f"pgs n={n}: same as cpu {np.array_equal(got.status, ref.status)}",
                  flush=True)


if __name__ == "__main__":
    main()
