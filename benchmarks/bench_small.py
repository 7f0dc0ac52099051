"""Benchmark: the small-solve path, ``lcpcli.solve(p, "lemke")`` at n = 10, against Siconos.

The problem is ``benchmarks/bench_lemke.py``'s (``M = A A^T + n I``, ``q ~ N(0, 1)``, seed
2026 + n).  Ours: the wall time per call of the whole :func:`lcpcli.solve` (registry lookup,
option parsing, kernel + polish, certificate, Result), the best of 100 batches of
``--calls / 100`` calls, and the same for each part of the path.  Siconos:
``siconos_peer.py --solver Lemke --repeat K``'s ``seconds_median`` (the C driver call from
Python, one warm-up), measured before and after ours in the same run (the mean of the two is
the reference).

    python benchmarks/bench_small.py [--n 10] [--calls 20000]

Writes ``benchmarks/results/small.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import lcpcli  # noqa: E402
from lcpcli.analysis.scaling import BALANCE, equilibrate, is_balanced  # noqa: E402
from lcpcli.api import certify_outcome  # noqa: E402
from lcpcli.core.certificate import certify  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402
from lcpcli.solvers.kernels.lemke_revised import lemke_solve_certified  # noqa: E402
from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL  # noqa: E402
from lcpcli.solvers.pipeline import run_method  # noqa: E402
from lcpcli.solvers.request import resolve  # noqa: E402

SHARED = Path(os.environ.get("LCPCLI_SHARED", ROOT.parent / "shared"))
PEER = SHARED / "peers" / "siconos_peer.py"


def make_problem(n: int, seed: int = 2026) -> Problem:
    rng = np.random.default_rng(seed + n)
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n), name=f"rand{n}")


def per_call(f, calls: int, batches: int = 100) -> float:
    """Seconds per call: the best of ``batches`` batches of ``calls / batches`` calls (after
    one warm-up; many short batches: robust on a machine shared with other work)."""
    f()
    each = max(1, calls // batches)
    best = float("inf")
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(each):
            f()
        best = min(best, (time.perf_counter() - t0) / each)
    return best


def siconos(prob: Problem, repeat: int) -> dict | None:
    if not PEER.exists() or not Path("/usr/bin/python3").exists():
        return None
    with tempfile.TemporaryDirectory() as td:
        path = Path(td) / "p.npz"
        np.savez(path, M=prob.dense_M(), q=prob.q)
        out = subprocess.run(["/usr/bin/python3", str(PEER), str(path), "--solver", "Lemke",
                              "--repeat", str(repeat)], capture_output=True, text=True,
                             timeout=600)
    try:
        return json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "results" /
                    "small.json")
    args = ap.parse_args(argv)
    prob = make_problem(args.n)
    sic_before = siconos(prob, 2000)
    req = resolve(prob, "lemke")
    spec, opts = req.spec, req.given  # what the dispatcher passes to run
    M = np.ascontiguousarray(prob.M)
    out = run_method(spec, prob, 1e-8, opts)
    M_arr, q_arr = prob.dense_M().copy(), prob.q.copy()
    parts = {
        "lcpcli.solve(p, 'lemke')": lambda: lcpcli.solve(prob, "lemke"),
        "  request.resolve (method, checks, options, tol)": lambda: resolve(prob, "lemke"),
        "  dispatcher run_method (-> certified Outcome)": lambda: run_method(spec, prob, 1e-8,
                                                                             opts),
        "    method run (one compiled call + Outcome)": lambda: spec.run(
            prob, tol=1e-8, balance=BALANCE, **opts),
        "      one C call: balance test, kernel, polish, certificate": lambda:
            lemke_solve_certified(M, prob.q, None, 1000, PIVOT_TOL, TIE_TOL, 50, BALANCE),
        "  certify_outcome (Result)": lambda: certify_outcome(prob, out, "lemke-revised", 0.0,
                                                              1e-8),
        "for comparison:": None,
        "  lcpcli.solve(p) (auto)": lambda: lcpcli.solve(prob),
        "  lcpcli.solve(M, q, method='lemke') (arrays)": lambda: lcpcli.solve(
            M_arr, q_arr, method="lemke"),
        "  certify (w and certificate, from Python)": lambda: certify(prob, out.z, 1e-8),
        "  equilibrate (Ruiz, symmetric)": lambda: equilibrate(prob, True),
        "  balance test alone (is_balanced, one C call)": lambda: is_balanced(prob),
    }
    times = {k: per_call(f, args.calls) for k, f in parts.items() if f is not None}
    sic_after = siconos(prob, 2000)
    sic = [s["seconds_median"] for s in (sic_before, sic_after) if s and s.get("seconds_median")]
    ref = sum(sic) / len(sic) if sic else None
    print(f"n = {args.n}, Lemke, pivots {out.iterations}")
    for k, t in times.items():
        ratio = f"{t / ref:7.1f}x Siconos" if ref else ""
        print(f"{k:58s} {t * 1e6:9.2f} us  {ratio}")
    if ref:
        print(f"{'Siconos Lemke (C driver, median)':58s} {ref * 1e6:9.2f} us  "
              f"(before {sic[0] * 1e6:.2f}, after {sic[-1] * 1e6:.2f})")
    payload = {"benchmark": "small", "n": args.n, "us": {k: t * 1e6 for k, t in times.items()},
               "siconos_us": None if ref is None else ref * 1e6,
               "siconos_runs_us": [s * 1e6 for s in sic],
               "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(payload, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
