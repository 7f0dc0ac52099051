"""Benchmark: Murty and Dantzig warm-started from the previous basis against cold solves.

    python benchmarks/bench_warm_methods.py               # n = 50 and 200, 30 steps each
    python benchmarks/bench_warm_methods.py --n 200 --steps 60

A sequence of LCPs as in time stepping: M = A A^T + n I (a random positive definite matrix,
hence a P-matrix; fixed), ``q_{k+1} = q_k + 0.01 |q_k| N(0, 1)`` (1 % noise).  At every step,
interleaved (so that load on a shared machine hits all alike), for ``murty`` and ``dantzig``:

* ``cold``: ``lcpcli.solve(M, q_k, method)``;
* ``warm``: ``lcpcli.solve(M, q_k, method, warm=warm result of step k-1)``: the method starts
  from the previous basis itself (Murty pivots the index set in; Dantzig runs on the principal
  pivot transform of its block; :mod:`lcpcli.solvers.warm`, ``takes_basis``).

Reported: mean pivots per step (``Result.iterations``) and the median time per step, ``wall``
(the whole call, certificate included) and ``seconds`` (``Result.seconds``), warm / cold in the
same run (the mean wall time too: on a loaded machine the median is the steadier figure).
Every answer is certified; warm z's are compared with the cold z (a P-matrix: one solution).
One BLAS thread.  Writes ``benchmarks/results/warm_methods.json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = os.environ.get("BENCH_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _results import write_results  # noqa: E402

import lcpcli  # noqa: E402

METHODS = ("murty", "dantzig")
KINDS = ("cold", "warm")


def bench(n: int, steps: int, seed: int = 0) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    q = rng.standard_normal(n)
    prev = {m: lcpcli.solve(M, q, m) for m in METHODS}
    walls = {(m, k): [] for m in METHODS for k in KINDS}
    secs = {(m, k): [] for m in METHODS for k in KINDS}
    pivots = {(m, k): [] for m in METHODS for k in KINDS}
    took_basis = {m: 0 for m in METHODS}
    diff = 0.0
    for step in range(steps + 1):  # step 0 untimed (imports, first calls)
        q = q + 0.01 * np.abs(q) * rng.standard_normal(n)
        for m in METHODS:
            out = {}
            for k in KINDS:
                t = time.perf_counter()
                r = lcpcli.solve(M, q, m) if k == "cold" else lcpcli.solve(M, q, m,
                                                                           warm=prev[m])
                wall = time.perf_counter() - t
                assert r.solved, (n, step, m, k, r.message)
                out[k] = r
                if step:
                    walls[m, k].append(wall)
                    secs[m, k].append(r.seconds)
                    pivots[m, k].append(r.iterations)
            if step and "from the given basis" in out["warm"].message:
                took_basis[m] += 1
            diff = max(diff, float(np.max(np.abs(out["warm"].z - out["cold"].z))))
            prev[m] = out["warm"]
    row: dict[str, object] = {"n": n, "steps": steps, "max_z_difference": diff}
    for m in METHODS:
        per = {k: {"wall": statistics.median(walls[m, k]),
                   "seconds": statistics.median(secs[m, k]),
                   "wall_mean": statistics.fmean(walls[m, k]),
                   "pivots": statistics.fmean(pivots[m, k])} for k in KINDS}
        row[m] = {**per,
                  "ratio_wall": per["warm"]["wall"] / per["cold"]["wall"],
                  "ratio_wall_mean": per["warm"]["wall_mean"] / per["cold"]["wall_mean"],
                  "ratio_seconds": per["warm"]["seconds"] / per["cold"]["seconds"],
                  "ratio_pivots": per["warm"]["pivots"] / max(per["cold"]["pivots"], 1e-300),
                  "warm_from_basis_steps": took_basis[m]}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[50, 200])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" /
                                         "warm_methods.json"))
    args = ap.parse_args()
    rows = []
    print(f"{'n':>5} {'method':>8} {'cold pivots':>12} {'warm pivots':>12} {'cold ms':>9} "
          f"{'warm ms':>9} {'warm/cold wall':>15} {'(seconds)':>10} {'(mean wall)':>11}")
    for n in args.n:
        row = bench(n, args.steps)
        rows.append(row)
        for m in METHODS:
            r = row[m]
            print(f"{n:>5} {m:>8} {r['cold']['pivots']:>12.1f} {r['warm']['pivots']:>12.1f} "
                  f"{r['cold']['wall'] * 1e3:>9.3f} {r['warm']['wall'] * 1e3:>9.3f} "
                  f"{r['ratio_wall']:>14.3f}x {r['ratio_seconds']:>9.3f}x "
                  f"{r['ratio_wall_mean']:>10.3f}x"
                  f"  ({r['warm_from_basis_steps']}/{args.steps} steps from the basis)")
        print(f"      max |z_warm - z_cold| {row['max_z_difference']:.1e}")
    write_results(args.out, rows)


if __name__ == "__main__":
    main()
