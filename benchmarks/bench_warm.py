"""Benchmark: warm-started pivoting (``lcpcli.solve(p, warm=previous)``) against cold solves.

    python benchmarks/bench_warm.py                 # n = 10, 100, 1000; 15 steps each
    python benchmarks/bench_warm.py --n 1000 --steps 30

A sequence of LCPs as in time stepping: M random positive definite (``A A^T / n + I``, fixed),
``q_{k+1} = q_k + 1 %`` noise (``q_k + 0.01 |q_k| * N(0, 1)``).  At every step, interleaved
(so that load on a shared machine hits all alike):

* ``cold``: ``lcpcli.solve(M, q_k)`` (``auto``) and ``lcpcli.solve(M, q_k, "lemke-revised")``
  (the fastest cold pivoting method, benchmarks/README.md);
* ``warm``: ``lcpcli.solve(M, q_k, warm=cold result of step k-1)``: the basis only, its block
  factored afresh (the first step of a sequence);
* ``chained``: ``lcpcli.solve(M, q_k, warm=warm result of step k-1)``: the steady state of a
  sequence, whose result carries the factors of its basis block (the same M reuses them);
* ``bpp-chained``: the same with ``method="bpp"``, which pivots from the basis at every n
  (``auto`` and Lemke do from n = 200 on, ``lcpcli.solvers.warm.WARM_MIN_N``; below that
  ``warm`` and ``chained`` are cold solves);
* ``lemke-chained``: the same with ``method="lemke"``: Lemke with the covering ray started from
  the previous basis (:mod:`lcpcli.solvers.methods.lemke_warm`; from n = 200 on, like ``auto``).

Times: ``seconds`` (``Result.seconds``: the method's time, certification excluded) and
``wall`` (the whole call, with the certificate), medians over the steps (the first step of
each kind untimed); every answer is certified and warm z's are compared with the cold z.
One BLAS thread.  Writes ``benchmarks/results/warm.json``.
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

KINDS = ("cold", "lemke-revised", "warm", "chained", "bpp-chained", "lemke-chained")
WARM = ("warm", "chained", "bpp-chained", "lemke-chained")
#: The kinds whose previous result starts the next step of the same kind.
CHAINS = ("chained", "bpp-chained", "lemke-chained")


def _run(M: np.ndarray, q: np.ndarray, kind: str, prev: dict[str, object]) -> object:
    if kind == "cold":
        return lcpcli.solve(M, q)
    if kind == "lemke-revised":
        return lcpcli.solve(M, q, "lemke-revised")
    if kind == "bpp-chained":
        return lcpcli.solve(M, q, "bpp", warm=prev["bpp-chained"])
    if kind == "lemke-chained":
        return lcpcli.solve(M, q, "lemke", warm=prev["lemke-chained"])
    return lcpcli.solve(M, q, warm=prev["cold" if kind == "warm" else "chained"])


def bench(n: int, steps: int, seed: int = 0) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + np.eye(n)
    q = rng.standard_normal(n)
    first = lcpcli.solve(M, q)
    prev: dict[str, object] = {"cold": first, **{k: first for k in CHAINS}}
    times: dict[str, list[float]] = {k: [] for k in KINDS}
    secs: dict[str, list[float]] = {k: [] for k in KINDS}
    iters: dict[str, list[int]] = {k: [] for k in KINDS}
    diff = 0.0
    for step in range(steps + 1):
        q = q + 0.01 * np.abs(q) * rng.standard_normal(n)
        out = {}
        for kind in KINDS:
            t = time.perf_counter()
            r = _run(M, q, kind, prev)
            wall = time.perf_counter() - t
            assert r.solved, (n, step, kind, r.message)
            out[kind] = r
            if step:
                times[kind].append(wall)
                secs[kind].append(r.seconds)
                iters[kind].append(r.iterations)
        diff = max(diff, *(float(np.max(np.abs(out[k].z - out["cold"].z)))
                           for k in WARM))
        prev = {k: out[k] for k in ("cold", *CHAINS)}
    med = {k: statistics.median(v) for k, v in times.items()}
    med_s = {k: statistics.median(v) for k, v in secs.items()}
    return {"n": n, "steps": steps, "wall": med, "seconds": med_s,
            "iterations": {k: statistics.median(v) for k, v in iters.items()},
            "max_z_difference": diff,
            "ratio_wall": {k: med[k] / med["cold"] for k in WARM},
            "ratio_seconds": {k: med_s[k] / med_s["cold"] for k in WARM},
            "ratio_seconds_vs_lemke_revised": {k: med_s[k] / med_s["lemke-revised"]
                                               for k in WARM}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--steps", type=int, default=15)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "warm.json"))
    args = ap.parse_args()
    rows = []
    print(f"{'n':>5} {'kind':>14} {'wall ms':>10} {'seconds ms':>11} {'iters':>6}")
    for n in args.n:
        row = bench(n, args.steps)
        rows.append(row)
        for k in KINDS:
            print(f"{n:>5} {k:>14} {row['wall'][k] * 1e3:>10.3f} "
                  f"{row['seconds'][k] * 1e3:>11.3f} {row['iterations'][k]:>6}")
        print("      / cold (auto), wall and seconds: " + "; ".join(
            f"{k} {row['ratio_wall'][k]:.3f}x {row['ratio_seconds'][k]:.3f}x" for k in WARM)
            + f"; max |z_warm - z_cold| {row['max_z_difference']:.1e}")
    write_results(args.out, rows)


if __name__ == "__main__":
    main()
