"""Benchmark: the compiled-kernel methods on fixed problems, for before/after comparisons.

Times are the method's own wall time (``Result.seconds`` from :func:`lcpcli.solve`: no file
reading, no certification), the median over repeats after one untimed warm-up call (which
also loads the kernels).  Every answer is certified; the table shows the status too.

Problems (fixed seeds, so two checkouts measure the same thing):

* ``pd-N``: ``M = A A^T + N I``, ``q ~ N(0, 1)`` (Lemke, Murty, Dantzig, PGS/PSOR);
* ``box-N``: the same M with ``-1 <= z <= 1`` (Dantzig, PGS);
* ``sparse-N``: tridiagonal SPD ``M`` (2.5 on the diagonal, -1 beside it), ``q ~ N(0, 1)`` (PGS);
* ``enum-N``: random positive definite nonsymmetric M, ``q = 3 N(0, 1)``
  (``benchmarks/bench_enumerate.py``'s problem; ``enum`` stops at the first solution).

    python benchmarks/bench_kernels.py [--quick] [--label before] [--output FILE]

Writes ``benchmarks/results/kernels.json`` (or ``--output``).
"""

from __future__ import annotations

import os

# One BLAS thread, as the other benchmarks (set before numpy is imported).
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from lcpcli.api import solve  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402


def pd(n: int) -> Problem:
    rng = np.random.default_rng(2026 + n)
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n), name=f"pd-{n}")


def box(n: int) -> Problem:
    p = pd(n)
    return Problem.create(p.M, p.q * n, lower=-np.ones(n), upper=np.ones(n), name=f"box-{n}")


def sparse(n: int) -> Problem:
    import scipy.sparse as sp

    rng = np.random.default_rng(7 + n)
    M = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    return Problem.create(M, rng.standard_normal(n), name=f"sparse-{n}")


def enum_problem(n: int) -> Problem:
    rng = np.random.default_rng(1000 + n)
    A = rng.standard_normal((n, n))
    C = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + 0.1 * np.eye(n) + (C - C.T), 3.0 * rng.standard_normal(n),
                          name=f"enum-{n}")


def cases(quick: bool) -> list[tuple[str, Problem, int]]:
    """(method, problem, repeats)."""
    out: list[tuple[str, Problem, int]] = []
    sizes = (10, 100) if quick else (10, 100, 500, 1000)
    for n in sizes:
        p = pd(n)
        k = 30 if n <= 100 else 5
        for m in ("lemke-tableau", "lemke-revised", "murty", "dantzig", "pgs", "psor"):
            out.append((m, p, k))
    for n in (100,) if quick else (100, 1000):
        b = box(n)
        k = 30 if n <= 100 else 5
        out += [("dantzig", b, k), ("pgs", b, k)]
    for n in (10_000,) if quick else (10_000, 100_000):
        out.append(("pgs", sparse(n), 5))
    for n in (12,) if quick else (12, 16, 20):
        out.append(("enum", enum_problem(n), 5 if n <= 16 else 3))
    return out


def run_case(method: str, prob: Problem, k: int) -> dict:
    res = solve(prob, method)  # warm-up: loads the kernels
    secs = []
    for _ in range(k):
        res = solve(prob, method)
        secs.append(res.seconds)
    return {"method": method, "problem": prob.name, "n": prob.n, "repeats": k,
            "seconds_median": statistics.median(secs), "status": res.status,
            "iterations": int(res.iterations), "error": float(res.error)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes only")
    ap.add_argument("--label", default="", help="a label stored with the results")
    ap.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "results" /
                    "kernels.json")
    args = ap.parse_args(argv)
    rows = []
    t0 = time.perf_counter()
    print(f"{'method':>14} {'problem':>14} {'ms':>10} {'status':>10} {'iters':>6} {'error':>9}")
    for method, prob, k in cases(args.quick):
        row = run_case(method, prob, k)
        rows.append(row)
        print(f"{method:>14} {prob.name:>14} {row['seconds_median'] * 1e3:10.4f} "
              f"{row['status']:>10} {row['iterations']:>6} {row['error']:9.1e}", flush=True)
    payload = {"benchmark": "kernels", "label": args.label, "rows": rows,
               "wall_s": time.perf_counter() - t0,
               "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
