"""Benchmark: warm-started stacks (``lcpcli.solve_many(M, q, warm=previous)``) against cold ones.

    python benchmarks/bench_warm_stack.py                  # K = 100,000, n = 12, 5 steps
    python benchmarks/bench_warm_stack.py --K 20000 --n 12 24 --steps 3

Issue 26's stack goal: K stacked LCPs of size n, M random positive definite (``A A^T / n + I``,
fixed), ``q_{k+1} = q_k + 1 %`` noise.  At every step, interleaved: the cold stack
``solve_many(M, q_k, "lemke")`` and the warm one ``solve_many(M, q_k, "lemke", warm=previous
warm result)`` (:mod:`lcpcli.solvers.warm_stack`: BPP from each basis in the batched kernel).
Rates are problems per second of the whole ``solve_many`` call (wall), medians over the steps,
and of process CPU time (the machine is shared), and the best (fastest) step of each kind, the
figure least disturbed by other work on a shared machine (cold and warm interleaved, so both
best steps come from the same stretch of time); every verdict and z is compared with the cold
stack's.  Threads: ``--threads`` (default: the cores this process may use).  Writes
``benchmarks/results/warm_stack.json``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from _results import write_results

import lcpcli


def bench(K: int, n: int, steps: int, threads: int | None, seed: int = 0) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    M = np.ascontiguousarray(np.einsum("kij,klj->kil", A, A) / n + np.eye(n))
    q = rng.standard_normal((K, n))
    prev = lcpcli.solve_many(M, q, "lemke", threads=threads)
    wall: dict[str, list[float]] = {"cold": [], "warm": []}
    cpu: dict[str, list[float]] = {"cold": [], "warm": []}
    diff, warm_iters, cold_iters = 0.0, [], []
    for _ in range(steps + 1):
        q = q + 0.01 * np.abs(q) * rng.standard_normal((K, n))
        out = {}
        for kind in ("cold", "warm"):
            t, c = time.perf_counter(), time.process_time()
            out[kind] = lcpcli.solve_many(M, q, "lemke", threads=threads,
                                          warm=prev if kind == "warm" else None)
            wall[kind].append(time.perf_counter() - t)
            cpu[kind].append(time.process_time() - c)
        assert np.array_equal(out["cold"].status, out["warm"].status)
        diff = max(diff, float(np.max(np.abs(out["cold"].z - out["warm"].z))))
        warm_iters.append(float(out["warm"].iterations.mean()))
        cold_iters.append(float(out["cold"].iterations.mean()))
        prev = out["warm"]
    med = {k: statistics.median(v[1:]) for k, v in wall.items()}  # the first step untimed
    med_cpu = {k: statistics.median(v[1:]) for k, v in cpu.items()}
    best = {k: min(v[1:]) for k, v in wall.items()}
    return {"K": K, "n": n, "steps": steps, "threads": threads,
            "rate": {k: K / v for k, v in med.items()},
            "cpu_rate": {k: K / v for k, v in med_cpu.items()},
            "best_rate": {k: K / v for k, v in best.items()},
            "speedup_wall": med["cold"] / med["warm"],
            "speedup_cpu": med_cpu["cold"] / med_cpu["warm"],
            "speedup_best": best["cold"] / best["warm"],
            "mean_iterations": {"cold": statistics.mean(cold_iters[1:]),
                                "warm": statistics.mean(warm_iters[1:])},
            "max_z_difference": diff, "solved": out["warm"].counts()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--K", type=int, default=100_000)
    ap.add_argument("--n", type=int, nargs="+", default=[12])
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "warm_stack.json"))
    args = ap.parse_args()
    rows = []
    for n in args.n:
        row = bench(args.K, n, args.steps, args.threads)
        rows.append(row)
        print(f"K = {args.K:,}, n = {n}: cold {row['rate']['cold']:,.0f}/s, warm "
              f"{row['rate']['warm']:,.0f}/s ({row['speedup_wall']:.2f}x wall, "
              f"{row['speedup_cpu']:.2f}x CPU time; best steps: cold "
              f"{row['best_rate']['cold']:,.0f}/s, warm {row['best_rate']['warm']:,.0f}/s, "
              f"{row['speedup_best']:.2f}x); mean pivots/iterations cold "
              f"{row['mean_iterations']['cold']:.2f}, warm {row['mean_iterations']['warm']:.3f}; "
              f"max |z_warm - z_cold| {row['max_z_difference']:.1e}")
    write_results(args.out, rows)


if __name__ == "__main__":
    main()
